"""What the libraries say reaches the user in our words: their warnings as one-line notes naming the
file (nothing raw on stderr), their exception texts as complete clauses of our one-line errors
(never cut mid-sentence)."""
from __future__ import annotations

import shutil
import struct
import warnings

import nibabel as nib
import numpy as np
import pytest

from anatomesh.core import load
from anatomesh.core.io.library_messages import reason
from anatomesh.core.io.nifti import read_nifti
from anatomesh.core.model.errors import AnatomeshError
from conftest import shared

SPARSE = shared("dicom_seg", "synthetic_tiny", "24x38x3", "sparse-labelmap-noppv.dcm")


def _odd_extension_nifti(path):
    """A valid NIfTI whose header extension is 24 bytes long (not a multiple of 16): nibabel reads
    it and warns."""
    nib.save(nib.Nifti1Image(np.arange(27, dtype=np.int16).reshape(3, 3, 3) - 5, np.eye(4)), str(path))
    raw = path.read_bytes()
    vox = int(struct.unpack("<f", raw[108:112])[0])
    header = bytearray(raw[:348])
    header[108:112] = struct.pack("<f", 384.0)
    ext = struct.pack("<ii", 24, 6) + b"odd size comment"
    path.write_bytes(bytes(header) + bytes([1, 0, 0, 0]) + ext + bytes(8) + raw[vox:])
    return path


def test_nibabel_warning_becomes_a_note_naming_the_file(tmp_path, capfd):
    path = _odd_extension_nifti(tmp_path / "odd.nii")
    with pytest.warns(UserWarning, match="Extension size is not a multiple of 16"):
        nib.load(str(path)).get_fdata()  # what nibabel does on its own
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vol = read_nifti(path)
    assert caught == [] and capfd.readouterr().err == ""
    assert vol.warnings == ["nibabel says about odd.nii: Extension size is not a multiple of 16 bytes; "
                            "Assuming size is correct and hoping for the best"]
    np.testing.assert_array_equal(vol.data.ravel()[:3], [-5, -4, -3])


def test_pydicom_warnings_of_several_files_are_one_note(tmp_path):
    """sts_001's RS.dcm has an 18-character SH value, which pydicom warns about; read as part of
    its folder, the note names it once."""
    folder = tmp_path / "sts"
    shutil.copytree(shared("rtstruct", "sts_001", "ct"), folder / "ct")
    shutil.copy(shared("rtstruct", "sts_001", "RS.dcm"), folder / "RS.dcm")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vol = load(folder / "RS.dcm")
    assert caught == []
    said = [w for w in vol.warnings if "exceeds the maximum length of 16 allowed for VR SH" in w]
    assert len(said) == 1 and said[0].startswith("pydicom says about RS.dcm: The value length (18)")


def test_a_long_library_error_enters_our_message_as_a_complete_clause(tmp_path):
    """A label-map SEG cut short: pydicom's long explanation ('... - the dataset may be corrupted,
    have an invalid group 0028 element value, or the transfer syntax may be incorrect') is kept to
    its first complete clause, not cut after 160 characters."""
    import highdicom as hd
    import pydicom

    cut = tmp_path / "cut.dcm"
    data = SPARSE.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.98)])
    with pytest.raises(Exception) as raw:  # the library's own error on this file
        hd.seg.Segmentation.from_dataset(pydicom.dcmread(cut), copy=False).get_stored_frames()
    library = str(raw.value)
    assert len(library) > 160  # what used to be cut mid-word
    with pytest.raises(AnatomeshError) as err:
        load(cut)
    message = str(err.value)
    clause = reason(raw.value)
    assert library.startswith(clause) and library[len(clause):][:3] in (" - ", ". ", "; ")
    assert f"({clause}): the file is truncated or damaged; copy it again" in message
    assert message.startswith(str(cut)) and "\n" not in message


def test_reason_keeps_short_texts_and_names_missing_attributes():
    assert reason(ValueError("buffer size must be a multiple of element size")) == \
        "buffer size must be a multiple of element size"
    assert reason(AttributeError("'Dataset' object has no attribute 'FrameContentSequence'")) == \
        "FrameContentSequence is missing"
    assert reason(KeyError()) == "KeyError"
    long = "first part that is long enough to stand - " + "x " * 80
    assert reason(RuntimeError(long)) == "first part that is long enough to stand"
