"""DICOM SEG → label-map layers: voxel for voxel against dcmqi's NRRD ground truth, on the referenced
CT grid or the SEG's own frame positions; JPEG 2000, non-byte-aligned, fractional and Label Map
SEGs; names, colours (CIELab → sRGB), codes; overlapping segments as layers; DICOM folders; a
label map written as SEG with highdicom in the test and read back gives the same surfaces."""
from __future__ import annotations

import shutil

import numpy as np
import pydicom
import pytest

from anatomesh.core import load
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.io.dicom_objects import list_dicom
from anatomesh.core.io.nrrd import read_nrrd
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.segmentation import Segmentation, as_layers
from conftest import shared

CT3 = shared("dicom_seg", "dcmqi_ct3slice")
CT2 = shared("dicom_seg", "highdicom_ct2")
TINY = shared("dicom_seg", "synthetic_tiny")


def _truth(name):
    v = read_nrrd(CT3 / "labelmaps" / name, label_map=True)
    return v


def _masks(seg):
    """{name: bool array} of every structure, and the grid's affine (LPS)."""
    out = {}
    for layer in as_layers(seg):
        for v, info in layer.labels.items():
            out[info.name] = layer.data == v
    return out, as_layers(seg)[0].affine


def test_liver_seg_equals_dcmqi_label_map_voxel_for_voxel():
    seg = load(CT3 / "liver.dcm")
    truth = _truth("liver_seg.nrrd")
    masks, affine = _masks(seg)
    assert seg.space == "LPS" and "referenced image series" in seg.meta["grid"]
    np.testing.assert_allclose(affine, truth.affine, atol=1e-3)
    np.testing.assert_array_equal(masks["Liver"], truth.data == 1)
    assert int(masks["Liver"].sum()) == 107098
    assert seg.meta["segments"][0]["type"]["meaning"] == "Liver"
    assert seg.labels[1].color == pytest.approx((0.8667, 0.5098, 0.3961), abs=0.01)  # CIELab → sRGB


@pytest.mark.parametrize("name", ["liver_j2k.dcm", "liver_nonbyte_aligned.dcm"])
def test_variants_decode_and_land_on_the_same_voxels(name):
    seg = load(CT3 / "variants" / name)
    assert "not here" in " ".join(seg.meta["notes"])  # the CT is not in variants/: own geometry
    masks, affine = _masks(seg)
    truth = _truth("liver_seg.nrrd")
    np.testing.assert_allclose(affine, truth.affine, atol=1e-3)
    nx, ny, _ = masks["Liver"].shape
    np.testing.assert_array_equal(masks["Liver"], (truth.data == 1)[:nx, :ny])


def test_overlapping_segments_are_layers_equal_to_the_nrrds():
    seg = load(CT3 / "partial_overlaps.dcm")
    assert isinstance(seg, Segmentation) and len(seg.layers) == 3
    masks, _ = _masks(seg)
    names = ["GREEN", "ORANGE", "PURPLE", "LIGHT_BLUE", "DARK_BLUE"]
    assert [i.name for i in seg.labels.values()] == names
    labelmaps = {1: "partial_overlaps-1.nrrd", 4: "partial_overlaps-1.nrrd", 5: "partial_overlaps-1.nrrd",
                 2: "partial_overlaps-2.nrrd", 3: "partial_overlaps-3.nrrd"}
    for n, name in enumerate(names, 1):
        np.testing.assert_array_equal(masks[name], _truth(labelmaps[n]).data == n)
    pairs = {(o["a"], o["b"]): o["voxels"] for o in seg.overlaps}
    assert pairs == {("GREEN", "ORANGE"): 3017, ("GREEN", "PURPLE"): 95, ("ORANGE", "PURPLE"): 50}


def test_fractional_and_binary_agree_and_threshold_is_said():
    binary, _ = _masks(load(CT2 / "seg_image_ct_binary.dcm"))
    frac = load(CT2 / "seg_image_ct_binary_fractional.dcm")
    assert any("0.5 of the maximum fractional value" in n for n in frac.meta["notes"])
    np.testing.assert_array_equal(_masks(frac)[0]["first segment"], binary["first segment"])
    true_frac = load(CT2 / "seg_image_ct_true_fractional.dcm")
    assert int(_masks(true_frac)[0]["first segment"].sum()) == 638  # 0.5 (128) in, 0.25 (64) out


def test_uneven_ct_gap_and_overlap_seg_on_its_own_planes():
    seg = load(CT2 / "seg_image_ct_binary_overlap.dcm")
    assert "do not form a volume" in " ".join(seg.meta["notes"])
    masks, affine = _masks(seg)
    assert masks["first segment"].shape[2] == 165  # 202.5 mm gap at 1.25 mm steps, left empty
    assert int(masks["first segment"].sum()) == 64 and int(masks["second segment"].sum()) == 16
    assert np.all(masks["first segment"][masks["second segment"]])


def test_label_map_sop_class_and_bit_packing_across_bytes():
    lm = load(TINY / "24x38x3" / "sparse-labelmap-noppv.dcm")
    truth = read_nrrd(TINY / "24x38x3" / "sparse_labelmap_noppv_seg.nrrd", label_map=True)
    np.testing.assert_array_equal(_masks(lm)[0]["Liver"], truth.data == 1)
    assert int(_masks(load(TINY / "23x38x3" / "label.seg"))[0]["Liver"].sum()) == 322


def test_dicom_folder_lists_and_picks():
    entries = list_dicom(CT3)
    kinds = [e["kind"] for e in entries]
    assert kinds[0] == "image" and kinds.count("SEG") == 4
    with pytest.raises(AnatomeshError, match="choose one with --series"):
        load(CT3)
    liver = next(e["number"] for e in entries if e["path"].endswith("liver.dcm"))
    assert _masks(load(CT3, series=str(liver)))[0]["Liver"].sum() == 107098
    ct = load(CT3, series="1")
    assert ct.meta["modality"] == "CT" and ct.shape == (512, 512, 3)


def test_one_segmentation_is_meshed_by_default_and_studies_must_not_mix(tmp_path):
    folder = tmp_path / "case"
    shutil.copytree(CT3 / "ct", folder / "ct")
    shutil.copy(CT3 / "liver.dcm", folder)
    seg = load(folder)
    assert "meshing the SEG object liver.dcm" in seg.meta["notes"][0]
    shutil.copytree(CT2 / "ct", folder / "other")
    with pytest.raises(AnatomeshError, match="unrelated studies"):
        load(folder)


def test_round_trip_label_map_to_highdicom_seg_and_back(tmp_path):
    import highdicom as hd
    from pydicom.sr.codedict import codes

    ct_files = sorted((CT3 / "ct").iterdir())
    source = [pydicom.dcmread(f) for f in ct_files]
    source.sort(key=lambda d: float(d.ImagePositionPatient[2]))
    for d in source:
        d.SpecificCharacterSet = "ISO_IR 100"  # the CT leaves it empty; highdicom wants one
        d.PatientName = f"{d.PatientName}^"  # a one-component name, said so (highdicom warns otherwise)
    lab = np.zeros((3, 512, 512), np.uint8)  # (frames, rows, cols)
    lab[:, 200:300, 150:260] = 1
    lab[1, 240:280, 300:360] = 2
    descs = [hd.seg.SegmentDescription(
        segment_number=n, segment_label=name, segmented_property_category=codes.SCT.Tissue,
        segmented_property_type=codes.SCT.Organ, algorithm_type=hd.seg.SegmentAlgorithmTypeValues.MANUAL)
        for n, name in ((1, "liver"), (2, "kidney"))]
    seg = hd.seg.Segmentation(
        source_images=source, pixel_array=lab, segmentation_type=hd.seg.SegmentationTypeValues.BINARY,
        segment_descriptions=descs, series_instance_uid=hd.UID(), series_number=99,
        sop_instance_uid=hd.UID(), instance_number=1, manufacturer="test", manufacturer_model_name="test",
        software_versions="1", device_serial_number="1")
    folder = tmp_path / "rt"
    shutil.copytree(CT3 / "ct", folder / "ct")
    seg.save_as(folder / "seg.dcm")
    back = load(folder)
    ct_affine = load(CT3, series="1").affine
    np.testing.assert_allclose(as_layers(back)[0].affine, ct_affine, atol=1e-4)
    expect = np.transpose(lab, (2, 1, 0))  # volume layout (column, row, slice)
    got = as_layers(back)[0]
    np.testing.assert_array_equal(got.data, expect)
    a = label_surfaces(got).shells()
    b = label_surfaces(np.ascontiguousarray(expect), affine=ct_affine, space="LPS").shells()
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.faces, y.faces)
        np.testing.assert_allclose(x.vertices, y.vertices, atol=1e-4)
    assert [m.name for m in a] == ["liver", "kidney"]
