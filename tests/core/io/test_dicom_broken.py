"""Broken DICOM input, made in tmp_path from real head-CT slices: every case gives a message that
names the file or folder and the problem (``pytest -s`` prints the corpus of messages)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pydicom
import pytest
from pydicom import uid

from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.io import load
from anatomesh.core.io.dicom import read_dicom

from helpers.dicom_corpus import edit, head_slices, non_image_object


def _error(target, **kwargs) -> str:
    with pytest.raises(AnatomeshError) as err:
        read_dicom(target, **kwargs)
    message = str(err.value)
    print(f"\n  [{Path(str(target)).name}] {message}")
    assert "\n" not in message
    return message


def _truncated_pixels(shared, folder):
    files = head_slices(shared, folder)
    data = files[2].read_bytes()
    files[2].write_bytes(data[: len(data) // 2])
    return folder, ["CTHead42.dcm", "truncated", "pixel data"]


def _truncated_header(shared, folder):
    files = head_slices(shared, folder)
    files[2].write_bytes(files[2].read_bytes()[:300])  # file meta only
    return folder, ["CTHead42.dcm", "truncated", "CT Image Storage", "Rows/Columns"]


def _damaged_header(shared, folder):
    files = head_slices(shared, folder)
    rng = np.random.default_rng(1)
    files[2].write_bytes(b"\0" * 128 + b"DICM" + rng.bytes(3000))
    return folder, ["CTHead42.dcm", "damaged", "SOP class"]


def _empty_dcm(shared, folder):
    files = head_slices(shared, folder)
    files[2].write_bytes(b"")
    return folder, ["CTHead42.dcm", "empty file (0 bytes)"]


def _text_named_dcm(shared, folder):
    files = head_slices(shared, folder)
    files[2].write_text("this is not an image\n")
    return folder, ["CTHead42.dcm", "not a DICOM file"]


def _two_series(shared, folder):
    head_slices(shared, folder)
    second = head_slices(shared, folder / "b", first=60, n=4)
    series_uid = uid.generate_uid()
    edit(second, lambda ds, _: (setattr(ds, "SeriesInstanceUID", series_uid),
                                setattr(ds, "SeriesNumber", 7),
                                setattr(ds, "SeriesDescription", "bone kernel")))
    return folder, ["2 image series", "--series", "'bone kernel'", "4 slices of 64x64",
                    "6 slices of 64x64", "#123456"]


def _missing_slice(shared, folder):
    head_slices(shared, folder, skip=(43,))
    return folder, ["missing slice", "CTHead42.dcm", "CTHead44.dcm", "3 mm", "1.5 mm",
                    "about 1 slice"]


def _duplicate_copy(shared, folder):
    files = head_slices(shared, folder)
    shutil.copy(files[2], folder / "CTHead42 copy.dcm")
    return folder, ["duplicate", "CTHead42.dcm", "CTHead42 copy.dcm", "same SOPInstanceUID"]


def _duplicate_acquisition(shared, folder):
    files = head_slices(shared, folder)
    twin = Path(shutil.copy(files[2], folder / "phase2_42.dcm"))
    edit([twin], lambda ds, _: setattr(ds, "SOPInstanceUID", uid.generate_uid()))
    return folder, ["duplicate", "CTHead42.dcm", "phase2_42.dcm", "several acquisitions"]


def _mixed_orientations(shared, folder):
    files = head_slices(shared, folder)
    edit(files[:2], lambda ds, _: setattr(ds, "ImageOrientationPatient", [1, 0, 0, 0, 0, -1]))
    return folder, ["mixed orientations", "4 with [1, 0, 0, 0, 1, 0]",
                    "2 with [1, 0, 0, 0, 0, -1] (e.g. CTHead40.dcm)"]


def _mixed_sizes(shared, folder):
    files = head_slices(shared, folder)
    edit(files[4:5], lambda ds, _: setattr(ds, "Rows", 32))
    return folder, ["mixed image sizes", "1 with 64x32 (e.g. CTHead44.dcm)", "5 with 64x64"]


def _off_line(shared, folder):
    files = head_slices(shared, folder)
    edit(files[3:4], lambda ds, _: setattr(ds, "ImagePositionPatient", [5.0, 0.0, 1.5 * 42]))
    return folder, ["do not lie on one line", "CTHead43.dcm", "5 mm off"]


def _single_slice(shared, folder):
    head_slices(shared, folder, n=1)
    return folder, ["single slice", "at least 2", "CTHead40.dcm"]


def _colour(shared, folder):
    files = head_slices(shared, folder)
    edit(files, lambda ds, _: setattr(ds, "SamplesPerPixel", 3))
    return folder, ["colour", "CTHead40.dcm"]


def _empty_folder(shared, folder):
    folder.mkdir()
    return folder, ["folder is empty"]


def _no_images(shared, folder):
    folder.mkdir()
    (folder / "README.txt").write_text("scans are elsewhere\n")
    non_image_object(folder / "DICOMDIR", uid.MediaStorageDirectoryStorage)
    non_image_object(folder / "report", uid.BasicTextSRStorage, "SR")
    return folder, ["no DICOM image series found among 3 file(s)", "DICOMDIR",
                    "Basic Text SR Storage", "not DICOM"]


CASES = {f.__name__[1:]: f for f in (
    _truncated_pixels, _truncated_header, _damaged_header, _empty_dcm, _text_named_dcm,
    _two_series, _missing_slice, _duplicate_copy, _duplicate_acquisition, _mixed_orientations,
    _mixed_sizes, _off_line, _single_slice, _colour, _empty_folder, _no_images)}


@pytest.mark.parametrize("case", sorted(CASES))
def test_broken_series_is_named_and_explained(case, shared_data, tmp_path):
    folder = tmp_path / case
    target, words = CASES[case](shared_data, folder)
    message = _error(target)
    assert str(folder) in message  # the folder or a file in it is named
    for word in words:
        assert word in message, (word, message)


def test_missing_codec_names_transfer_syntax_and_package(shared_data, monkeypatch):
    folder = shared_data("totalsegmentator", "example_ct_dicom")
    decoder = pydicom.pixels.get_decoder(uid.JPEG2000Lossless)
    monkeypatch.setattr(decoder, "_available", {})  # as if no JPEG 2000 plug-in were installed
    with pytest.raises(RuntimeError):  # pydicom itself now cannot decode these files
        pydicom.pixels.pixel_array(next(folder.iterdir()))
    message = _error(folder)
    for word in ("JPEG 2000 Image Compression (Lossless Only)", "1.2.840.10008.1.2.4.90",
                 "pip install pylibjpeg pylibjpeg-openjpeg", str(folder)):
        assert word in message


def test_unknown_series_choice_lists_the_series(shared_data, tmp_path):
    folder, _ = _two_series(shared_data, tmp_path / "two")
    message = _error(folder, series="99")
    assert "no image series matches --series '99'" in message and "[2]" in message


def test_path_that_does_not_exist(tmp_path):
    missing = tmp_path / "no_such_scan"
    with pytest.raises(AnatomeshError) as err:
        load(missing)
    print(f"\n  [load] {err.value}")
    assert str(missing) in str(err.value) and "no such file or folder" in str(err.value)
    with pytest.raises(AnatomeshError) as err:
        read_dicom([tmp_path / "a.dcm"])
    assert "a.dcm" in str(err.value) and "no such file" in str(err.value)


def test_junk_files_are_skipped_with_a_warning(shared_data, tmp_path):
    ref = read_dicom(head_slices(shared_data, tmp_path / "ref"))
    folder = tmp_path / "junk"
    head_slices(shared_data, folder)
    (folder / "notes.txt").write_text("CT head, six slices\n")
    (folder / "thumb.jpg").write_bytes(b"\xff\xd8\xff\xe0" + bytes(200))
    (folder / "README").write_bytes(b"")
    (folder / ".DS_Store").write_bytes(b"\0\0\0\1Bud1")  # hidden: ignored silently
    non_image_object(folder / "DICOMDIR", uid.MediaStorageDirectoryStorage)
    non_image_object(folder / "rtstruct.dcm", uid.RTStructureSetStorage, "RTSTRUCT")
    non_image_object(folder / "pr.dcm", uid.GrayscaleSoftcopyPresentationStateStorage, "PR")
    vol = read_dicom(folder)
    assert np.array_equal(vol.data, ref.data)
    text = " | ".join(vol.warnings)
    print(f"\n  [junk] {text}")
    assert "2 file(s) that are not DICOM: notes.txt, thumb.jpg" in text
    assert "1 empty file(s): README" in text
    assert "DICOMDIR" in text and "RT Structure Set Storage" in text
    assert "Grayscale Softcopy Presentation State Storage" in text
    assert ".DS_Store" not in text and len(vol.warnings) == 5
