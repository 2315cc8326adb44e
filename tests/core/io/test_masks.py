"""Folders and lists of binary masks (TotalSegmentator, 3D Slicer segment exports) → label-map
layers: names and colours from file names, the CT recognised as the image, masks on other grids
placed by their affines, overlapping structures in separate layers, bad input refused."""
from __future__ import annotations

import nibabel as nib
import numpy as np
import pytest

from anatomesh.core import load
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.labels import anatomical_color
from anatomesh.core.model.segmentation import Segmentation, as_layers
from conftest import shared

AORTA = shared("totalsegmentator", "aorta")
PULMONARY = shared("totalsegmentator", "pulmonary")
AORTA_NAMES = ["aorta", "aorta_false_lumen", "aorta_true_lumen", "brachiocephalic_trunk", "celiac_trunk",
               "common_carotid_artery_left", "subclavian_artery_left", "superior_mesenteric_artery",
               "vertebrae_T12"]


def _mask(path):
    return np.asanyarray(nib.load(str(path)).dataobj) > 0


def _structure(seg, name):
    """(layer, value) of a structure by name."""
    for layer in as_layers(seg):
        for v, info in (layer.labels or {}).items():
            if info.name == name:
                return layer, v
    raise KeyError(name)


def test_aorta_folder_layers_names_colours_and_image():
    seg = load(AORTA)
    assert isinstance(seg, Segmentation)
    assert seg.meta["image"].endswith("ct_cropped.nii.gz")  # the CT is the image, not a mask
    assert [i.name for i in seg.labels.values()] == AORTA_NAMES
    assert seg.labels[1].color[0] > 0.7 and seg.labels[1].color[2] < 0.3  # arteries red
    assert anatomical_color("vertebrae_T12") is not None
    for name in AORTA_NAMES:  # every structure whole, voxel for voxel, on its own (common) grid
        layer, v = _structure(seg, name)
        np.testing.assert_array_equal(layer.data == v, _mask(AORTA / f"{name}.nii.gz"))
    layer_of = {seg.labels[v].name: i for v, i in seg.layer_of().items()}
    assert layer_of["aorta"] != layer_of["aorta_true_lumen"]
    assert layer_of["aorta"] != layer_of["aorta_false_lumen"]
    assert layer_of["aorta"] == layer_of["vertebrae_T12"]  # no overlap: one conforming layer
    pairs = {(o["a"], o["b"]): o for o in seg.overlaps}
    aorta, lumen = _mask(AORTA / "aorta.nii.gz"), _mask(AORTA / "aorta_true_lumen.nii.gz")
    assert pairs[("aorta", "aorta_true_lumen")]["voxels"] == int((aorta & lumen).sum())
    assert pairs[("aorta", "aorta_true_lumen")]["mm3"] == pytest.approx((aorta & lumen).sum() * 1.5 ** 3)


def test_masks_on_another_grid_are_placed_by_their_affines():
    seg = load(PULMONARY)
    assert "heart" in seg.meta["grid"]  # finest grid (tie: first), covering both structures
    moved = {r["name"]: r for r in seg.meta["resampled"]}
    assert "shifted" in moved["pulmonary_artery"]["how"]
    layer, v = _structure(seg, "pulmonary_artery")
    src = nib.load(str(PULMONARY / "pulmonary_artery.nii.gz"))
    assert int((layer.data == v).sum()) == int(_mask(PULMONARY / "pulmonary_artery.nii.gz").sum())
    # a voxel of the mask lands at the same place in mm
    ijk = np.argwhere(_mask(PULMONARY / "pulmonary_artery.nii.gz"))[0]
    mm_ras = src.affine @ np.r_[ijk, 1.0]
    dst = np.linalg.inv(layer.affine) @ mm_ras
    assert np.allclose(dst, np.round(dst), atol=1e-4)
    assert layer.data[tuple(np.round(dst[:3]).astype(int))] == v
    on_ct = load(PULMONARY, grid="image")
    assert "image" in on_ct.meta["grid"]
    layer, v = _structure(on_ct, "heart")
    assert int((layer.data == v).sum()) == int(_mask(PULMONARY / "heart.nii.gz").sum())


def _save(path, data, affine=np.diag([1.5, 1.5, 1.5, 1.0])):
    nib.save(nib.Nifti1Image(np.asarray(data), affine), str(path))


def test_list_of_masks_and_resampling_by_nearest_neighbour(tmp_path):
    a = np.zeros((20, 20, 20), np.uint8)
    a[5:15, 5:15, 5:15] = 1
    _save(tmp_path / "liver.nii.gz", a, np.diag([1.0, 1.0, 1.0, 1.0]))
    b = np.zeros((10, 10, 10), np.uint8)
    b[1:4, 1:4, 1:4] = 1  # 2 mm voxels: 6 mm cube at 2..8 mm (centres), i.e. 1..7 mm edges
    _save(tmp_path / "spleen.nii.gz", b, np.diag([2.0, 2.0, 2.0, 1.0]))
    vol = load([tmp_path / "liver.nii.gz", tmp_path / "spleen.nii.gz"])
    layers = as_layers(vol)
    assert layers[0].spacing == pytest.approx((1.0, 1.0, 1.0))  # the finest grid
    how = {r["name"]: r["how"] for r in vol.meta["resampled"]}
    assert "nearest" in how["spleen"]
    _, v = _structure(vol, "spleen")
    n = sum(int((lay.data == v).sum()) for lay in layers)
    assert n == 6 ** 3  # 27 voxels of 8 mm³ → 216 voxels of 1 mm³
    assert vol.labels[v].name == "spleen"


def test_bad_masks(tmp_path):
    m = np.zeros((8, 8, 8), np.uint8)
    m[2:5, 2:5, 2:5] = 2
    m[2, 2, 2] = 1  # two structures in one file: a label map, not a mask
    _save(tmp_path / "liver.nii.gz", m)
    with pytest.raises(AnatomeshError, match="liver.nii.gz: holds 2 different nonzero values") as err:
        load(tmp_path)
    assert "split a label map into one 0/1 mask per structure" in str(err.value) and "\n" not in str(err.value)
    m[m > 0] = 3  # one value other than 1 (or 255): one label cut out of a label map, refused too
    _save(tmp_path / "liver.nii.gz", m)
    refused = r"liver.nii.gz: holds only the values 0 and 3 .*only 0 and 1 \(or 0 and 255\)"
    with pytest.raises(AnatomeshError, match=refused):
        load(tmp_path)
    m[m > 0] = 1
    _save(tmp_path / "liver.nii.gz", m)
    _save(tmp_path / "kidney_left.nii.gz", np.zeros((8, 8, 8), np.uint8))
    vol = load(tmp_path)
    assert any("kidney_left" in w and "empty" in w for w in vol.warnings)
    assert [i.name for i in vol.labels.values()] == ["liver"]
    with pytest.raises(AnatomeshError, match="grid"):
        load(tmp_path, grid="no_such_structure")


# -- masks that are not 0/1: used by a stated rule, refused, or the image, never dropped -----------------
def _blob(shape=(12, 12, 12)):
    m = np.zeros(shape, np.float32)
    m[3:9, 3:9, 3:9] = 1.0
    return m


def _notes(vol):
    return " | ".join(vol.meta["notes"])


def test_probability_map_is_thresholded_at_one_half_with_a_note(tmp_path):
    prob = _blob() * 0.9
    prob[3:9, 3:9, 3] = 0.4  # below one half: outside
    prob[3:9, 3:9, 8] = 0.5  # exactly one half: inside
    _save(tmp_path / "liver.nii.gz", prob)
    _save(tmp_path / "spleen.nii.gz", _blob().astype(np.uint8))
    vol = load(tmp_path)
    assert sorted(i.name for i in vol.labels.values()) == ["liver", "spleen"]  # not taken as "the image"
    assert vol.meta["image"] is None
    layer, v = _structure(vol, "liver")
    np.testing.assert_array_equal(layer.data == v, prob >= 0.5)
    assert int((layer.data == v).sum()) == 6 * 6 * 5
    assert "liver.nii.gz holds fractions within 0..1 (a probability map): voxels at or above 0.5 were " \
           "taken as inside" in _notes(vol)


def test_0_255_mask_is_its_nonzero_voxels_with_a_note(tmp_path):
    _save(tmp_path / "kidney_left.nii.gz", (_blob() * 255).astype(np.uint8))
    vol = load(tmp_path)
    layer, v = _structure(vol, "kidney_left")
    assert int((layer.data == v).sum()) == 6 ** 3
    assert "kidney_left.nii.gz holds the values 0 and 255: voxels of value 255 (> 0) were taken as inside" \
        in _notes(vol)


def test_only_a_real_scan_is_the_image_and_that_is_said(tmp_path):
    ct = np.full((12, 12, 12), -1000, np.int16)
    ct[2:10, 2:10, 2:10] = 40
    _save(tmp_path / "ct.nii.gz", ct)
    _save(tmp_path / "liver.nii.gz", _blob().astype(np.uint8))
    vol = load(tmp_path)
    assert vol.meta["image"].endswith("ct.nii.gz") and [i.name for i in vol.labels.values()] == ["liver"]
    assert "ct.nii.gz was taken as the image, not a mask (values -1000..40: a scan)" in _notes(vol)
    mr = np.random.default_rng(0).uniform(0, 900, (12, 12, 12)).astype(np.float32)  # fractions beyond 1
    _save(tmp_path / "ct.nii.gz", mr)
    assert load(tmp_path).meta["image"].endswith("ct.nii.gz")
    _save(tmp_path / "mr.nii.gz", mr)
    with pytest.raises(AnatomeshError, match="two images among the masks"):
        load(tmp_path)
