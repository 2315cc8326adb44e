"""Preprocessing through the command line and recipes on the real scans: every step
reported with its parameters and measured effect, difference colours in PLY/GLB, the reported
difference checked against an independent measurement, isovalue guidance pictures, hints, and
bad parameters as one line with exit code 2."""
import json

import nibabel as nib
import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial import cKDTree

from anatomesh.app.cli import main
from anatomesh.app.flow.recipe import Recipe, dump_recipe, load_recipe, recipe_from_text
from anatomesh.app.flow.run import run as run_recipe
from anatomesh.core.export.gltf import read_glb
from anatomesh.core.extract.isosurface import isosurface
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.volume import Volume
from conftest import SAMPLE, shared
from helpers.fields import cross_sections, grid, largest_jump

SEG = SAMPLE / "example_seg.nii.gz"


def cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def report(out_dir):
    return json.loads((out_dir / "report.json").read_text())


def steps(rep):
    return {s["step"]: s for s in rep["preprocess"]["steps"]}


def test_brain_label_map_interpolated_staircase_gone(capsys, tmp_path):
    brain = shared("pyradiomics_brain1", "brain1_label.nrrd")
    code, out, err = cli(capsys, "mesh", brain, "--out", tmp_path / "a", "--interpolate", "--format", "ply,glb",
                         "--difference-colors")
    assert code == 0, err
    assert "preprocess interpolate" in out and "difference colours" in out
    rep = report(tmp_path / "a")
    step = steps(rep)["interpolate"]
    assert step["grid"]["spacing"] == pytest.approx([0.78125] * 3, abs=1e-5)
    assert step["effect"]["max_mm"] < 6.5 and 0.2 < step["effect"]["mean_mm"] < 1.5  # within one slice
    assert rep["input"]["spacing"] == pytest.approx([0.78125] * 3, abs=1e-5)
    assert rep["preprocess"]["input"]["spacing"][2] == pytest.approx(6.5)
    # the smoothed surface without preprocessing keeps the 6.5 mm staircase; with it, it is gone
    code, _, err = cli(capsys, "mesh", brain, "--out", tmp_path / "b", "--format", "glb")
    assert code == 0, err
    (plain,) = read_glb(tmp_path / "b" / "brain1_label.glb")
    (smooth,) = read_glb(tmp_path / "a" / "brain1_label.glb")
    assert largest_jump(cross_sections(smooth)) < largest_jump(cross_sections(plain)) / 1.5
    # the colours: a diverging map, white where nothing moved, saturated at the reported scale
    diff = rep["preprocess"]["difference"]
    assert smooth.vertex_colors is not None and diff["scale_mm"] > 0
    assert 0 < diff["surfaces"]["1"]["mean_mm"] < diff["surfaces"]["1"]["max_mm"] < 6.5
    ply = (tmp_path / "a" / "brain1_label.ply").read_bytes()
    assert b"property uchar red" in ply


def test_reported_difference_matches_an_independent_measurement(capsys, tmp_path):
    """A noisy sphere (NIfTI) smoothed with a 1 mm Gaussian: the report's mean and max distance
    between the surfaces before and after equal a measurement made here with scipy's Gaussian
    filter and a k-d tree over densely sampled surface points."""
    (x, y, z), affine = grid((44, 44, 44), (1.0, 1.0, 1.0))
    clean = 1000.0 / (1.0 + np.exp((np.sqrt(x**2 + y**2 + z**2) - 14.0) / 0.7))
    data = (clean + np.random.default_rng(5).normal(0, 60, clean.shape)).astype(np.float32)
    path = tmp_path / "sphere.nii.gz"
    nib.save(nib.Nifti1Image(data, affine), str(path))
    code, _, err = cli(capsys, "mesh", path, "--out", tmp_path / "o", "--level", "500",
                       "--smooth-volume", "gaussian:1", "--smooth", "none")
    assert code == 0, err
    effect = steps(report(tmp_path / "o"))["smooth_volume"]["effect"]["surfaces"]["500"]
    before = isosurface(Volume(data, affine), 500.0, cap=True)
    after = isosurface(Volume(ndimage.gaussian_filter(data, 1.0, mode="nearest", truncate=3.0), affine),
                       500.0, cap=True)
    d = np.concatenate([_dense_distances(before, after), _dense_distances(after, before)])
    assert effect["mean_mm"] == pytest.approx(d.mean(), rel=0.1, abs=0.01)
    assert effect["max_mm"] == pytest.approx(d.max(), rel=0.1, abs=0.05)


def _dense_distances(a, b, k=12):
    """Distances from the vertices and face centroids of ``a`` (the samples the report uses) to
    ``b``, computed here without the library: candidate triangles from a k-d tree over random
    points on ``b`` (the triangles of the ``k`` nearest), then the exact distance to each
    candidate as the least of the distance to its plane (when the foot falls inside it) and to
    its three sides."""
    rng = np.random.default_rng(0)
    tri = b.vertices[b.faces].astype(np.float64)
    w = rng.dirichlet([1, 1, 1], size=(len(tri), 8))
    cloud = np.einsum("fnk,fkd->fnd", w, tri).reshape(-1, 3)
    owner = np.repeat(np.arange(len(tri)), 8)
    p = np.concatenate([a.vertices, a.vertices[a.faces].mean(axis=1)]).astype(np.float64)
    _, idx = cKDTree(cloud).query(p, k=k)
    t = tri[owner[idx]]  # (P, k, 3, 3)
    q = p[:, None, :]
    e0, e1 = t[:, :, 1] - t[:, :, 0], t[:, :, 2] - t[:, :, 0]
    n = np.cross(e0, e1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    h = np.einsum("pkd,pkd->pk", q - t[:, :, 0], n)
    foot = q - h[..., None] * n
    inside = np.ones(h.shape, bool)
    for i in range(3):  # the foot is inside when it lies left of every side (same winding as n)
        u, v = t[:, :, i], t[:, :, (i + 1) % 3]
        inside &= np.einsum("pkd,pkd->pk", np.cross(v - u, foot - u), n) >= 0
    best = np.where(inside, np.abs(h), np.inf)
    for i in range(3):
        u, v = t[:, :, i], t[:, :, (i + 1) % 3]
        s = np.clip(np.einsum("pkd,pkd->pk", q - u, v - u) / np.einsum("pkd,pkd->pk", v - u, v - u), 0, 1)
        best = np.minimum(best, np.linalg.norm(q - (u + s[..., None] * (v - u)), axis=-1))
    return best.min(axis=1)


def test_scalar_steps_from_a_recipe_on_the_head_ct(capsys, tmp_path):
    head = shared("slicer_ctheadaxial")
    text = (f'[input]\npath = "{head}"\nlevels = [1150.0]\n[preprocess]\nresample = 2.0\n'
            'resample_method = "cubic"\nsmooth_volume = "diffusion:5"\nprecise = true\n'
            f'[smoothing]\nmethod = "none"\n[output]\ndir = "{tmp_path / "o"}"\nformats = ["stl"]\n')
    (tmp_path / "r.toml").write_text(text)
    code, out, err = cli(capsys, "mesh", "--recipe", tmp_path / "r.toml")
    assert code == 0, err
    rep = report(tmp_path / "o")
    got = steps(rep)
    assert list(got) == ["resample", "smooth_volume", "precise"]
    assert got["resample"]["grid"]["spacing"] == pytest.approx([2.0] * 3)
    assert got["resample"]["params"] == {"spacing_mm": [2.0], "method": "cubic"}
    assert got["smooth_volume"]["info"]["iterations"] == 5
    for name in ("resample", "smooth_volume"):
        e = got[name]["effect"]
        assert 0 < e["mean_mm"] <= e["p99_mm"] <= e["max_mm"]
    p = got["precise"]["info"]["surfaces"]["1150"]
    assert p["faces_after"] == p["faces_before"] + 2 * p["split_faces"] and p["seconds"] >= 0
    assert rep["surfaces"][0]["faces"] == p["faces_after"] and rep["surfaces"][0]["closed"]
    saved = load_recipe(tmp_path / "o" / "recipe.toml")  # the run's recipe keeps the section
    assert (saved.resample, saved.resample_method, saved.smooth_volume, saved.precise) == (
        [2.0], "cubic", "diffusion:5", True)


def test_fuzzy_shells_in_the_glb(capsys, tmp_path):
    head = shared("slicer_ctheadaxial")
    code, out, err = cli(capsys, "mesh", head, "--out", tmp_path, "--fuzzy", "400", "800", "3",
                         "--format", "glb", "--smooth", "none")
    assert code == 0, err
    shells = read_glb(tmp_path / "slicer_ctheadaxial.glb")
    assert [m.value for m in shells] == [400, 600, 800]
    assert [round(m.color[3], 2) if len(m.color) == 4 else 1.0 for m in shells] == [0.5, 1.0, 0.5]
    assert steps(report(tmp_path))["fuzzy"]["alphas"] == [0.5, 1.0, 0.5]


def test_label_topology_and_fuzzy_boundary_on_totalsegmentator(capsys, tmp_path):
    code, out, err = cli(capsys, "mesh", SEG, "--out", tmp_path / "t", "--labels", "liver,spleen,aorta",
                         "--fill-cavities", "--close-handles", "6", "--smooth", "none")
    assert code == 0, err
    got = steps(report(tmp_path / "t"))
    assert list(got) == ["fill_cavities", "close_handles"]
    for entry in got["close_handles"]["effect"]["surfaces"].values():
        assert entry["genus_after"] <= entry["genus_before"]
        assert entry["components_after"] <= entry["components_before"]
    labels = got["close_handles"]["info"]["labels"]
    assert set(labels) == {"5", "1", "52"} and labels["5"]["name"] == "liver"
    assert all(v["after"]["handles"] <= v["before"]["handles"] for v in labels.values())
    code, out, err = cli(capsys, "mesh", SEG, "--out", tmp_path / "f", "--labels", "liver,spleen,aorta",
                         "--fuzzy-boundary", "--smooth", "none")
    assert code == 0, err
    assert "within one voxel" in out
    effect = steps(report(tmp_path / "f"))["fuzzy_boundary"]["effect"]
    assert effect["within_one_voxel"] and effect["max_mm"] <= 3.0
    for s in report(tmp_path / "f")["surfaces"]:
        assert s["closed"] and s["manifold"]


def test_roi_and_resample_on_the_chest_ct(capsys, tmp_path):
    chest = shared("itkelastix_chest_ct")
    code, out, err = cli(capsys, "mesh", chest, "--out", tmp_path, "--level", "300", "--roi",
                         "-60", "-60", "-1000", "60", "60", "1000", "--resample", "1.5", "--smooth", "none")
    assert code == 0, err
    rep = report(tmp_path)
    roi = steps(rep)["roi"]
    assert roi["grid"]["shape"][0] in (122, 123) and roi["grid"]["shape"][2] == 141  # 120 mm / 0.977
    assert rep["surfaces"][0]["faces"] > 1000 and rep["input"]["spacing"] == pytest.approx([1.5] * 3)
    assert np.array(rep["input"]["extent_mm"]) == pytest.approx([120.0, 120.0, 282.0], abs=2.0)
    code, _, err = cli(capsys, "mesh", chest, "--out", tmp_path / "b", "--level", "300",
                       "--roi=-60,-60,-1000,60,60,1000", "--smooth", "none")  # the comma form
    assert code == 0, err
    assert steps(report(tmp_path / "b"))["roi"]["grid"]["shape"] == roi["grid"]["shape"]


def test_inspect_histogram_picture_and_hints(capsys, tmp_path):
    code, out, err = cli(capsys, "inspect", shared("itkelastix_chest_ct"), "--histogram",
                         tmp_path / "h.png", "--level", "bone:300", "--level", "skin:-500")
    assert code == 0, err
    png = (tmp_path / "h.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20], "big") == 960
    assert "hint" in out and "--resample" in out
    code, out, err = cli(capsys, "inspect", shared("pyradiomics_brain1", "brain1_label.nrrd"), "--json")
    facts = json.loads(out)
    assert any("6.5 mm apart" in h and "--interpolate" in h for h in facts["hints"])


def test_preview_gallery_png(capsys, tmp_path):
    code, out, err = cli(capsys, "preview", shared("slicer_ctheadaxial"), "--out", tmp_path / "g.png",
                         "--levels", "skin:500", "bone:1150", "--size", "128")
    assert code == 0, err
    assert "skin 500" in out and "bone 1150" in out
    png = (tmp_path / "g.png").read_bytes()
    w, h = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert w == 2 * 128 + 3 * 6 and h > 128
    code, _, err = cli(capsys, "preview", shared("slicer_ctheadaxial"), "--out", tmp_path / "g.png")
    assert code == 2 and "already exist" in err  # no silent overwrite


@pytest.mark.parametrize("argv, words", [
    (["--resample", "-1"], "--resample"),
    (["--resample", "1,2"], "--resample takes 1 or 3"),
    (["--resample-method", "nearest"], "--resample-method"),
    (["--roi", "1,2,3"], "--roi takes 6"),
    (["--smooth-volume", "blur:2"], "--smooth-volume"),
    (["--smooth-volume", "diffusion:x"], "diffusion:ITERATIONS"),
    (["--close-handles", "abc"], "--close-handles"),
    (["--fuzzy", "1"], "--fuzzy"),
    (["--fuzzy", "5", "5"], "--fuzzy"),
    (["--interpolate"], "for label maps"),
])
def test_bad_parameters_are_one_line_exit_2(capsys, tmp_path, argv, words):
    code, out, err = cli(capsys, "mesh", shared("slicer_ctheadaxial"), "--out", tmp_path, "--level", "500", *argv)
    assert code == 2
    assert words in err and len(err.strip().splitlines()) == 1, err


def test_recipe_section_round_trips_and_rejects_bad_keys():
    r = Recipe(input="x.nii", resample=[1.0, 1.0, 2.0], roi=[0, 0, 0, 10, 10, 10], smooth_volume="median:2",
               interpolate=True, close_handles=3.0, fuzzy=[100.0, 200.0, 7.0], difference_colors=True)
    text = dump_recipe(r)
    assert "[preprocess]" in text and 'smooth_volume = "median:2"' in text
    back = recipe_from_text(text)
    assert (back.resample, back.roi, back.fuzzy, back.close_handles) == (r.resample, r.roi, r.fuzzy, 3.0)
    from anatomesh.core.model.errors import AnatomeshError
    with pytest.raises(AnatomeshError, match="allowed keys"):
        recipe_from_text("[preprocess]\nsharpen = true\n")
    with pytest.raises(AnatomeshError, match="roi must be"):
        recipe_from_text("[preprocess]\nroi = [1, 2]\n")


def test_python_door_gives_the_same_report(tmp_path):
    brain = shared("pyradiomics_brain1", "brain1_label.nrrd")
    res = run_recipe(Recipe(input=str(brain), out_dir=str(tmp_path), interpolate=True, fill_cavities=True,
                            smooth="none"))
    assert [s["step"] for s in res.preprocess["steps"]] == ["interpolate", "fill_cavities"]
    t = topology(res.surfaces[0].vertices, res.surfaces[0].faces)
    assert t.closed and res.report["preprocess"] == res.preprocess
