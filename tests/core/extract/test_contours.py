"""RT contours → closed surfaces, both ways (direct tiling; rasterisation + shape-based
interpolation + conforming extraction), on analytic shapes built here: a sphere's circles, a
torus' two concentric circles per plane, a Y branching into two tubes. Volumes within 2 % of the
truth, closed oriented 2-manifolds, vertices exactly on the contour points."""
from __future__ import annotations

import math

import numpy as np
import pytest

from anatomesh.core.extract.contours import tile_roi
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.topology import topology
from anatomesh.core.io.contour_raster import contour_grid, rasterise_roi
from anatomesh.core.model.labels import LabelInfo
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.model.segmentation import RoiContours, segmentation_from_masks

N = 180  # points per circle: the inscribed polygon loses 0.02 % of the area


def circle(cx, cy, r, z, n=N, clockwise=False):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    if clockwise:
        t = t[::-1]
    return np.c_[cx + r * np.cos(t), cy + r * np.sin(t), np.full(n, float(z))]


def roi_of(contours, name="shape", normal=(0.0, 0.0, 1.0)):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    t = np.array([float(np.median(c @ normal)) for c in contours])
    planes = np.unique(np.round(t, 6))
    idx = np.array([int(np.argmin(np.abs(planes - x))) for x in t])
    return RoiContours(LabelInfo(1, name, (1.0, 0.0, 0.0)), contours, idx, normal, planes, "analytic")


def sphere_roi(R=20.0, h=2.0):
    zs = np.arange(-R + h / 2, R, h)
    return roi_of([circle(0, 0, math.sqrt(R * R - z * z), z) for z in zs]), 4 / 3 * math.pi * R ** 3


def torus_roi(R=30.0, r=10.0, h=1.0):
    cs = []
    for z in np.arange(-r + h / 2, r, h):
        w = math.sqrt(r * r - z * z)
        cs += [circle(0, 0, R + w, z), circle(0, 0, R - w, z, clockwise=True)]
    return roi_of(cs), 2 * math.pi ** 2 * R * r * r


def _union_outline(d, r, n=N):
    """Outline of the union of two circles of radius r at (±d, 0), counter-clockwise."""
    if d <= 1e-9:
        return circle(0, 0, r, 0, n)[:, :2]
    t0 = math.acos(-d / r)  # right circle: x = d + r cos t >= 0
    tr = np.linspace(-t0, t0, n // 2)
    right = np.c_[d + r * np.cos(tr), r * np.sin(tr)]
    return np.concatenate([right, -right])


def _lens(d, r):
    """Area of the intersection of two circles of radius r whose centres are 2d apart."""
    c = 2 * d
    if c >= 2 * r:
        return 0.0
    return 2 * r * r * math.acos(c / (2 * r)) - 0.5 * c * math.sqrt(4 * r * r - c * c)


def y_roi(r=5.3, h=1.0, z0=20.0, top=50.0, slope=0.4):
    cs, zs = [], np.arange(0.0, top + 1e-9, h)
    for z in zs:
        d = max(0.0, (z - z0) * slope)
        if d < r:
            xy = _union_outline(d, r)
            cs.append(np.c_[xy, np.full(len(xy), z)])
        else:
            cs += [circle(d, 0, r, z), circle(-d, 0, r, z)]
    fine = np.linspace(0.0, top, 20001)
    area = [2 * math.pi * r * r - _lens(max(0.0, (z - z0) * slope), r) for z in fine]
    trapezoid = getattr(np, "trapezoid", None) or np.trapz  # NumPy 2 renamed it
    return roi_of(cs), float(trapezoid(area, fine))


SHAPES = {"sphere": sphere_roi, "torus": torus_roi, "Y": y_roi}


def _check_closed(m, genus=None):
    topo = topology(m.vertices, m.faces)
    assert topo.closed and topo.manifold and topo.oriented, topo
    if genus is not None:
        assert topo.genus == genus
    return topo


@pytest.mark.parametrize("shape", list(SHAPES))
def test_tiling_volume_and_topology(shape):
    roi, truth = SHAPES[shape]()
    m = tile_roi(roi)
    _check_closed(m, {"sphere": 0, "torus": 1, "Y": 0}[shape])
    vol = signed_volume(m.vertices, m.faces)
    assert vol > 0
    assert abs(vol - truth) / truth < 0.02, (shape, vol, truth)
    # every vertex is a contour point, where the contour put it
    pts = {tuple(p) for p in np.concatenate(roi.contours).astype(np.float32)}
    assert all(tuple(v) in pts for v in m.vertices)


@pytest.mark.parametrize("shape", list(SHAPES))
def test_raster_volume_matches_tiling(shape):
    roi, truth = SHAPES[shape]()
    grid = contour_grid([roi], None, pixel_mm=0.5)
    mask = rasterise_roi(roi, grid)
    vol = segmentation_from_masks([mask], grid.shape, grid.affine, "LPS")
    shell = label_surfaces(vol).shells()[0]
    _check_closed(shell)
    raster = signed_volume(shell.vertices, shell.faces)
    assert abs(raster - mask.voxels * vol.voxel_volume_mm3()) < 1e-3 * raster
    assert abs(raster - truth) / truth < 0.02, (shape, raster, truth)
    tiled = tile_roi(roi)
    assert abs(raster - signed_volume(tiled.vertices, tiled.faces)) / truth < 0.02


def test_raster_planes_are_exact_even_odd():
    """On a contour plane a voxel is inside iff its centre is inside (hole of the torus: out)."""
    roi, _ = torus_roi()
    grid = contour_grid([roi], None, pixel_mm=0.5)
    mask = rasterise_roi(roi, grid)
    k = int(grid.plane_k[len(roi.plane_t) // 2])
    full = np.zeros(grid.shape, bool)
    o = mask.offset
    full[o[0]:o[0] + mask.data.shape[0], o[1]:o[1] + mask.data.shape[1], o[2]:o[2] + mask.data.shape[2]] = mask.data
    ii, jj = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
    centres = grid.affine[:3, :3] @ np.stack([ii.ravel(), jj.ravel(), np.full(ii.size, k)]) + grid.affine[:3, 3:4]
    rad = np.hypot(centres[0], centres[1]).reshape(ii.shape)
    z = centres[2, 0]
    w = math.sqrt(100.0 - z * z)
    expect = (rad < 30 + w - 0.02) & (rad > 30 - w + 0.02)
    unsure = np.abs(rad - (30 + w)) < 0.05
    unsure |= np.abs(rad - (30 - w)) < 0.05
    assert np.array_equal(full[:, :, k][~unsure], expect[~unsure])


def test_oblique_stack_tiles_and_rasterises():
    """A sphere contoured on tilted planes (normal 30° off z) keeps its volume both ways."""
    n = np.array([math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))])
    u = np.cross([0.0, 1.0, 0.0], n)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    R, cs = 15.0, []
    for s in np.arange(-R + 0.5, R, 1.0):
        c = circle(0, 0, math.sqrt(R * R - s * s), 0)
        cs.append(np.array([5.0, -3.0, 2.0]) + c[:, :1] * u + c[:, 1:2] * v + s * n)
    roi = roi_of(cs, normal=n)
    truth = 4 / 3 * math.pi * R ** 3
    m = tile_roi(roi)
    _check_closed(m, 0)
    assert abs(signed_volume(m.vertices, m.faces) - truth) / truth < 0.02
    grid = contour_grid([roi], None, pixel_mm=0.5)
    mask = rasterise_roi(roi, grid)
    assert abs(mask.voxels * abs(np.linalg.det(grid.affine[:3, :3])) - truth) / truth < 0.02


def test_single_contour_roi_is_a_closed_slab_both_ways():
    """One contour alone: tiling gives a closed prism one plane step thick around it; the raster
    gives the voxels of its plane."""
    c = circle(0, 0, 8.0, 4.0)
    roi = roi_of([c])
    m = tile_roi(roi)
    _check_closed(m, 0)
    area = 0.5 * N * 64.0 * math.sin(2 * math.pi / N)
    assert signed_volume(m.vertices, m.faces) == pytest.approx(area * 1.0, rel=1e-3)
    assert np.isclose(m.vertices[:, 2], 4.0).sum() == N  # the contour itself is the middle belt
    grid = contour_grid([roi], None, pixel_mm=0.5)
    mask = rasterise_roi(roi, grid)
    assert mask.data.shape[2] == 1
    assert abs(mask.voxels * 0.25 - area) / area < 0.02
