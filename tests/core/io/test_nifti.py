"""NIfTI reader (core/io/nifti.py) on the real TotalSegmentator files and on broken inputs."""
from __future__ import annotations

import gzip
import json
import shutil

import nibabel as nib
import numpy as np
import pytest
from conftest import SHARED_DATA, shared

import anatomesh.core.model.volume as volume_mod
from anatomesh.core import load
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.io.nifti import read_nifti

TS = "totalsegmentator"
NAMES = (TS, "label_names_total_and_total_mr.json")
AORTA_MASKS = ("aorta", "aorta_false_lumen", "aorta_true_lumen", "brachiocephalic_trunk",
               "celiac_trunk", "common_carotid_artery_left", "subclavian_artery_left",
               "superior_mesenteric_artery", "vertebrae_T12")

# path, shape, spacing (mm), orientation, number of labels (None: a scan), table key
CASES = [
    ("example_ct_sm.nii.gz", (122, 101, 30), (3, 3, 3), "RAS", None, None),
    ("example_seg.nii.gz", (122, 101, 30), (3, 3, 3), "RAS", 41, "total"),
    ("example_ct.nii.gz", (122, 101, 112), (3, 3, 3), "RAS", None, None),
    ("example_seg_fast_force_split.nii.gz", (122, 101, 112), (3, 3, 3), "RAS", 61, "total"),
    ("example_mr_sm.nii.gz", (117, 91, 20), (3, 3, 3), "LPS", None, None),
    ("example_seg_mr.nii.gz", (117, 91, 20), (3, 3, 3), "LPS", 23, "total_mr"),
    ("example_seg_dicom.nii.gz", (512, 512, 20), (0.977, 0.977, 2.0), "LAS", 31, "total"),
    ("aorta/ct_cropped.nii.gz", (120, 126, 164), (1.5, 1.5, 1.5), "LPS", None, None),
    *[(f"aorta/{m}.nii.gz", (120, 126, 164), (1.5, 1.5, 1.5), "LPS", 1, None) for m in AORTA_MASKS],
    ("pulmonary/ct_cropped.nii.gz", (122, 102, 112), (1.5, 1.5, 1.5), "LPS", None, None),
    ("pulmonary/heart.nii.gz", (233, 167, 191), (1.5, 1.5, 1.5), "LPS", 1, None),
    ("pulmonary/pulmonary_artery.nii.gz", (122, 102, 112), (1.5, 1.5, 1.5), "LPS", 1, None),
    # TotalSegmentator --fast, both ways: the 40-label map, and one mask per class of the "total" task
    ("fast_folder/example_seg_fast.nii.gz", (122, 101, 30), (3, 3, 3), "RAS", 40, "total"),
    *[(f"fast_folder/example_seg_tissue_types/{m}.nii.gz", (122, 101, 30), (3, 3, 3), "RAS", 1, None)
      for m in ("skeletal_muscle", "subcutaneous_fat", "torso_fat")],
]


def _fast_masks():
    """One case per mask of the --fast folder, named by TotalSegmentator's own statistics.json of
    that run: one label when it gives the structure a volume, none (an empty mask) otherwise."""
    stats = json.loads(shared(TS, "fast_folder", "example_seg_fast", "statistics.json").read_text())
    return [(f"fast_folder/example_seg_fast/{name}.nii.gz", (122, 101, 30), (3, 3, 3), "RAS",
             1 if facts["volume"] > 0 else 0, None) for name, facts in sorted(stats.items())]


CASES += _fast_masks()


def test_cases_cover_every_shared_nifti():
    found = {str(p.relative_to(SHARED_DATA / TS)) for p in (SHARED_DATA / TS).rglob("*.nii*")}
    assert found == {c[0] for c in CASES}
    fast = [c for c in CASES if c[0].startswith("fast_folder/example_seg_fast/")]
    assert len(fast) == 117 and sum(c[4] == 0 for c in fast) == 77  # 40 structures found, 77 empty


@pytest.mark.parametrize("rel, shape, spacing, orient, n_labels, key", CASES, ids=[c[0] for c in CASES])
def test_real_nifti(rel, shape, spacing, orient, n_labels, key):
    path = shared(TS, *rel.split("/"))
    names_json = shared(*NAMES)
    vol = read_nifti(path, labels=names_json if key else None)
    img = nib.load(str(path))
    hdr = img.header
    assert vol.shape == shape
    np.testing.assert_allclose(vol.spacing, spacing, atol=1e-3)
    assert vol.space == "RAS" and vol.orientation() == orient
    assert "".join(nib.aff2axcodes(img.affine)) == orient
    # geometry: nibabel's affine, and the raw sform rows the files carry (sform_code 2)
    np.testing.assert_allclose(vol.affine, img.affine, atol=1e-6)
    assert int(hdr["sform_code"]) > 0
    sform = np.vstack([hdr["srow_x"], hdr["srow_y"], hdr["srow_z"], [0, 0, 0, 1]])
    np.testing.assert_allclose(vol.affine, sform, atol=1e-4)
    # voxels unchanged, dtype kept (no scaling in these files)
    raw = np.asanyarray(img.dataobj)
    np.testing.assert_array_equal(vol.data, raw)
    assert vol.warnings == ([] if n_labels != 0 else ["the label map is empty (all voxels are 0, background)"])
    assert vol.meta["format"] == "NIfTI-1" and vol.meta["source"] == str(path)
    if n_labels is None:
        assert not vol.is_label_map and vol.labels is None
        assert vol.data.dtype == raw.dtype and vol.data.dtype.kind == "i"
        return
    assert vol.is_label_map and vol.data.dtype == np.uint8
    values = [int(v) for v in np.unique(raw) if v]
    assert len(vol.labels) == n_labels == len(values) and sorted(vol.labels) == values
    if key:
        table = json.loads(names_json.read_text())[key]
        assert vol.meta["label_table"].endswith(f"#{key}")
        assert all(info.name == table[str(v)] for v, info in vol.labels.items())
    elif n_labels:  # a binary mask is named after its file
        (info,) = vol.labels.values()
        assert info.value == 1 and info.name == rel.split("/")[-1][: -len(".nii.gz")]


def test_liver_is_value_5_in_the_total_table():
    assert json.loads(shared(*NAMES).read_text())["total"]["5"] == "liver"
    vol = read_nifti(shared(TS, "example_seg.nii.gz"), labels=shared(*NAMES))
    assert vol.labels[5].name == "liver"
    assert vol.labels[5].color != vol.labels[1].color  # liver vs spleen


def test_names_file_in_the_folder_is_a_sidecar(tmp_path):
    vol = read_nifti(shared(TS, "example_seg.nii.gz"))
    # the shared folder holds label_names*.json, found as a sidecar
    assert vol.meta["label_table"].endswith("label_names_total_and_total_mr.json#total")
    assert vol.labels[5].name == "liver"
    # but a single-structure mask keeps its file name (value 1 would be "spleen")
    shutil.copy(shared(TS, "aorta", "aorta.nii.gz"), tmp_path / "aorta.nii.gz")
    shutil.copy(shared(*NAMES), tmp_path)
    assert read_nifti(tmp_path / "aorta.nii.gz").labels[1].name == "aorta"


def test_generic_names_and_forbidden_label_map(tmp_path):
    p = tmp_path / "seg.nii.gz"
    shutil.copy(shared(TS, "example_seg.nii.gz"), p)
    vol = read_nifti(p)
    assert vol.is_label_map and vol.labels[5].name == "label_5" and len(vol.labels) == 41
    assert vol.meta["label_table"] == "generic names"
    scan = read_nifti(p, label_map=False)
    assert scan.labels is None and scan.data.dtype == np.uint8


def test_ct_is_never_a_label_map():
    p = shared(TS, "example_ct_sm.nii.gz")
    assert read_nifti(p).labels is None
    with pytest.raises(AnatomeshError, match="negative values.*is this a scan"):
        read_nifti(p, label_map=True)
    with pytest.raises(AnatomeshError, match="a label table was given but the image has negative"):
        read_nifti(p, labels=shared(*NAMES))


def test_mask_on_another_grid_than_the_ct():
    """pulmonary/heart.nii.gz and ct_cropped.nii.gz have different grids: the affines line them up."""
    heart_p, ct_p = shared(TS, "pulmonary", "heart.nii.gz"), shared(TS, "pulmonary", "ct_cropped.nii.gz")
    heart, ct = read_nifti(heart_p), read_nifti(ct_p)
    assert heart.shape != ct.shape
    h_aff, c_aff = nib.load(str(heart_p)).affine, nib.load(str(ct_p)).affine
    ijk = np.round(np.argwhere(heart.data > 0).mean(axis=0)).astype(int)  # centre of the heart
    assert heart.data[tuple(ijk)] == 1
    world = heart.affine @ np.r_[ijk, 1]
    np.testing.assert_allclose(world, nib.affines.apply_affine(h_aff, ijk).tolist() + [1], atol=1e-6)
    ct_ijk = np.linalg.solve(ct.affine, world)[:3]
    np.testing.assert_allclose(ct_ijk, nib.affines.apply_affine(np.linalg.inv(c_aff), world[:3]), atol=1e-6)
    np.testing.assert_allclose(ct_ijk, np.round(ct_ijk), atol=1e-4)  # same spacing, integer offset
    assert ct_ijk.tolist() != ijk.tolist()
    ct_val = ct.data[tuple(np.round(ct_ijk).astype(int))]
    assert ct_val > 150  # contrast-filled blood in the heart, not air or fat


def test_mr_orientation_is_lps():
    vol = read_nifti(shared(TS, "example_mr_sm.nii.gz"))
    assert vol.orientation() == "LPS"
    assert vol.in_space("LPS").orientation() == "LPS"
    # the first voxel's position in RAS from nibabel, and in LPS after conversion
    p0 = nib.load(str(shared(TS, "example_mr_sm.nii.gz"))).affine[:3, 3]
    np.testing.assert_allclose(vol.in_space("LPS").affine[:3, 3], p0 * [-1, -1, 1])


def test_load_dispatches_to_nifti():
    p = shared(TS, "example_seg.nii.gz")
    vol = load(p, labels=shared(*NAMES))
    assert vol.meta["format"] == "NIfTI-1" and vol.labels[5].name == "liver"
    lps = load(p, space="LPS")
    assert lps.space == "LPS"
    np.testing.assert_allclose(lps.affine[:2], -nib.load(str(p)).affine[:2])
    assert load(shared(TS, "aorta", "aorta.nii.gz")).labels[1].name == "aorta"


# -- written in tmp_path --------------------------------------------------------------------
def _save(path, data, affine=None, **header):
    img = nib.Nifti1Image(data, np.diag([2.0, 2.0, 3.0, 1.0]) if affine is None else affine)
    for k, v in header.items():
        img.header[k] = v
    img.header.set_sform(img.affine, code=1)
    nib.save(img, str(path))
    return path


def test_4d_needs_a_volume_index(tmp_path):
    data = np.arange(4 * 5 * 6 * 3, dtype=np.int16).reshape(4, 5, 6, 3)
    p = _save(tmp_path / "dwi.nii.gz", data)
    with pytest.raises(AnatomeshError, match=r"4D, shape \(4, 5, 6, 3\).*volume_index.*--volume") as err:
        read_nifti(p)
    assert str(p) in str(err.value)
    vol = read_nifti(p, volume_index=2, label_map=False)
    np.testing.assert_array_equal(vol.data, data[..., 2])
    assert vol.meta["volume_index"] == 2
    with pytest.raises(AnatomeshError, match=r"volume index 3 is out of range.*0 to 2"):
        read_nifti(p, volume_index=3)
    assert load(p, volume_index=1, label_map=False).data[0, 0, 0] == data[0, 0, 0, 1]
    # a 4th axis of length 1 is just a 3D volume
    one = _save(tmp_path / "one.nii.gz", data[..., :1])
    assert read_nifti(one, label_map=False).shape == (4, 5, 6)


def test_scaled_4d_volume(tmp_path):
    data = np.arange(2 * 3 * 4 * 2, dtype=np.int16).reshape(2, 3, 4, 2)
    img = nib.Nifti1Image(data, np.eye(4))
    img.header.set_slope_inter(0.5, -10)
    nib.save(img, str(tmp_path / "s.nii"))
    vol = read_nifti(tmp_path / "s.nii", volume_index=1)
    assert vol.data.dtype == np.float32
    np.testing.assert_allclose(vol.data, data[..., 1] * 0.5 - 10)


def test_5d_rejected(tmp_path):
    p = _save(tmp_path / "field.nii.gz", np.zeros((3, 4, 5, 1, 3), np.float32))
    with pytest.raises(AnatomeshError, match=r"5D, shape \(3, 4, 5, 1, 3\)"):
        read_nifti(p)


def test_scaling_applied_and_integer_kept(tmp_path):
    raw = np.arange(-20, 40, dtype=np.int16).reshape(3, 4, 5)
    img = nib.Nifti1Image(raw, np.eye(4))
    img.header.set_slope_inter(2.0, -1024.0)
    nib.save(img, str(tmp_path / "ct.nii.gz"))
    vol = read_nifti(tmp_path / "ct.nii.gz")
    assert vol.data.dtype == np.float32 and vol.labels is None
    np.testing.assert_allclose(vol.data, raw * 2.0 - 1024.0)
    assert vol.meta["scl_slope"] == 2.0 and vol.meta["scl_inter"] == -1024.0
    unscaled = read_nifti(_save(tmp_path / "int.nii.gz", raw))
    assert unscaled.data.dtype == np.int16 and "scl_slope" not in unscaled.meta
    f64 = read_nifti(_save(tmp_path / "f64.nii.gz", raw.astype(np.float64) + 0.25))
    assert f64.data.dtype == np.float32


def test_nifti2_and_2d(tmp_path):
    data = np.arange(-6, 6, dtype=np.int16).reshape(3, 4)
    nib.save(nib.Nifti2Image(data, np.diag([0.5, 0.5, 1.0, 1.0])), str(tmp_path / "slice.nii"))
    vol = read_nifti(tmp_path / "slice.nii")
    assert vol.meta["format"] == "NIfTI-2" and vol.shape == (3, 4, 1)
    np.testing.assert_array_equal(vol.data[:, :, 0], data)
    np.testing.assert_allclose(vol.spacing, (0.5, 0.5, 1.0))


def test_big_endian_becomes_native(tmp_path):
    data = (np.arange(60, dtype=np.int16) - 30).reshape(3, 4, 5)
    hdr = nib.Nifti1Header(endianness=">")
    hdr.set_data_dtype(np.int16)
    img = nib.Nifti1Image(data, np.eye(4), hdr)
    nib.save(img, str(tmp_path / "be.nii"))
    assert nib.load(str(tmp_path / "be.nii")).header.get_data_dtype().byteorder == ">"
    vol = read_nifti(tmp_path / "be.nii")
    assert vol.data.dtype == np.dtype(np.int16) and vol.data.dtype.isnative
    np.testing.assert_array_equal(vol.data, data)


def test_float_label_map_becomes_integer(tmp_path):
    seg = np.zeros((5, 5, 5), np.float32)
    seg[1:3, 1:3, 1:3] = 300
    seg[3, 3, 3] = 7
    vol = read_nifti(_save(tmp_path / "seg.nii.gz", seg))
    assert vol.is_label_map and vol.data.dtype == np.uint16 and sorted(vol.labels) == [7, 300]
    np.testing.assert_array_equal(vol.data, seg.astype(np.uint16))


def test_intent_label_lifts_the_512_limit(tmp_path):
    data = np.arange(1000, dtype=np.int32).reshape(10, 10, 10)
    plain = _save(tmp_path / "plain.nii.gz", data)
    assert read_nifti(plain).labels is None
    img = nib.Nifti1Image(data, np.eye(4))
    img.header.set_intent("label")
    nib.save(img, str(tmp_path / "lab.nii.gz"))
    vol = read_nifti(tmp_path / "lab.nii.gz")
    assert vol.is_label_map and len(vol.labels) == 999 and vol.data.dtype == np.uint16


def test_nan_voxels(tmp_path):
    data = np.linspace(-5, 5, 60, dtype=np.float32).reshape(3, 4, 5)
    data[0, 0, :3] = np.nan
    data[2, 3, 4] = np.inf
    vol = read_nifti(_save(tmp_path / "nan.nii.gz", data))
    assert len(vol.warnings) == 1 and "4 voxels were NaN or infinite" in vol.warnings[0]
    assert np.isfinite(vol.data).all()
    assert vol.data[0, 0, 0] == vol.data[2, 3, 4] == np.nanmin(data[np.isfinite(data)])
    with pytest.raises(AnatomeshError, match="4 voxels are NaN or infinite"):
        read_nifti(tmp_path / "nan.nii.gz", label_map=True)
    allnan = _save(tmp_path / "allnan.nii.gz", np.full((2, 2, 2), np.nan, np.float32))
    with pytest.raises(AnatomeshError, match="every voxel is NaN"):
        read_nifti(allnan)


def test_units_converted_to_mm(tmp_path):
    data = np.zeros((3, 3, 3), np.int16) - 1
    aff = np.diag([500.0, 500.0, 1000.0, 1.0])
    aff[:3, 3] = [1000, 2000, 3000]
    img = nib.Nifti1Image(data, aff)
    img.header.set_xyzt_units("micron")
    nib.save(img, str(tmp_path / "um.nii.gz"))
    vol = read_nifti(tmp_path / "um.nii.gz")
    np.testing.assert_allclose(vol.spacing, (0.5, 0.5, 1.0))
    np.testing.assert_allclose(vol.affine[:3, 3], (1.0, 2.0, 3.0))
    assert vol.meta["spatial_units"] == "micron" and "converted to mm" in vol.warnings[0]
    img.header.set_xyzt_units("meter")
    img.set_sform(np.diag([0.001, 0.001, 0.002, 1.0]))
    nib.save(img, str(tmp_path / "m.nii.gz"))
    np.testing.assert_allclose(read_nifti(tmp_path / "m.nii.gz").spacing, (1.0, 1.0, 2.0))


def test_no_sform_no_qform_warns(tmp_path):
    img = nib.Nifti1Image(np.zeros((3, 3, 3), np.int16) - 1, None)  # no affine: both codes 0
    assert int(img.header["sform_code"]) == int(img.header["qform_code"]) == 0
    nib.save(img, str(tmp_path / "bare.nii"))
    vol = read_nifti(tmp_path / "bare.nii")
    assert any("neither sform nor qform" in w for w in vol.warnings)


def test_empty_file(tmp_path):
    p = tmp_path / "empty.nii.gz"
    p.write_bytes(b"")
    with pytest.raises(AnatomeshError, match="not a readable NIfTI file.*[Ee]mpty") as err:
        read_nifti(p)
    assert str(p) in str(err.value)


def test_truncated_gzip(tmp_path):
    src = shared(TS, "example_seg.nii.gz").read_bytes()
    p = tmp_path / "cut.nii.gz"
    p.write_bytes(src[: len(src) // 2])
    with pytest.raises(AnatomeshError, match="could not read the voxel data.*truncated or corrupt"):
        read_nifti(p)
    head = tmp_path / "head.nii.gz"
    head.write_bytes(src[:60])
    with pytest.raises(AnatomeshError, match="not a readable NIfTI"):
        read_nifti(head)


def test_not_gzip_but_named_so(tmp_path):
    p = tmp_path / "text.nii.gz"
    p.write_bytes(gzip.compress(b"hello, I am not an image" * 20))
    with pytest.raises(AnatomeshError, match="NIfTI"):
        read_nifti(p)


def test_memory_checked_before_reading(tmp_path, monkeypatch):
    """The size check uses the header only: a truncated file fails on memory, not on its data."""
    src = shared(TS, "example_seg_dicom.nii.gz").read_bytes()
    p = tmp_path / "big.nii.gz"
    p.write_bytes(src[: len(src) // 3])
    monkeypatch.setattr(volume_mod, "available_memory_bytes", lambda: 1e6)
    with pytest.raises(AnatomeshError, match=r"shape \(512, 512, 20\).*needs 5 MiB.*only 1 MiB"):
        read_nifti(p)
    monkeypatch.setattr(volume_mod, "available_memory_bytes", lambda: 1e9)
    with pytest.raises(AnatomeshError, match="truncated"):
        read_nifti(p)


def test_sidecar_colour_table(tmp_path):
    p = tmp_path / "seg.nii.gz"
    shutil.copy(shared(TS, "example_seg.nii.gz"), p)
    (tmp_path / "seg.ctbl").write_text("5 Leber 10 20 30 255\n1 Milz 200 0 0 255\n")
    vol = read_nifti(p)
    assert vol.labels[5].name == "Leber" and vol.labels[5].color == (10 / 255, 20 / 255, 30 / 255)
    assert vol.labels[2].name == "label_2"
    assert any("39 label value(s) not in the label table" in w for w in vol.warnings)
