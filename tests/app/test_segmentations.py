"""Segmentations as users have them, through the one flow (``app.run`` and the ``anatomesh``
command): the TotalSegmentator aorta folder (every structure, raw volumes = voxel counts x voxel
volume, lumina inside the aorta, layers and overlaps in the report), DICOM folders with an RTSTRUCT
or a SEG (meshed by default, said on stderr), both contour methods, DICOM write-back, bad input
(exit 2, one line, nothing written)."""
from __future__ import annotations

import json
import shutil

import nibabel as nib
import numpy as np
import pydicom
import pytest

from anatomesh.app.cli import main
from anatomesh.app.flow.recipe import Recipe, load_recipe
from anatomesh.app.flow.run import run
from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import signed_volume
from helpers.readback import pinch_volume_bound
from conftest import shared

AORTA = shared("totalsegmentator", "aorta")
STS = shared("rtstruct", "sts_001")
CT3 = shared("dicom_seg", "dcmqi_ct3slice")


def cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def aorta_raw(tmp_path_factory):
    out = tmp_path_factory.mktemp("aorta")
    return run(Recipe(input=str(AORTA), out_dir=str(out), smooth="none", space="RAS"))


def test_aorta_every_structure_raw_volume_is_its_voxels(aorta_raw):
    res = aorta_raw
    names = sorted(p.name[: -len(".nii.gz")] for p in AORTA.glob("*.nii.gz") if not p.name.startswith("ct"))
    assert sorted(m.name for m in res.surfaces) == names
    for m in res.surfaces:
        topo = topology(m.vertices, m.faces)
        assert topo.closed and topo.manifold and topo.oriented, m.name
        voxels = int((np.asanyarray(nib.load(str(AORTA / f"{m.name}.nii.gz")).dataobj) > 0).sum())
        error = signed_volume(m.vertices, m.faces) - voxels * 1.5 ** 3
        assert abs(error) <= pinch_volume_bound(m.meta["pinch_points"], voxels * 1.5 ** 3, 1.5 ** 3), m.name
    rep = json.loads(res.report_path.read_text())
    layers = {n: layer["layer"] for layer in rep["layers"] for n in layer["structures"]}
    assert layers["aorta"] != layers["aorta_true_lumen"] and layers["aorta"] != layers["aorta_false_lumen"]
    assert any(o["a"] == "aorta" and o["b"] == "aorta_true_lumen" and o["mm3"] > 1e5 for o in rep["overlaps"])


def test_lumina_inside_the_aorta_as_separate_shells(tmp_path):
    res = run(Recipe(input=str(AORTA), out_dir=str(tmp_path), labels=["aorta", "aorta_true_lumen",
                                                                       "aorta_false_lumen"], space="LPS"))
    by = {m.name: m for m in res.surfaces}
    outer = TriangleGrid(by["aorta"].vertices, by["aorta"].faces)
    aorta = np.asanyarray(nib.load(str(AORTA / "aorta.nii.gz")).dataobj) > 0
    lps = nib.load(str(AORTA / "aorta.nii.gz")).affine.copy()
    lps[:2] *= -1  # NIfTI RAS → LPS
    for lumen in ("aorta_true_lumen", "aorta_false_lumen"):
        m = by[lumen]
        ids = set(np.asarray(m.meta["vertex_ids"]).tolist())
        assert not ids & set(np.asarray(by["aorta"].meta["vertex_ids"]).tolist())  # own shell, own layer
        tri = m.vertices[m.faces].astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        just_inside = tri.mean(axis=1) - 0.5 * n  # half a millimetre inside the lumen's wall
        assert outer.contains(just_inside).mean() > 0.8, lumen  # the masks are not fully nested
        vox = np.asanyarray(nib.load(str(AORTA / f"{lumen}.nii.gz")).dataobj) > 0
        nested = (vox & aorta).sum() / vox.sum()  # 0.96 (true lumen), 0.92 (false lumen)
        centres = (lps[:3, :3] @ np.argwhere(vox).T + lps[:3, 3:4]).T
        assert outer.contains(centres).mean() == pytest.approx(nested, abs=0.02), lumen
        assert signed_volume(m.vertices, m.faces) < signed_volume(by["aorta"].vertices, by["aorta"].faces)


def test_dicom_folder_with_rtstruct_both_methods_and_dicom_output(capsys, tmp_path):
    code, out, err = cli(capsys, "mesh", STS, "--out", tmp_path / "raster", "--format", "stl,dicom")
    assert code == 0, err
    assert "note: meshing the RTSTRUCT object RS.dcm" in err
    dcm = pydicom.dcmread(tmp_path / "raster" / "GTV_Mass_CT.dcm")
    assert dcm.StudyInstanceUID == pydicom.dcmread(STS / "RS.dcm", stop_before_pixels=True).StudyInstanceUID
    code, out, err = cli(capsys, "mesh", STS, "--out", tmp_path / "tile", "--contours", "tile", "--smooth", "none")
    assert code == 0, err
    a = json.loads((tmp_path / "raster" / "report.json").read_text())["surfaces"][0]
    b = json.loads((tmp_path / "tile" / "report.json").read_text())["surfaces"][0]
    assert a["closed"] and b["closed"] and a["name"] == b["name"] == "GTV_Mass_CT"
    assert abs(a["volume_mm3"] - b["volume_mm3"]) / b["volume_mm3"] < 0.02
    recipe = load_recipe(tmp_path / "tile" / "recipe.toml")
    assert recipe.contours == "tile"


def test_series_picks_the_image_and_inspect_lists(capsys, tmp_path):
    code, out, err = cli(capsys, "inspect", STS)
    assert code == 0 and "RTSTRUCT" in out and "[1] image" in out
    code, out, err = cli(capsys, "mesh", STS, "--series", "1", "--level", "300", "--out", tmp_path)
    assert code == 0, err
    code, out, err = cli(capsys, "inspect", CT3, "--json")
    assert code == 0 and len(json.loads(out)["dicom_contents"]) == 5


def test_bad_input_exit_2_one_line_nothing_written(capsys, tmp_path):
    bad = tmp_path / "masks"
    bad.mkdir()
    m = np.zeros((6, 6, 6), np.uint8)
    m[1:3, 1:3, 1:3] = 3
    nib.save(nib.Nifti1Image(m, np.eye(4)), str(bad / "liver.nii.gz"))
    mixed = tmp_path / "mixed"
    shutil.copytree(STS / "ct", mixed / "ct")
    shutil.copy(CT3 / "liver.dcm", mixed)
    for path, words in ((bad, "only 0 and 1"), (mixed, "unrelated studies")):
        out = tmp_path / f"out_{path.name}"
        code, _, err = cli(capsys, "mesh", path, "--out", out)
        assert code == 2 and words in err and err.count("\n") == 1, err
        assert not out.exists()
