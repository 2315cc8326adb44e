"""Every real segmentation in shared/data, read as a user would, checked against the source with
other tools: DICOM SEG voxels per segment = the frames' pixels counted with pydicom; RTSTRUCT voxels
on every contour plane = an even-odd rasterisation with matplotlib on the same grid; mask-folder
voxels = nonzero voxels counted with nibabel (and TotalSegmentator's own statistics.json). Each SEG
and RTSTRUCT is read in place (with its images where they exist) and alone (copied into tmp_path).
Reading any real DICOM input prints nothing and emits no Python warning."""
from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import nibabel as nib
import numpy as np
import pydicom
import pytest

from anatomesh.core import load
from anatomesh.core.io.nifti import read_nifti
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.segmentation import as_layers
from conftest import SHARED_DATA, shared
from helpers.contour_truth import compare_plane, planes_on_grid, roi_contours
from helpers.seg_corpus import segment_voxels

SEG_CLASSES = ("1.2.840.10008.5.1.4.1.1.66.4", "1.2.840.10008.5.1.4.1.1.66.7")
RTSTRUCT_CLASS = "1.2.840.10008.5.1.4.1.1.481.3"
FAST = ("totalsegmentator", "fast_folder")


def _dicom_objects(*sop_classes):
    """Paths (relative to shared/data) of every DICOM file of these SOP classes under dicom_seg/ and rtstruct/."""
    found = []
    for top in ("dicom_seg", "rtstruct"):
        for p in sorted(shared(top).rglob("*")):
            if p.is_file() and p.read_bytes()[128:132] == b"DICM":
                if str(pydicom.dcmread(p, stop_before_pixels=True).SOPClassUID) in sop_classes:
                    found.append(str(p.relative_to(SHARED_DATA)))
    return found


SEGS = _dicom_objects(*SEG_CLASSES)
RTSTRUCTS = _dicom_objects(RTSTRUCT_CLASS)
#: image series folders, and single slices given alone
SERIES = ["slicer_ctheadaxial", "itkelastix_chest_ct", "totalsegmentator/example_ct_dicom",
          "dicom_seg/dcmqi_ct3slice/ct", "dicom_seg/highdicom_ct2/ct", "rtstruct/sts_001/ct", "rtstruct/sts_001",
          "rtstruct/rtutils_phantom", "rtstruct/dicompyler_breast", "dicom_seg/synthetic_tiny/24x38x3/image"]
SLICES = ["slicer_ctheadaxial/CTHead50.dcm", "rtstruct/rtutils_phantom/ct_1.dcm", "rtstruct/dicompyler_breast/ct.0.dcm",
          "dicom_seg/highdicom_ct2/single_frame/ct_image.dcm", "rtstruct/sts_001/ct/000030.dcm",
          "totalsegmentator/example_ct_dicom/"
          + sorted(p.name for p in shared("totalsegmentator", "example_ct_dicom").iterdir())[0]]


def test_the_corpus_is_all_there():
    # dicom_seg/README.md: 12 SEG objects; rtstruct/README.md and the third wave: 4 RT structure sets
    assert len(SEGS) == 12 and len(RTSTRUCTS) == 4


def _voxels(vol) -> dict:
    """{structure name: voxel count} over all layers."""
    return {info.name: int(np.count_nonzero(layer.data == v))
            for layer in as_layers(vol) for v, info in layer.labels.items()}


def _alone(rel: str, tmp_path: Path) -> Path:
    """The file copied into an empty folder: read without its images."""
    folder = tmp_path / "alone"
    folder.mkdir()
    return Path(shutil.copy(shared(*rel.split("/")), folder))


# -- no library warnings, nothing on stderr -----------------------------------------------------------
@pytest.mark.parametrize("rel", SEGS + RTSTRUCTS + SERIES + SLICES)
def test_reading_real_dicom_prints_no_library_warning(rel, capfd):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            vol = load(shared(*rel.split("/")))
        except AnatomeshError as err:  # a lone slice or a series with a gap: a clear refusal
            assert "\n" not in str(err)
            vol = None
    assert [str(w.message) for w in caught] == []
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    if rel == "rtstruct/sts_001/RS.dcm":  # pydicom's complaint about a too long SH value, as our note
        assert any(w.startswith("pydicom says about RS.dcm: The value length (18) exceeds") for w in vol.warnings)


# -- DICOM SEG: voxels per segment = the frames' pixels ----------------------------------------------
@pytest.mark.parametrize("rel", SEGS)
def test_seg_voxels_per_segment_are_its_frame_pixels(rel, tmp_path):
    expected = {k: v for k, v in segment_voxels(pydicom.dcmread(shared(*rel.split("/")))).items() if v}
    in_place = load(shared(*rel.split("/")))
    alone = load(_alone(rel, tmp_path))
    assert _voxels(in_place) == expected
    assert _voxels(alone) == expected
    assert "own frame positions" in alone.meta["grid"]
    np.testing.assert_allclose(alone.spacing[:2], in_place.spacing[:2], rtol=1e-6)
    if "referenced image series" in in_place.meta["grid"]:  # same voxels in mm both ways
        for name in expected:
            a = [m for m in as_layers(alone) for v, i in m.labels.items() if i.name == name][0]
            b = [m for m in as_layers(in_place) for v, i in m.labels.items() if i.name == name][0]
            va = next(v for v, i in a.labels.items() if i.name == name)
            vb = next(v for v, i in b.labels.items() if i.name == name)
            mm_a = (a.affine[:3, :3] @ np.argwhere(a.data == va).T).T + a.affine[:3, 3]
            mm_b = (b.affine[:3, :3] @ np.argwhere(b.data == vb).T).T + b.affine[:3, 3]
            np.testing.assert_allclose(np.sort(mm_a, axis=0), np.sort(mm_b, axis=0), atol=1e-3)


# -- RTSTRUCT: voxels on every contour plane = even-odd of its contours ---------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("rel", RTSTRUCTS)
def test_rtstruct_voxels_on_contour_planes_are_even_odd_of_the_contours(rel, tmp_path):
    contours = roi_contours(pydicom.dcmread(shared(*rel.split("/"))))
    in_place, alone = load(shared(*rel.split("/"))), load(_alone(rel, tmp_path))
    checked = [in_place]
    if alone.shape == in_place.shape and np.allclose(alone.affine, in_place.affine):
        assert _voxels(alone) == _voxels(in_place)  # no image beside it: the same grid both ways
    else:
        checked.append(alone)
    for vol in checked:
        masks = {info.name: layer.data == v for layer in as_layers(vol) for v, info in layer.labels.items()}
        assert sorted(masks) == sorted(contours)
        for name, cs in contours.items():
            planes = planes_on_grid(cs, vol.affine)  # every contour lies on a grid slice
            for k, polys in planes.items():
                ours, truth, off_edge = compare_plane(masks[name][:, :, k], polys)
                assert off_edge == 0, (rel, name, k)  # differences only where a pixel centre is on an edge
                assert abs(ours - truth) <= 0.01 * max(truth, 100), (rel, name, k, ours, truth)


def test_rtutils_phantom_contours_beyond_its_two_images():
    vol = load(shared("rtstruct", "rtutils_phantom", "dummy_rt.dcm"))
    ds = pydicom.dcmread(shared("rtstruct", "rtutils_phantom", "dummy_rt.dcm"))
    ct = [pydicom.dcmread(shared("rtstruct", "rtutils_phantom", f"ct_{n}.dcm"), stop_before_pixels=True)
          for n in (1, 2)]
    referenced = {str(i.ReferencedSOPInstanceUID) for fr in ds.ReferencedFrameOfReferenceSequence
                  for st in fr.RTReferencedStudySequence for se in st.RTReferencedSeriesSequence
                  for i in se.ContourImageSequence}
    missing = len(referenced - {str(d.SOPInstanceUID) for d in ct})
    assert (len(referenced), missing) == (5, 3)
    said = f"{missing} of the {len(referenced)} images the RTSTRUCT references are not among"
    assert said in " ".join(vol.meta["notes"])
    np.testing.assert_allclose(vol.spacing[:2], [float(v) for v in ct[0].PixelSpacing][::-1], rtol=1e-6)
    z = sorted({round(float(c.ContourData[2]), 3) for item in ds.ROIContourSequence for c in item.ContourSequence})
    assert z == [60.0, 65.0, 70.0]  # 70 lies beyond the two CT slices (60, 65)
    top = vol.affine @ np.r_[0, 0, vol.shape[2] - 1, 1]
    assert top[2] == pytest.approx(70.0) and vol.affine[2, 3] == pytest.approx(60.0)
    assert sorted(_voxels(vol)) == ["ROI-1", "ROI-2", "ROI-3", "ROI-4"]


def test_eclipse_structure_set_without_ct_on_its_contour_planes():
    path = shared("rtstruct", "eclipse_prostate_no_ct", "RS_eclipse_prostate.dcm")
    ds = pydicom.dcmread(path)
    contours = roi_contours(ds)
    assert len(ds.StructureSetROISequence) == 16 and len(contours) == 6
    vol = load(path)
    assert "the contour planes at 1 mm pixels" in vol.meta["grid"]
    assert sorted(_voxels(vol)) == sorted(contours)
    body_planes = {round(float(c[0, 2]), 3) for c in contours["BODY"]}
    assert len(body_planes) == 92
    roi = {r["name"]: r for r in vol.meta["rois"]}
    assert roi["BODY"]["planes"] == 92
    empty = [str(s.ROIName) for s in ds.StructureSetROISequence if str(s.ROIName) not in contours]
    for name in empty:
        assert any(repr(name) in w and "skipped" in w for w in vol.warnings), name
    t = np.array(sorted(body_planes))
    assert vol.spacing[2] == pytest.approx(np.diff(t).min() / 2)  # 2 grid slices per plane step


# -- mask folders: voxels per structure = nonzero voxels (nibabel) ----------------------------------------
def _nonzero(path: Path) -> int:
    return int(np.count_nonzero(np.asanyarray(nib.load(str(path)).dataobj)))


def test_totalsegmentator_fast_folder_equals_its_label_map():
    folder = shared(*FAST, "example_seg_fast")
    files = sorted(folder.glob("*.nii.gz"))
    counts = {p.name[: -len(".nii.gz")]: _nonzero(p) for p in files}
    stats = json.loads((folder / "statistics.json").read_text())
    assert set(stats) == set(counts)
    masks = load(folder)
    label_map = read_nifti(shared(*FAST, "example_seg_fast.nii.gz"),
                           labels=shared("totalsegmentator", "label_names_total_and_total_mr.json"))
    present = {n: c for n, c in counts.items() if c}
    assert _voxels(masks) == _voxels(label_map) == present
    voxel_mm3 = label_map.voxel_volume_mm3()
    assert {n: c * voxel_mm3 for n, c in present.items()} == pytest.approx(
        {n: stats[n]["volume"] for n in present}, rel=1e-6)
    assert all(stats[n]["volume"] == 0 for n in counts if not counts[n])
    empty_warned = [w for w in masks.warnings if "is empty (no voxel set): skipped" in w]
    assert len(empty_warned) == len(counts) - len(present)
    assert masks.shape == label_map.shape
    ras = masks.in_space("RAS") if masks.space != "RAS" else masks
    np.testing.assert_allclose(ras.affine, label_map.affine, atol=1e-6)


def test_tissue_type_masks():
    folder = shared(*FAST, "example_seg_tissue_types")
    files = sorted(folder.glob("*.nii.gz"))
    seg = load(folder)
    assert _voxels(seg) == {p.name[: -len(".nii.gz")]: _nonzero(p) for p in files}
    arrays = {p.name[: -len(".nii.gz")]: np.asanyarray(nib.load(str(p)).dataobj) > 0 for p in files}
    names = sorted(arrays)
    pairs = {(o["a"], o["b"]): o["voxels"] for o in getattr(seg, "overlaps", [])}  # a Volume: none
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            shared_voxels = int((arrays[a] & arrays[b]).sum())
            assert pairs.get((a, b), pairs.get((b, a), 0)) == shared_voxels, (a, b)
    for layer in as_layers(seg):
        for v, info in layer.labels.items():
            ras = layer.in_space("RAS")
            np.testing.assert_array_equal(layer.data == v, arrays[info.name])
            np.testing.assert_allclose(ras.affine, nib.load(str(folder / f"{info.name}.nii.gz")).affine, atol=1e-6)


@pytest.mark.parametrize("folder", ["totalsegmentator/aorta", "totalsegmentator/pulmonary"])
def test_other_mask_folders_keep_every_voxel(folder):
    path = shared(*folder.split("/"))
    seg = load(path)
    image = Path(seg.meta["image"]).name
    expected = {p.name[: -len(".nii.gz")]: _nonzero(p) for p in path.glob("*.nii.gz") if p.name != image}
    assert _voxels(seg) == expected
    assert any(n.startswith(f"{image} was taken as the image") for n in seg.meta["notes"])
