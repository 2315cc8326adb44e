"""DICOM series reader on real series: exact geometry, values, series choice, layout."""
from __future__ import annotations

import math
from pathlib import Path

import nibabel as nib
import numpy as np
import pydicom
import pytest

from anatomesh.core.model.errors import AnatomeshError, Cancelled
from anatomesh.core.io import load
from anatomesh.core.io.dicom import SeriesInfo, list_series, read_dicom

from helpers.dicom_corpus import edit, head_slices


def _pixels_by_z(folder: Path):
    """{z: (file, stored pixel array)} read with pydicom directly, for cross-checks."""
    out = {}
    for f in sorted(folder.iterdir()):
        ds = pydicom.dcmread(f)
        out[float(ds.ImagePositionPatient[2])] = (f, ds.pixel_array, ds)
    return out


# -- head CT (GE, uncompressed, 64x64x93) ---------------------------------------------------------
def test_head_ct_geometry_values_and_meta(shared_data):
    folder = shared_data("slicer_ctheadaxial")
    calls = []
    vol = read_dicom(folder, progress=lambda f, t: calls.append((f, t)))
    assert vol.shape == (64, 64, 93)
    assert vol.space == "LPS"
    assert vol.data.dtype == np.int16 and vol.data.flags.c_contiguous
    np.testing.assert_allclose(vol.spacing, (3.2, 3.2, 1.5))
    np.testing.assert_allclose(vol.affine, np.diag([3.2, 3.2, 1.5, 1.0]), atol=1e-9)
    assert vol.orientation() == "LPS" and vol.warnings == []
    # data[i, j, k] == pixel array of the k-th slice (z ascending) at row j, column i
    ref = _pixels_by_z(folder)
    for k in (0, 46, 92):
        f, pix, ds = ref[1.5 * k]
        assert np.array_equal(vol.data[:, :, k], pix.T), f
    meta = vol.meta
    assert meta["format"] == "dicom" and meta["modality"] == "CT" and meta["units"] == "HU"
    assert meta["series_number"] == 123456 and meta["n_files"] == 93
    assert meta["slice_spacing"] == pytest.approx(1.5)
    assert meta["rescale"] == {"slope": 1.0, "intercept": 0.0}
    assert meta["transfer_syntax"] == "Explicit VR Little Endian"
    assert not any("patient" in key.lower() for key in meta)
    fractions = [f for f, _ in calls]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert sum("slice" in t for _, t in calls) == 93


def test_head_ct_through_load_a_file_and_a_list(shared_data):
    folder = shared_data("slicer_ctheadaxial")
    by_folder = load(folder)
    by_file = load(folder / "CTHead50.dcm")  # a single slice → the series in its folder
    files = sorted(folder.glob("*.dcm"), reverse=True)
    by_list = read_dicom(files)
    for vol in (by_file, by_list):
        assert np.array_equal(vol.data, by_folder.data)
        np.testing.assert_array_equal(vol.affine, by_folder.affine)
    ras = load(folder, space="RAS")
    assert ras.space == "RAS" and ras.orientation() == "LPS"  # same axes, other space
    np.testing.assert_allclose(ras.affine[:3, 0], (-3.2, 0, 0))


def test_list_series_head_ct(shared_data):
    (info,) = list_series(shared_data("slicer_ctheadaxial"))
    assert isinstance(info, SeriesInfo)
    assert (info.number, info.modality, info.n_slices) == (123456, "CT", 93)
    assert (info.rows, info.cols) == (64, 64)
    assert len(info.files) == 93 and info.uid.startswith("1.2.826.0.1.3680043")
    assert "93 slices of 64x64" in info.label()


def test_cancel_from_progress_stops_reading(shared_data):
    def progress(fraction, text):
        if "slice" in text:
            raise Cancelled()
    with pytest.raises(Cancelled):
        read_dicom(shared_data("slicer_ctheadaxial"), progress=progress)


# -- chest CT (Philips, files in reverse order, SpacingBetweenSlices = -2) ------------------------
def test_chest_ct_sorted_along_normal_in_hu(shared_data):
    folder = shared_data("itkelastix_chest_ct")
    first = pydicom.dcmread(folder / "00-slice000.dcm", stop_before_pixels=True)
    assert float(first.SpacingBetweenSlices) == -2.0  # the trap this test is about
    vol = read_dicom(folder)
    assert vol.shape == (512, 512, 141) and vol.data.dtype == np.int16
    np.testing.assert_allclose(vol.spacing, (0.9765625, 0.9765625, 2.0))
    assert vol.warnings == []
    # k runs along +normal = row x col = +z (LPS: superior)
    row, col = np.array(first.ImageOrientationPatient, float).reshape(2, 3)
    normal = np.cross(row, col)
    assert vol.affine[:3, 2] @ normal == pytest.approx(2.0)
    # the origin is the lowest slice, the last index lands on the highest one
    z = {}
    for f in folder.glob("*.dcm"):
        ds = pydicom.dcmread(f, stop_before_pixels=True)
        z[f.name] = np.array(ds.ImagePositionPatient, float)
    lowest = min(z.values(), key=lambda p: p @ normal)
    highest = max(z.values(), key=lambda p: p @ normal)
    np.testing.assert_allclose(vol.affine @ [0, 0, 0, 1], [*lowest, 1], atol=1e-6)
    np.testing.assert_allclose(vol.affine @ [0, 0, 140, 1], [*highest, 1], atol=1e-6)
    # file 00-slice000 is the top slice (k = 140); values are stored + intercept (-1024) = HU
    assert np.allclose(z["00-slice000.dcm"], highest)
    pix = pydicom.dcmread(folder / "00-slice000.dcm").pixel_array.astype(np.int32)
    assert np.array_equal(vol.data[:, :, 140], (pix - 1024).T)
    assert vol.meta["units"] == "HU" and vol.meta["rescale"]["intercept"] == -1024.0
    assert vol.meta["window_width"] == 400.0
    hu = vol.data
    assert hu.min() == -1024
    assert (hu < -900).mean() > 0.2      # air around the body and in the lungs
    assert ((hu > -100) & (hu < 100)).mean() > 0.1  # soft tissue


# -- TotalSegmentator DICOM (JPEG 2000) against its label map --------------------------------------
def _grid_map(affine_from: np.ndarray, affine_to: np.ndarray, shape_to):
    """For each axis of the 'from' grid: (axis in 'to', sign, offset) so both hit the same point."""
    m = np.linalg.solve(affine_to, affine_from)  # index_from → index_to
    perm, sign, offset = [], [], []
    for a in range(3):
        b = int(np.argmax(np.abs(m[:3, a])))
        assert abs(abs(m[b, a]) - 1) < 1e-6, "the grids differ by more than a permutation/flip"
        perm.append(b)
        sign.append(int(round(m[b, a])))
        offset.append(int(round(m[b, 3])))
        assert abs(m[b, 3] - offset[-1]) < 1e-6
    assert sorted(perm) == [0, 1, 2]
    return perm, sign, offset


def test_totalsegmentator_jpeg2000_matches_its_label_map(shared_data):
    vol = read_dicom(shared_data("totalsegmentator", "example_ct_dicom"))
    assert vol.meta["transfer_syntax_uid"] == "1.2.840.10008.1.2.4.90"
    assert vol.shape == (512, 512, 20) and vol.meta["units"] == "HU"
    seg = nib.load(shared_data("totalsegmentator", "example_seg_dicom.nii.gz"))
    labels = np.asarray(seg.dataobj)
    a_nifti = seg.affine.copy()
    a_nifti[:2] *= -1.0  # RAS → LPS
    perm, sign, offset = _grid_map(vol.affine, a_nifti, labels.shape)
    assert perm == [0, 1, 2] and sign == [1, -1, 1]  # NIfTI stores the rows the other way round
    # every voxel centre of the DICOM grid is the centre of its NIfTI twin
    i, j = np.meshgrid(np.arange(512), np.arange(512), indexing="ij")
    worst = 0.0
    for k in range(vol.shape[2]):
        idx_d = np.stack([i.ravel(), j.ravel(), np.full(i.size, k), np.ones(i.size)])
        idx_n = np.ones_like(idx_d)
        for a in range(3):
            idx_n[perm[a]] = sign[a] * idx_d[a] + offset[a]
        assert idx_n[:3].min() >= 0 and (idx_n[:3].max(axis=1) < labels.shape).all()
        worst = max(worst, np.abs(vol.affine @ idx_d - a_nifti @ idx_n).max())
    assert worst < 1e-3
    on_dicom = labels[:, ::-1, :]
    hu = vol.data.astype(np.float64)

    def mean_hu(ids, lab=on_dicom):
        wanted = np.zeros(256, bool)
        wanted[ids] = True
        return hu[wanted[lab]].mean()

    assert mean_hu([32, 33]) > 150          # vertebrae T11, T12
    assert mean_hu(list(range(97, 116))) > 150  # ribs
    assert mean_hu([69, 70]) > 300          # humeri
    assert 40 < mean_hu([5]) < 150          # liver
    assert 40 < mean_hu([1]) < 150          # spleen
    assert -20 < mean_hu([86, 87]) < 80     # autochthonous back muscles
    # the same map without the row flip puts the vertebrae on air and fat
    assert mean_hu([32, 33], labels) < 0


# -- geometry on edited copies of real slices ------------------------------------------------------
def _rotation(axis, degrees):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    x, y, z = axis
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) * c + s * k + (1 - c) * np.outer(axis, axis)


def test_oblique_orientation_is_exact(shared_data, tmp_path):
    plain = read_dicom(head_slices(shared_data, tmp_path / "plain"))
    files = head_slices(shared_data, tmp_path / "oblique")
    rot, shift = _rotation((1, 2, 3), 30.0), np.array([-10.0, 20.0, 5.0])

    def rotate(ds, _):
        iop = np.array(ds.ImageOrientationPatient, float).reshape(2, 3)
        ds.ImageOrientationPatient = [round(v, 8) for v in (iop @ rot.T).ravel()]
        ipp = rot @ np.array(ds.ImagePositionPatient, float) + shift
        ds.ImagePositionPatient = [round(v, 6) for v in ipp]
    edit(files[::-1], rotate)
    vol = read_dicom(tmp_path / "oblique")
    assert vol.warnings == []
    np.testing.assert_allclose(vol.affine[:3, :3], rot @ plain.affine[:3, :3], atol=1e-5)
    np.testing.assert_allclose(vol.affine[:3, 3], rot @ plain.affine[:3, 3] + shift, atol=1e-5)
    assert np.array_equal(vol.data, plain.data)


def test_gantry_tilt_gives_an_exact_sheared_affine(shared_data, tmp_path):
    files = head_slices(shared_data, tmp_path)
    tan = math.tan(math.radians(20.0))

    def tilt(ds, _):
        x, y, z = (float(v) for v in ds.ImagePositionPatient)
        ds.ImagePositionPatient = [x, round(y + tan * z, 6), z]
        ds.GantryDetectorTilt = 20
    edit(files, tilt)
    vol = read_dicom(tmp_path)
    np.testing.assert_allclose(vol.affine[:3, 2], (0.0, 1.5 * tan, 1.5), atol=1e-5)
    (warning,) = vol.warnings
    assert "sheared by 20.00°" in warning and "GantryDetectorTilt 20" in warning
    z0 = 1.5 * 39  # CTHead40 is the first slice
    z5 = z0 + 5 * 1.5
    np.testing.assert_allclose(vol.affine @ [0, 0, 5, 1], [0, tan * z5, z5, 1], atol=1e-5)


def test_pixel_spacing_rows_then_columns(shared_data, tmp_path):
    files = head_slices(shared_data, tmp_path)
    edit(files, lambda ds, _: setattr(ds, "PixelSpacing", [2.0, 3.2]))  # rows 2.0 mm apart
    vol = read_dicom(tmp_path)
    np.testing.assert_allclose(vol.affine[:3, 0], (3.2, 0, 0))  # i: along a row, column spacing
    np.testing.assert_allclose(vol.affine[:3, 1], (0, 2.0, 0))  # j: down a column, row spacing


def test_non_uniform_spacing_is_a_warning(shared_data, tmp_path):
    files = head_slices(shared_data, tmp_path)

    def nudge(ds, index):
        if index == 3:
            ds.ImagePositionPatient = [0, 0, float(ds.ImagePositionPatient[2]) + 0.2]
    edit(files, nudge)
    vol = read_dicom(tmp_path)
    (warning,) = vol.warnings
    assert "not uniform" in warning and "1.3 to 1.7 mm" in warning
    assert vol.spacing[2] == pytest.approx(1.5)


def test_rescale_dtype_rules(shared_data, tmp_path):
    raw = read_dicom(head_slices(shared_data, tmp_path / "raw"))
    files = head_slices(shared_data, tmp_path / "half")
    edit(files, lambda ds, _: setattr(ds, "RescaleSlope", 0.5))
    half = read_dicom(tmp_path / "half")
    assert half.data.dtype == np.float32
    np.testing.assert_array_equal(half.data, raw.data.astype(np.float32) * 0.5)
    files = head_slices(shared_data, tmp_path / "big")
    edit(files, lambda ds, _: setattr(ds, "RescaleSlope", 10))  # 3926 * 10 does not fit int16
    big = read_dicom(tmp_path / "big")
    assert big.data.dtype == np.float32 and big.data.max() == float(raw.data.max()) * 10
    files = head_slices(shared_data, tmp_path / "mixed")
    edit(files, lambda ds, i: setattr(ds, "RescaleIntercept", -1000 if i == 0 else 0))
    mixed = read_dicom(tmp_path / "mixed")
    assert mixed.data.dtype == np.int16
    assert np.array_equal(mixed.data[:, :, 0], raw.data[:, :, 0] - 1000)
    assert np.array_equal(mixed.data[:, :, 1:], raw.data[:, :, 1:])
    assert mixed.meta["rescale"]["intercept"] == "per slice"


def test_bare_dicom_without_preamble(shared_data, tmp_path):
    files = head_slices(shared_data, tmp_path / "bare")
    for f in files:
        ds = pydicom.dcmread(f)
        ds.preamble = None
        ds.file_meta = pydicom.dataset.FileMetaDataset()
        pydicom.dcmwrite(f, ds, implicit_vr=True, little_endian=True, enforce_file_format=False)
        assert open(f, "rb").read(2) == b"\x08\x00"  # a bare data set: no DICM preamble
    vol = read_dicom(tmp_path / "bare")
    ref = read_dicom(head_slices(shared_data, tmp_path / "ref"))
    assert np.array_equal(vol.data, ref.data) and np.allclose(vol.affine, ref.affine)


def test_choose_among_series_by_index_number_uid_or_file(shared_data, tmp_path):
    head_slices(shared_data, tmp_path, first=40, n=6)
    second = head_slices(shared_data, tmp_path / "sub", first=60, n=4)
    uid = pydicom.uid.generate_uid()

    def other(ds, _):
        ds.SeriesInstanceUID, ds.SeriesNumber, ds.SeriesDescription = uid, 7, "second"
    edit(second, other)
    infos = list_series(tmp_path)
    assert [(s.number, s.n_slices, s.description) for s in infos] == [(7, 4, "second"),
                                                                        (123456, 6, "None")]
    assert read_dicom(tmp_path, series=1).shape == (64, 64, 4)         # 1-based index first
    assert read_dicom(tmp_path, series="2").shape == (64, 64, 6)
    assert read_dicom(tmp_path, series=123456).shape == (64, 64, 6)    # then SeriesNumber
    assert read_dicom(tmp_path, series=uid).meta["series_description"] == "second"
    assert read_dicom(second[0]).shape == (64, 64, 4)                  # the series of that file
    assert load(tmp_path, series="7").meta["series_uid"] == uid


def test_memory_check_before_allocation(shared_data, tmp_path, monkeypatch):
    import anatomesh.core.model.volume as volume
    head_slices(shared_data, tmp_path)
    monkeypatch.setattr(volume, "available_memory_bytes", lambda: 1000.0)
    with pytest.raises(AnatomeshError) as err:
        read_dicom(tmp_path)
    assert "memory" in str(err.value) and str(tmp_path) in str(err.value)


def test_non_orthogonal_orientation_is_kept_with_a_warning(shared_data, tmp_path):
    files = head_slices(shared_data, tmp_path)
    col = np.array([0.05, 1.0, 0.0]) / np.linalg.norm([0.05, 1.0, 0.0])
    edit(files, lambda ds, _: setattr(ds, "ImageOrientationPatient",
                                      [1, 0, 0, *(round(v, 8) for v in col)]))
    vol = read_dicom(tmp_path)
    (warning,) = vol.warnings
    assert "87.14° apart" in warning
    np.testing.assert_allclose(vol.affine[:3, 1], col * 3.2, atol=1e-6)  # as given, not squared
    np.testing.assert_allclose(vol.affine[:3, 2], (0, 0, 1.5), atol=1e-6)  # normal = row x col
