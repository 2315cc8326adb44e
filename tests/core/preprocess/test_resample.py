"""resample(): the same values as scipy.ndimage for linear and cubic, the slab path equal to the
whole-volume path, the region of interest, and surfaces closer to the true shape."""
import numpy as np
import pytest
from scipy import ndimage

from anatomesh.core.extract.isosurface import isosurface
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.volume import Volume
from anatomesh.core.preprocess.resample import (crop, filter_taps, grid_positions, resample,
                                                resample_data, roi_bounds)
from helpers.fields import grid, mean_error, sphere_distance


@pytest.fixture(scope="module")
def noise():
    return np.random.default_rng(3).normal(size=(21, 17, 9)).astype(np.float32)


def positions():
    return [grid_positions(21, 1.0, 0.7), grid_positions(17, 1.0, 1.6), grid_positions(9, 5.0, 1.0)]


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("method, spline_order", [("linear", 1), ("cubic", 3)])
def test_matches_scipy_map_coordinates(noise, order, method, spline_order):
    pos = positions()
    ref = ndimage.map_coordinates(noise.astype(np.float64), np.meshgrid(*pos, indexing="ij"),
                                  order=spline_order, mode="mirror")
    out = resample_data(np.asarray(noise, order=order), pos, method)
    assert out.shape == ref.shape == (30, 11, 45)
    np.testing.assert_allclose(out, ref, atol=2e-5)
    assert out.flags["F_CONTIGUOUS" if order == "F" else "C_CONTIGUOUS"]  # the input's layout
    np.testing.assert_array_equal(noise, np.asarray(noise))  # the input is not touched


@pytest.mark.parametrize("method", ["linear", "cubic", "lanczos"])
def test_slabs_give_the_same_result(noise, method):
    """The bounded-memory path: slabs of a few planes (a tiny slab budget) equal one slab."""
    pos = positions()
    whole = resample_data(noise, pos, method, slab_mb=1000.0)
    slabs = resample_data(noise, pos, method, slab_mb=0.002)  # ~ one plane per slab
    np.testing.assert_allclose(slabs, whole, atol=1e-6)


def test_lanczos_keeps_constants_and_low_passes_when_downsampling():
    flat = np.full((12, 12, 12), 7.0, np.float32)
    out = resample_data(flat, [grid_positions(12, 1.0, 0.6)] * 3, "lanczos")
    np.testing.assert_allclose(out, 7.0, atol=1e-5)
    idx, w = filter_taps(grid_positions(40, 1.0, 3.0), 40, "lanczos")
    assert idx.shape[1] == 18  # 2 a x the ratio of spacings: an anti-aliasing filter
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-6)
    stripes = np.tile(np.array([1.0, -1.0], np.float32), 20)  # the highest frequency: removed
    down = resample_data(np.broadcast_to(stripes, (2, 2, 40)).copy(), [np.arange(2.0)] * 2
                         + [grid_positions(40, 1.0, 3.0)], "lanczos")
    assert np.abs(down).max() < 0.05


def test_grid_keeps_field_of_view_and_spacing():
    vol = Volume(np.zeros((10, 8, 5), np.int16), np.diag([1.0, 1.0, 4.0, 1.0]))
    out = resample(vol, 2.0)
    assert out.shape == (5, 4, 10) and out.spacing == pytest.approx((2.0, 2.0, 2.0))
    # the first voxel centre moves to keep the grid centred on the old field of view
    np.testing.assert_allclose(out.affine[:3, 3], [0.5, 0.5, -1.0])
    assert out.data.dtype == np.float32 and out.meta["resampled_from"]["spacing"] == [1.0, 1.0, 4.0]


def test_thick_slices_resampled_come_closer_to_the_sphere():
    """A sphere's distance field on 1 x 1 x 4 mm voxels: cubic B-spline (and Lanczos) resampling
    to 1 mm brings the isosurface closer to the true sphere (mean distance halved)."""
    (x, y, z), affine = grid((40, 40, 11), (1.0, 1.0, 4.0))
    vol = Volume((14.0 - np.sqrt(x**2 + y**2 + z**2)).astype(np.float32), affine)
    before = mean_error(isosurface(vol, 0.0, cap=True), sphere_distance, 14.0)
    cubic = mean_error(isosurface(resample(vol, 1.0, "cubic"), 0.0, cap=True), sphere_distance, 14.0)
    lanczos = mean_error(isosurface(resample(vol, 1.0, "lanczos"), 0.0, cap=True), sphere_distance, 14.0)
    assert cubic < before / 1.8 and lanczos < before / 1.6, (before, cubic, lanczos)


def test_roi_cuts_to_the_voxels_inside_the_box():
    (x, y, z), affine = grid((20, 20, 10), (1.0, 1.0, 2.0))
    vol = Volume(x.astype(np.float32), affine, "RAS")
    lo, hi = roi_bounds(vol, [-3.2, -100, 0.0, 4.0, 100, 100])
    cut = crop(vol, lo, hi)
    centres = cut.affine @ np.c_[np.indices(cut.shape).reshape(3, -1).T, np.ones(np.prod(cut.shape))].T
    assert centres[0].min() >= -3.2 and centres[0].max() <= 4.0 and centres[2].min() >= 0.0
    np.testing.assert_allclose(cut.data[:, 0, 0], centres[0].reshape(cut.shape)[:, 0, 0])
    # the box in LPS: x and y flip
    lo2, hi2 = roi_bounds(vol, [-4.0, -100, 0.0, 3.2, 100, 100], "LPS")
    assert list(lo2) == list(lo) and list(hi2) == list(hi)
    with pytest.raises(AnatomeshError, match="holds no voxel"):
        roi_bounds(vol, [500, 500, 500, 600, 600, 600])
    with pytest.raises(AnatomeshError, match="6 numbers"):
        roi_bounds(vol, [1, 2, 3])


def test_bad_settings_are_one_line_errors():
    vol = Volume(np.zeros((4, 4, 4), np.float32), np.eye(4))
    with pytest.raises(AnatomeshError, match="method"):
        resample(vol, 1.0, "nearest")
    with pytest.raises(AnatomeshError, match="> 0"):
        resample(vol, [1.0, 0.0, 1.0])
    labels = Volume(np.zeros((4, 4, 4), np.uint8), np.eye(4), labels={})
    with pytest.raises(AnatomeshError, match="--interpolate"):
        resample(labels, 1.0)
