"""The `anatomesh` command line end to end on real data: inspect, mesh (decimation, print checks,
scene formats, recipes), bad input and exit codes (0 ok, 1 a print check failed, 2 bad input)."""
import json
import os
import subprocess
import sys

import nibabel as nib
import numpy as np
import pytest

from anatomesh.app.cli import main
from anatomesh.core.io.mesh_files import read_stl
from helpers.readback import pinch_volume_bound
from conftest import SAMPLE, shared

SEG = SAMPLE / "example_seg.nii.gz"
CT = SAMPLE / "example_ct_sm.nii.gz"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_inspect_label_map_json(capsys):
    code, out, err = run(capsys, "inspect", SEG, "--json")
    assert code == 0, err
    facts = json.loads(out)
    assert facts["shape"] == [122, 101, 30]
    assert facts["spacing"] == pytest.approx([3.0, 3.0, 3.0])
    assert facts["space"] == "RAS"
    img = nib.load(str(SEG))
    np.testing.assert_allclose(facts["affine"], img.affine, atol=1e-5)
    labels = {lab["value"]: lab for lab in facts["labels"]}
    data = np.asarray(img.dataobj)
    assert len(labels) == len(np.unique(data)) - 1 == 41
    liver = labels[5]
    assert liver["name"] == "liver"  # from the sidecar label_names_*.json next to the sample
    assert liver["voxels"] == int((data == 5).sum())
    assert liver["volume_mm3"] == pytest.approx(liver["voxels"] * 27.0)
    assert {"dtype", "min", "max"} <= set(facts)


def test_inspect_ct_text_has_histogram_peaks(capsys):
    code, out, err = run(capsys, "inspect", CT)
    assert code == 0, err
    assert "RAS" in out and "122 x 101 x 30" in out and "histogram" in out
    peaks = out.split("peaks", 1)[1].splitlines()[0]
    assert "soft tissue" in peaks and ("air" in peaks or "fat" in peaks)


@pytest.mark.parametrize("argv, words", [
    (["inspect", "/nonexistent/scan.nii.gz"], ["/nonexistent/scan.nii.gz", "no such file"]),
    (["mesh", str(SEG), "--out", "{tmp}", "--labels", "livr"], ["livr", "liver"]),
    (["mesh", str(CT), "--out", "{tmp}"], ["--level"]),
    (["mesh", str(SEG), "--out", "{tmp}", "--format", "fbx"], ["fbx", "stl"]),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, argv, words):
    code, out, err = run(capsys, *[a.replace("{tmp}", str(tmp_path / "o")) for a in argv])
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err
    for w in words:
        assert w in lines[0]
    print(lines[0])


def test_mesh_label_subset_lands_on_the_voxels(capsys, tmp_path):
    out_dir = tmp_path / "out"
    code, out, err = run(capsys, "mesh", SEG, "--out", out_dir, "--labels", "liver,spleen,3",
                         "--format", "stl,ply", "--smooth", "none")
    assert code == 0, err
    rep = json.loads((out_dir / "report.json").read_text())
    assert rep["space"] == "RAS" and rep["units"] == "mm"
    assert rep["input"]["shape"] == [122, 101, 30]
    surf = {s["name"]: s for s in rep["surfaces"]}
    assert set(surf) == {"liver", "spleen", "kidney_left"}
    img = nib.load(str(SEG))
    data = np.asarray(img.dataobj)
    for name, value in (("liver", 5), ("spleen", 1)):
        s = surf[name]
        assert s["closed"] and s["manifold"] and s["genus"] is not None
        # the raw surface encloses exactly the label's voxels (but at its pinch points)
        assert abs(s["volume_mm3"] - (data == value).sum() * 27.0) <= pinch_volume_bound(s["pinch_points"], s["volume_mm3"], 27.0)
        tri = read_stl(out_dir / s["files"]["stl"])
        assert b"SPACE=RAS" in tri["header"]
        pts = tri["triangles"].reshape(-1, 3)
        # the mesh lies within the label's voxel extent (voxel centres +- half a voxel, 3 mm)
        idx = np.argwhere(data == value)
        corners = np.array([[a, b, c] for a in (idx[:, 0].min() - .5, idx[:, 0].max() + .5)
                            for b in (idx[:, 1].min() - .5, idx[:, 1].max() + .5)
                            for c in (idx[:, 2].min() - .5, idx[:, 2].max() + .5)])
        world = nib.affines.apply_affine(img.affine, corners)
        assert (pts >= world.min(0) - 1e-3).all() and (pts <= world.max(0) + 1e-3).all()
        assert (out_dir / s["files"]["ply"]).exists()
    # refusing to overwrite, then allowed with --overwrite
    code, _, err = run(capsys, "mesh", SEG, "--out", out_dir, "--labels", "liver")
    assert code == 2 and "--overwrite" in err
    code, _, err = run(capsys, "mesh", SEG, "--out", out_dir, "--labels", "liver", "--overwrite")
    assert code == 0, err


def test_mesh_default_smoothing_is_measured_and_bounded(capsys, tmp_path):
    code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path, "--labels", "liver,aorta,vertebrae_L1")
    assert code == 0, err
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["smoothing"]["preset"] == "organ" and rep["smoothing"]["method"] == "taubin"
    for s in rep["surfaces"]:
        assert s["closed"] and s["manifold"] and s["topology_changed"] is False
        assert abs(s["volume_change_pct"]) <= 1.0          # compact organs keep their volume
        diag = 3.0 * 3 ** 0.5                               # one voxel diagonal, 3 mm voxels
        assert 0 < s["mean_deviation_mm"] < s["max_deviation_mm"] <= diag
        assert s["max_displacement_mm"] <= diag / 2 + 1e-3  # every vertex stays in its voxel cell
    code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path / "cap", "--labels", "liver",
                       "--max-deviation", "0.5", "--iterations", "30")
    assert code == 0, err
    liver = json.loads((tmp_path / "cap" / "report.json").read_text())["surfaces"][0]
    assert liver["max_displacement_mm"] <= 0.5 + 1e-4


def test_mesh_absent_label_is_a_warning_in_report_and_terminal(capsys, tmp_path):
    code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path, "--labels", "spleen,200", "--smooth", "none")
    assert code == 0, err
    assert "warning:" in err and "200" in err
    rep = json.loads((tmp_path / "report.json").read_text())
    assert [s["name"] for s in rep["surfaces"]] == ["spleen"]
    assert any("200" in w for w in rep["warnings"])


def test_mesh_space_lps_negates_x_and_y(capsys, tmp_path):
    for space in ("RAS", "LPS"):
        code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path / space, "--labels", "spleen",
                           "--space", space)
        assert code == 0, err
    ras = read_stl(tmp_path / "RAS" / "spleen.stl")["triangles"]
    lps = read_stl(tmp_path / "LPS" / "spleen.stl")["triangles"]
    assert b"SPACE=LPS" in read_stl(tmp_path / "LPS" / "spleen.stl")["header"]
    np.testing.assert_allclose(lps[..., :2], -ras[..., :2], atol=1e-4)
    np.testing.assert_allclose(lps[..., 2], ras[..., 2], atol=1e-4)


def test_mesh_head_ct_dicom_skin_and_bone_closed(capsys, tmp_path):
    code, out, err = run(capsys, "mesh", shared("slicer_ctheadaxial"), "--out", tmp_path,
                         "--level", "500", "--level", "1150", "--keep-largest")
    assert code == 0, err
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["input"]["shape"] == [64, 64, 93]
    assert len(rep["surfaces"]) == 2
    for s in rep["surfaces"]:
        assert s["closed"] and s["manifold"] and s["components"] == 1
        assert s["degenerate_faces"] == 0
    skin, bone = sorted(rep["surfaces"], key=lambda s: s["value"])
    assert skin["volume_mm3"] > bone["volume_mm3"] > 0


def test_console_script_entry_point(tmp_path):
    out = subprocess.run([sys.executable, "-m", "anatomesh.app.cli", "inspect", str(SEG), "--json"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["space"] == "RAS"


# ---------------------------------------------------------------------------------------------
# decimation, print checks, scene formats, recipes
# ---------------------------------------------------------------------------------------------
def test_mesh_decimate_flag_reports_the_error_in_mm(capsys, tmp_path):
    code, out, err = run(capsys, "mesh", SEG, "--out", tmp_path, "--labels", "spleen,kidney_left",
                         "--decimate", "0.3")
    assert code == 0, err
    assert "decimated" in out and "max error" in out
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["recipe"]["decimate"] == 0.3
    for s in rep["surfaces"]:
        assert s["faces"] < s["faces_before"]
        assert s["closed"] and s["manifold"]
        assert 0 < s["decimation_mean_error_mm"] < s["decimation_max_error_mm"] < 3.0
        assert "decimation_volume_change_pct" in s


def test_mesh_check_exit_codes(capsys, tmp_path):
    # the spleen is a compact solid: it passes; the liver's edges in this 3 mm map are tapering rims
    # a printer blunts by a fraction of its line: at a 5 mm minimum wall they pass with a warning
    # each; at 12 mm the waists between its lobes are thinner than the wall: it fails
    code, out, err = run(capsys, "mesh", SEG, "--out", tmp_path / "spleen", "--labels", "spleen,liver", "--check")
    assert code == 0, err
    assert "print check (fdm): passed" in out
    assert json.loads((tmp_path / "spleen" / "report.json").read_text())["print_check"]["passed"] is True
    code, out, err = run(capsys, "mesh", SEG, "--out", tmp_path / "liver5", "--labels", "liver", "--check",
                         "--min-wall", "5")
    assert code == 0, err
    (part,) = json.loads((tmp_path / "liver5" / "report.json").read_text())["print_check"]["parts"]
    assert part["passed"] and part["warnings"]
    assert all("a printer blunts it by about" in w for w in part["warnings"])
    assert 0 < part["rims"]["max_cut_back_mm"] <= 0.4  # within the fdm line
    code, out, err = run(capsys, "mesh", SEG, "--out", tmp_path / "liver12", "--labels", "liver", "--check",
                         "--min-wall", "12")
    assert code == 1
    assert "FAILED" in err and "liver" in err
    pc = json.loads((tmp_path / "liver12" / "report.json").read_text())["print_check"]
    (part,) = pc["parts"]
    assert pc["passed"] is False and part["reasons"]
    assert any(r["kind"] == "pinch" and r["thickness_mm"] < 12 for r in part["thin_regions"])
    code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path / "bad", "--labels", "spleen", "--check",
                       "--min-wall", "-1")
    assert code == 2 and "--min-wall" in err


def test_mesh_scene_formats_and_overwrite_refusal(capsys, tmp_path):
    code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path, "--labels", "spleen,liver",
                       "--format", "3mf,glb")
    assert code == 0, err
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["example_seg.3mf", "example_seg.glb", "liver.3mf", "recipe.toml", "report.json",
                     "spleen.3mf"]
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["files"]["glb"] == "example_seg.glb"
    before = (tmp_path / "example_seg.glb").stat().st_mtime_ns
    code, _, err = run(capsys, "mesh", SEG, "--out", tmp_path, "--labels", "kidney_left", "--format", "glb")
    assert code == 2 and "--overwrite" in err  # the GLB (and report/recipe) of the first run exist
    assert (tmp_path / "example_seg.glb").stat().st_mtime_ns == before


def test_mesh_recipe_file_with_flags_overriding(capsys, tmp_path):
    scans = tmp_path / "project"
    scans.mkdir()
    (scans / "organs.toml").write_text(
        f'[input]\npath = "{os.path.relpath(SEG, scans)}"\nlabels = ["spleen"]\n'
        '[smoothing]\nmethod = "none"\n[decimation]\nratio = 0.2\n'
        '[output]\ndir = "out"\nformats = ["stl", "ply"]\n')
    code, out, err = run(capsys, "mesh", "--recipe", scans / "organs.toml", "--labels", "liver,kidney_left",
                         "--max-error", "0.5")
    assert code == 0, err
    out_dir = scans / "out"  # relative to the recipe's folder
    rep = json.loads((out_dir / "report.json").read_text())
    assert sorted(s["name"] for s in rep["surfaces"]) == ["kidney_left", "liver"]  # the flag won
    assert rep["smoothing"]["method"] == "none" and (out_dir / "liver.ply").exists()  # the file's
    assert rep["decimation"]["target"] == {"max_error_mm": 0.5}  # the flag's target replaced the file's
    # the stored recipe re-runs the same job
    code, _, err = run(capsys, "mesh", "--recipe", out_dir / "recipe.toml", "--out", tmp_path / "again")
    assert code == 0, err
    again = json.loads((tmp_path / "again" / "report.json").read_text())
    assert [(s["name"], s["faces"]) for s in again["surfaces"]] == \
        [(s["name"], s["faces"]) for s in rep["surfaces"]]


@pytest.mark.parametrize("text, words", [
    ('[input]\npath = "x.nii.gz"\n[decimation]\nratio = 0.5\nerror = 1\n', ["'error'", "max_error_mm"]),
    ('[output]\ndir = "o"\n', ["no input"]),
])
def test_mesh_bad_recipe_is_one_line_exit_2(capsys, tmp_path, text, words):
    (tmp_path / "r.toml").write_text(text)
    code, out, err = run(capsys, "mesh", "--recipe", tmp_path / "r.toml")
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    for w in words:
        assert w in lines[0]


def test_mesh_needs_an_output_folder(capsys):
    code, _, err = run(capsys, "mesh", SEG)
    assert code == 2 and "--out" in err


def test_version_is_the_package_version(capsys):
    import tomllib
    from pathlib import Path

    want = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())["project"]["version"]
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"anatomesh {want}"


def test_a_bad_flag_value_is_one_line_naming_the_flag(capsys):
    assert main(["mesh", "x.nii.gz", "--out", "o", "--max-deviation", "abc"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--max-deviation" in err[0] and "invalid float value: 'abc'" in err[0]


def test_named_levels_name_the_files_and_the_recipe_keeps_them(capsys, tmp_path):
    code, out, err = run(capsys, "mesh", CT, "--out", tmp_path / "a", "--level", "bone:300", "--level", "-500",
                         "--smooth", "none")
    assert code == 0, err
    assert (tmp_path / "a" / "bone.stl").is_file() and (tmp_path / "a" / "isosurface_-500.stl").is_file()
    recipe = (tmp_path / "a" / "recipe.toml").read_text()
    assert 'level_names = ["bone", "isosurface -500"]' in recipe
    code, out, err = run(capsys, "mesh", "--recipe", tmp_path / "a" / "recipe.toml", "--out", tmp_path / "b")
    assert code == 0, err
    assert (tmp_path / "b" / "bone.stl").read_bytes() == (tmp_path / "a" / "bone.stl").read_bytes()
    code, out, err = run(capsys, "mesh", CT, "--out", tmp_path / "c", "--level", "bone:x")
    assert code == 2 and "--level takes VALUE or NAME:VALUE items" in err
