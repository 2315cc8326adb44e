"""One DICOM file given: only that file is read. A SEG or RTSTRUCT looks up its referenced series
in its folder when the grid needs it; a CT slice finds the other slices of its series. Damaged or
unrelated files beside it never stop the run (skipped, named in a note when they matter), and an
error always names the file the problem is in. Cases built in tmp_path from the real SEG, RTSTRUCT
and CT files of shared/data."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from pydicom import uid

from anatomesh.core import load
from anatomesh.core.io.nrrd import read_nrrd
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.segmentation import as_layers
from conftest import shared
from helpers.dicom_corpus import edit, head_slices, non_image_object

CT3 = shared("dicom_seg", "dcmqi_ct3slice")
STS = shared("rtstruct", "sts_001")


def _damaged(path: Path) -> Path:
    """A file with the DICOM marker and a header pydicom reads but that names nothing."""
    path.write_bytes(b"\0" * 128 + b"DICM" + bytes(range(256)) * 8)
    return path


def _error(target, **kwargs) -> str:
    with pytest.raises(AnatomeshError) as err:
        load(target, **kwargs)
    message = str(err.value)
    assert "\n" not in message
    return message


def _liver(vol) -> np.ndarray:
    (layer,) = as_layers(vol)
    return layer.data == 1


@pytest.fixture
def seg_folder(tmp_path):
    """The liver SEG with its CT, another SEG, a damaged file, an empty .dcm, a text file and a CT
    of another study, all in one folder."""
    folder = tmp_path / "export"
    shutil.copytree(CT3 / "ct", folder / "ct")
    for name in ("liver.dcm", "partial_overlaps.dcm"):
        shutil.copy(CT3 / name, folder)
    _damaged(folder / "broken.dcm")
    (folder / "empty.dcm").write_bytes(b"")
    (folder / "notes.txt").write_text("exported from PACS\n")
    shutil.copytree(shared("dicom_seg", "highdicom_ct2", "ct"), folder / "other_study")
    return folder


def test_a_seg_given_alone_is_read_beside_damaged_and_unrelated_files(seg_folder):
    truth = read_nrrd(CT3 / "labelmaps" / "liver_seg.nrrd", label_map=True)
    vol = load(seg_folder / "liver.dcm")
    assert "referenced image series" in vol.meta["grid"]
    np.testing.assert_allclose(vol.affine, truth.affine, atol=1e-3)
    np.testing.assert_array_equal(_liver(vol), truth.data == 1)
    assert vol.meta["notes"] == []  # its series was found whole: the damaged files do not matter
    native = load(seg_folder / "liver.dcm", grid="native")  # no look-up at all
    np.testing.assert_array_equal(_liver(native), truth.data == 1)
    # the folder itself is still read strictly: the damaged file is named
    assert "broken.dcm" in _error(seg_folder)


def test_a_seg_whose_ct_has_a_damaged_slice_uses_its_own_grid_and_says_why(seg_folder):
    ct2 = seg_folder / "ct" / "02.dcm"
    ct2.write_bytes(ct2.read_bytes()[:400])  # header cut before the image size
    truth = read_nrrd(CT3 / "labelmaps" / "liver_seg.nrrd", label_map=True)
    vol = load(seg_folder / "liver.dcm")
    notes = " | ".join(vol.meta["notes"])
    assert "1 of the 3 images the SEG references are not among the readable files" in notes
    assert "ct/02.dcm" in notes and "meshed on the SEG's own grid" in notes
    np.testing.assert_allclose(vol.affine, truth.affine, atol=1e-3)
    np.testing.assert_array_equal(_liver(vol), truth.data == 1)
    message = _error(seg_folder / "liver.dcm", grid="image")  # asked for explicitly: refused
    assert "liver.dcm" in message and "0.50 voxel" in message


def test_an_rtstruct_given_alone_beside_damaged_files(tmp_path):
    folder = tmp_path / "sts"
    shutil.copytree(STS / "ct", folder / "ct")
    shutil.copy(STS / "RS.dcm", folder)
    clean = load(folder / "RS.dcm")
    _damaged(folder / "ct" / "zz_broken.dcm")
    (folder / "RS copy.dcm").write_bytes((STS / "RS.dcm").read_bytes()[:5000])  # a cut copy
    vol = load(folder / "RS.dcm")
    np.testing.assert_array_equal(vol.affine, clean.affine)
    np.testing.assert_array_equal(vol.data, clean.data)
    assert "referenced CT's pixel lattice" in vol.meta["grid"]
    assert "RS copy.dcm" in _error(folder / "RS copy.dcm")  # the cut copy itself: named


def test_a_ct_slice_given_alone_skips_unrelated_damaged_files(shared_data, tmp_path):
    folder = tmp_path / "head"
    files = head_slices(shared_data, folder)
    clean = load(files[0])
    _damaged(folder / "broken.dcm")
    (folder / "cut_seg.dcm").write_bytes((CT3 / "liver.dcm").read_bytes()[:3000])
    non_image_object(folder / "report.dcm", uid.BasicTextSRStorage, "SR")
    vol = load(files[2])
    np.testing.assert_array_equal(vol.data, clean.data)
    np.testing.assert_array_equal(vol.affine, clean.affine)
    skipped = [w for w in vol.warnings if w.startswith("skipped 2 unreadable file(s) in head:")]
    assert len(skipped) == 1 and "broken.dcm" in skipped[0] and "cut_seg.dcm" in skipped[0]
    assert not any("report.dcm" in w for w in vol.warnings)  # unrelated, readable: not mentioned


def test_a_damaged_slice_of_the_same_series_is_an_error_naming_it(shared_data, tmp_path):
    folder = tmp_path / "head"
    files = head_slices(shared_data, folder)
    edit(files[3:4], lambda ds, _: (delattr(ds, "Rows"), delattr(ds, "Columns")))  # series UID kept
    message = _error(files[0])
    assert message.startswith(str(files[3])) and "no image size" in message
    assert "it belongs to the series of CTHead40.dcm" in message


def test_a_file_that_is_no_slice_is_named_not_its_siblings(shared_data, tmp_path):
    folder = tmp_path / "mixed"
    head_slices(shared_data, folder)
    sr = non_image_object(folder / "report.dcm", uid.BasicTextSRStorage, "SR")
    message = _error(sr)
    assert message.startswith(str(sr)) and "Basic Text SR Storage" in message and "not a slice" in message
    cut = folder / "liver_cut.dcm"
    cut.write_bytes((CT3 / "liver.dcm").read_bytes()[:60000])
    message = _error(cut)
    assert message.startswith(str(cut)) and "truncated or damaged" in message
    text = folder / "readme.dcm"
    text.write_text("not an image\n")
    assert _error(text).startswith(str(text))


def test_a_seg_given_alone_ignores_a_second_study_and_other_segs(tmp_path):
    """A folder with two SEGs and a CT of another study: given as a folder, a choice is asked
    for; each SEG given alone is simply read on its CT."""
    folder = tmp_path / "two"
    shutil.copytree(CT3 / "ct", folder / "ct")
    for name in ("liver.dcm", "partial_overlaps.dcm"):
        shutil.copy(CT3 / name, folder)
    shutil.copytree(shared("dicom_seg", "highdicom_ct2", "ct"), folder / "other_study")
    assert "unrelated studies" in _error(folder)
    overlaps = load(folder / "partial_overlaps.dcm")
    assert sorted(i.name for i in overlaps.labels.values()) == ["DARK_BLUE", "GREEN", "LIGHT_BLUE", "ORANGE",
                                                               "PURPLE"]
    assert "referenced image series" in overlaps.meta["grid"]
    assert int(_liver(load(folder / "liver.dcm")).sum()) == 107098
