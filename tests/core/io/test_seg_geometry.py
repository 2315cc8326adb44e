"""Where a DICOM SEG's frames land: the file's own exact geometry (per-frame positions, Pixel
Measures), sparse frames as empty planes (never a longer step), frames a little off the grid read
onto it with a note, frames clearly off refused with the offset and the tolerance, the same in the
image and the native grid. Cases: dcmqi's sparse Label Map SEG, and BINARY SEGs written with
highdicom on real head-CT slices in tmp_path, then edited with pydicom."""
from __future__ import annotations

import re
import shutil

import numpy as np
import pydicom
import pytest

from anatomesh.core import load
from anatomesh.core.io.nrrd import read_nrrd
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.segmentation import as_layers
from conftest import shared
from helpers.seg_corpus import (binary_seg, edit_seg, frame_positions, head_ct, move_frames, pixel_measures,
                                segment_voxels)

SPARSE = shared("dicom_seg", "synthetic_tiny", "24x38x3")
HEAD_SLICES = 6


def _structures(vol):
    """{name: bool (I, J, K)} of every structure of a read SEG."""
    return {info.name: layer.data == v for layer in as_layers(vol) for v, info in layer.labels.items()}


def _notes(vol) -> str:
    return " | ".join(vol.meta.get("notes", []))


# -- the sparse Label Map SEG (dcmqi): two of three planes stored ----------------------------------
@pytest.mark.parametrize("edit, why", [(None, "SpacingBetweenSlices"),
                                       (pixel_measures(SpacingBetweenSlices=None), "SliceThickness")],
                         ids=["spacing-between-slices", "slice-thickness-only"])
def test_sparse_label_map_seg_alone_keeps_the_true_step(tmp_path, edit, why):
    """Read without its images, the missing middle plane is an empty plane: the grid and the
    volume equal the NRRD dcmqi made the SEG from (before: twice the slice step, +100 % volume)."""
    path = shutil.copy(SPARSE / "sparse-labelmap-noppv.dcm", tmp_path / "sparse.dcm")
    if edit is not None:
        edit_seg(path, edit)
    ds = pydicom.dcmread(path)
    thickness = float(ds.SharedFunctionalGroupsSequence[0].PixelMeasuresSequence[0].SliceThickness)
    z = np.unique(frame_positions(ds)[:, 2])
    assert len(z) == 2 and z[1] - z[0] == pytest.approx(2 * thickness)  # one plane left out
    truth = read_nrrd(SPARSE / "sparse_labelmap_noppv_seg.nrrd", label_map=True)
    vol = load(path)
    assert vol.shape == truth.shape == (24, 38, 3)
    np.testing.assert_allclose(vol.spacing, (0.7, 0.7, thickness), atol=1e-9)
    np.testing.assert_allclose(vol.affine, truth.affine, atol=1e-4)
    np.testing.assert_array_equal(_structures(vol)["Liver"], truth.data == 1)
    assert int(_structures(vol)["Liver"].sum()) == segment_voxels(ds)["Liver"]
    assert f"step {thickness:g} mm from {why}" in vol.meta["grid"]
    assert "the 1 plane(s) between them without a frame are empty planes" in _notes(vol)


def test_sparse_label_map_seg_with_its_images_is_the_same():
    with_images = load(SPARSE / "sparse-labelmap-noppv.dcm")
    assert "referenced image series" in with_images.meta["grid"]
    truth = read_nrrd(SPARSE / "sparse_labelmap_noppv_seg.nrrd", label_map=True)
    np.testing.assert_allclose(with_images.affine, truth.affine, atol=1e-4)
    np.testing.assert_array_equal(_structures(with_images)["Liver"], truth.data == 1)


# -- BINARY SEGs on real head-CT slices -------------------------------------------------------------
def _labels() -> np.ndarray:
    """uint8 (slices, rows, cols): bone on slices 1 and 4, brain on slice 4; slices 0, 2, 3, 5
    empty (highdicom leaves their frames out)."""
    lab = np.zeros((HEAD_SLICES, 64, 64), np.uint8)
    lab[1, 20:40, 10:30] = 1
    lab[4, 22:44, 12:33] = 1
    lab[4, 5:9, 5:13] = 2
    return lab


@pytest.fixture
def head_case(tmp_path, shared_data):
    """(folder with ct/ and seg.dcm, the SEG alone in another folder, labels, CT files)."""
    folder = tmp_path / "case"
    ct = head_ct(shared_data, folder / "ct", n=HEAD_SLICES)
    seg = binary_seg(ct, _labels(), folder / "seg.dcm")
    alone = tmp_path / "alone"
    alone.mkdir()
    return folder, shutil.copy(seg, alone / "seg.dcm"), _labels(), ct


def _expected_on_ct(lab: np.ndarray, value: int) -> np.ndarray:
    return np.transpose(lab == value, (2, 1, 0))  # (column, row, slice)


def test_sparse_binary_seg_on_its_ct_and_alone(head_case):
    folder, alone, lab, ct = head_case
    ds = pydicom.dcmread(alone)
    assert len(ds.PerFrameFunctionalGroupsSequence) == 3  # empty frames left out
    counts = segment_voxels(ds)
    on_ct = load(folder / "seg.dcm")
    assert on_ct.shape == (64, 64, HEAD_SLICES) and "referenced image series" in on_ct.meta["grid"]
    np.testing.assert_allclose(on_ct.affine, load(ct[0]).affine, atol=1e-9)
    own = load(alone)
    # the frames lie on slices 1 and 4: 4 planes 1.5 mm apart, the 2 between them empty
    assert own.shape == (64, 64, 4) and own.spacing[2] == pytest.approx(1.5)
    for n, name in ((1, "bone"), (2, "brain")):
        np.testing.assert_array_equal(_structures(on_ct)[name], _expected_on_ct(lab, n))
        np.testing.assert_array_equal(_structures(own)[name], _expected_on_ct(lab, n)[:, :, 1:5])
        assert int(_structures(own)[name].sum()) == int(_structures(on_ct)[name].sum()) == counts[name]


def _jitter(ds, voxels: float) -> np.ndarray:
    """Per-frame offsets (F, 3) mm: each frame moved by up to ``voxels`` voxel along z (slice step
    1.5 mm) and x (pixel 3.2 mm), alternating in sign; the largest move is exactly ``voxels``."""
    n = len(ds.PerFrameFunctionalGroupsSequence)
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    frac = voxels * np.linspace(0.5, 1.0, n) * sign
    return np.c_[frac * 3.2, np.zeros(n), frac * 1.5]


@pytest.mark.parametrize("voxels", [0.01, 0.03, 0.05])
def test_frames_slightly_off_the_grid_are_placed_with_a_note(head_case, voxels):
    folder, alone, lab, _ = head_case
    for seg in (folder / "seg.dcm", alone):
        edit_seg(seg, lambda ds: move_frames(_jitter(ds, voxels))(ds))
    on_ct = load(folder / "seg.dcm")
    native_with_ct = load(folder / "seg.dcm", grid="native")
    own = load(alone)
    # on the CT the offsets are the moves made; on its own grid, the moves less the fitted origin
    assert f"up to {voxels:.3f} voxel" in _notes(on_ct)
    assert "off the slices of the referenced image series" in _notes(on_ct)
    for vol in (on_ct, native_with_ct, own):
        text = _notes(vol)
        said = re.search(r"SEG frames lie up to ([0-9.]+) voxel \(([0-9.]+) mm\) off", text)
        assert said and 0.005 < float(said.group(1)) <= voxels + 1e-3, text
        assert "tolerance 0.1 voxel" in text and "placed on its nearest voxel" in text, text
        for n, name in ((1, "bone"), (2, "brain")):
            assert int(_structures(vol)[name].sum()) == int((lab == n).sum())
    assert "off the SEG's own grid" in _notes(own) and "off the SEG's own grid" in _notes(native_with_ct)
    np.testing.assert_array_equal(_structures(on_ct)["bone"], _expected_on_ct(lab, 1))
    np.testing.assert_allclose(own.spacing, (3.2, 3.2, 1.5), atol=1e-9)
    np.testing.assert_array_equal(_structures(own)["bone"], _expected_on_ct(lab, 1)[:, :, 1:5])
    np.testing.assert_array_equal(_structures(native_with_ct)["bone"], _structures(own)["bone"])


@pytest.mark.parametrize("axis, where", [(2, "along the slice normal"), (0, "in its plane")])
def test_frames_clearly_off_the_grid_are_refused_in_both_grids(head_case, axis, where):
    folder, alone, _, _ = head_case
    voxel = (3.2, 3.2, 1.5)[axis]
    for seg in (folder / "seg.dcm", alone):
        def shift(ds):
            offsets = np.zeros((len(ds.PerFrameFunctionalGroupsSequence), 3))
            offsets[-1, axis] = 0.3 * voxel  # the last frame, 0.3 voxel off
            move_frames(offsets)(ds)
        edit_seg(seg, shift)
    messages = []
    for target, kwargs in ((folder / "seg.dcm", {}), (folder / "seg.dcm", {"grid": "native"}), (alone, {})):
        with pytest.raises(AnatomeshError) as err:
            load(target, **kwargs)
        messages.append(str(err.value))
    for m in messages:
        assert "\n" not in m and "seg.dcm" in m and "tolerance" in m and "0.1 voxel" in m, m
    image, native, own = messages
    # on the CT grid the offset is the move made; on the SEG's own grid, the move less the fitted origin
    assert f"frame 3 lies 0.30 voxel ({0.3 * voxel:.3f} mm) off the slices of the referenced image series" in image
    assert f") {where}, more than the tolerance of 0.1 voxel" in image
    assert "fit no grid of their own either; export the segmentation again" in image
    for m in (native, own):
        assert "off the SEG's own grid" in m or "not evenly spaced" in m, m
    assert "put the image series it was made from beside it" in own


def test_a_seg_on_its_own_lattice_offered_native_when_not_on_the_ct(head_case):
    """Every frame 0.3 voxel off the CT slices, but evenly spaced: the image grid refuses and says
    --grid native, which reads it."""
    folder, _, lab, _ = head_case
    seg = folder / "seg.dcm"
    edit_seg(seg, lambda ds: move_frames(np.tile([0.0, 0.0, 0.45], (len(ds.PerFrameFunctionalGroupsSequence), 1)))(ds))
    with pytest.raises(AnatomeshError, match=r"0\.30 voxel \(0\.450 mm\).*--grid native"):
        load(seg)
    own = load(seg, grid="native")
    assert own.affine[2, 3] == pytest.approx(1.5 * 40 + 0.45)  # slice 1 of CTHead40.. at z = 60 mm, moved
    np.testing.assert_array_equal(_structures(own)["bone"], _expected_on_ct(lab, 1)[:, :, 1:5])


def test_pixels_unlike_the_ct_mean_its_own_grid_or_an_error_for_grid_image(head_case):
    folder, _, lab, _ = head_case
    seg = folder / "seg.dcm"
    edit_seg(seg, pixel_measures(PixelSpacing=[1.6, 1.6]))
    vol = load(seg)
    assert "differ from the referenced series'" in _notes(vol) and "meshed on the SEG's own grid" in _notes(vol)
    np.testing.assert_allclose(vol.spacing, (1.6, 1.6, 1.5))
    assert int(_structures(vol)["bone"].sum()) == int((lab == 1).sum())
    with pytest.raises(AnatomeshError, match=r"--grid image cannot be used: the SEG's pixels \(1\.6 x 1\.6 mm"):
        load(seg, grid="image")


def test_without_spacing_between_slices_the_step_comes_from_thickness_or_positions(head_case):
    """No SpacingBetweenSlices: thin frames (1.5 mm) 4.5 mm apart leave empty planes between them;
    thick ones (5 mm, overlapping) give the planes' own step; planes on no lattice are refused."""
    _, alone, lab, _ = head_case
    edit_seg(alone, pixel_measures(SpacingBetweenSlices=None))
    thin = load(alone)
    assert "step 1.5 mm from SliceThickness" in thin.meta["grid"] and thin.shape == (64, 64, 4)
    assert "taken as the SliceThickness and the planes between them as empty" in _notes(thin)
    np.testing.assert_array_equal(_structures(thin)["bone"], _expected_on_ct(lab, 1)[:, :, 1:5])
    edit_seg(alone, pixel_measures(SliceThickness=5.0))
    thick = load(alone)
    assert "step 4.5 mm from the frame positions" in thick.meta["grid"] and thick.shape == (64, 64, 2)



def test_frame_planes_on_no_lattice_are_refused(head_case, tmp_path):
    """Frames on slices 0, 1, 2 and 4 without SpacingBetweenSlices, the last moved half a slice
    (z 64.5 → 63.75): no lattice holds the four planes within 0.1 voxel."""
    _, _, _, ct = head_case
    lab = np.zeros((HEAD_SLICES, 64, 64), np.uint8)
    lab[[0, 1, 2, 4], 20:40, 10:30] = 1
    (tmp_path / "planes").mkdir()
    seg = binary_seg(ct, lab, tmp_path / "planes" / "planes.dcm", names=("bone",))
    edit_seg(seg, pixel_measures(SpacingBetweenSlices=None))
    assert load(seg).shape == (64, 64, 5)  # on the planes' own 1.5 mm lattice, slice 3 empty

    def half_slice(ds):
        for g in ds.PerFrameFunctionalGroupsSequence:
            pos = g.PlanePositionSequence[0]
            if float(pos.ImagePositionPatient[2]) == pytest.approx(64.5):
                pos.ImagePositionPatient = [0, 0, 63.75]
    edit_seg(seg, half_slice)
    with pytest.raises(AnatomeshError) as err:
        load(seg)
    message = str(err.value)
    assert "not evenly spaced" in message and "(the frame positions)" in message and "0.1 voxel" in message
    assert "planes.dcm" in message and "\n" not in message
