"""Raw DICOM pixels read in place (core/io/dicom_pixels.py): the same values as pydicom's
decoders, on implicit- and explicit-VR series, with unused high bits, and files where the pixel
data is not the last element (those go through pydicom)."""
from __future__ import annotations

import shutil

import numpy as np
import pydicom

from anatomesh.core.io import dicom_pixels
from anatomesh.core.io.dicom import read_dicom

from helpers.dicom_corpus import edit, head_slices


def _pydicom_volume(files):
    """(cols, rows, slices) rescaled values read with pydicom, slices by position along z."""
    dss = sorted((pydicom.dcmread(f) for f in files), key=lambda d: float(d.ImagePositionPatient[2]))
    return np.stack([d.pixel_array.T * float(d.get("RescaleSlope", 1)) + float(d.get("RescaleIntercept", 0))
                     for d in dss], axis=2)


def test_chest_ct_12_bits_stored_matches_pydicom(shared_data, tmp_path, monkeypatch):
    src = sorted(shared_data("itkelastix_chest_ct").iterdir())[60:64]
    files = [shutil.copy(f, tmp_path / f.name) for f in src]
    ds = pydicom.dcmread(files[0], stop_before_pixels=True)
    assert (ds.BitsAllocated, ds.BitsStored) == (16, 12) and not ds.file_meta.TransferSyntaxUID.is_compressed
    hits = _count_raw_reads(monkeypatch)
    vol = read_dicom(tmp_path)
    assert hits == [True] * 4  # every slice read in place
    np.testing.assert_array_equal(vol.data, _pydicom_volume(files))


def test_explicit_vr_and_pixel_data_not_last_fall_back_to_pydicom(shared_data, tmp_path, monkeypatch):
    files = head_slices(shared_data, tmp_path, n=4)
    expect = _pydicom_volume(files)

    def trailing_padding(d, i):  # (FFFC,FFFC) after the pixel data: no longer the last element
        if i == 1:
            d.add_new(0xFFFCFFFC, "OB", b"\0\0\0\0")

    edit(files, trailing_padding)
    hits = _count_raw_reads(monkeypatch)
    vol = read_dicom(tmp_path)
    assert sorted(hits) == [False, True, True, True]  # the padded file went through pydicom
    np.testing.assert_array_equal(vol.data, expect)



def _count_raw_reads(monkeypatch):
    """Record whether each slice was read in place (True) or handed to pydicom (False)."""
    hits = []
    read = dicom_pixels._read_native

    def recording(*args):
        hits.append(read(*args))
        return hits[-1]

    monkeypatch.setattr(dicom_pixels, "_read_native", recording)
    return hits
