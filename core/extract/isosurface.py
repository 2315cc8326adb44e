"""Isosurfaces of scalar scans: watertight marching cubes in mm.

:func:`isosurface` extracts the surface ``value == level`` of a volume as an indexed face set:
one shared vertex per crossed grid edge, triangles oriented so their normals point out of the
region ``value >= level`` (positive signed volume for a bright blob, whatever the affine),
vertex normals from the scalar field's gradient. The case table (:mod:`.mc_table`) cuts every
cube face with one fixed rule, so neighbouring cells agree and the surface is closed and
2-manifold except where it leaves the grid; ``cap=True`` closes it there too.

Method: marching cubes (Lorensen and Cline 1987) organised like flying edges (Schroeder, Maynard
and Geveci 2015): one pass packs ``value >= level`` into bits (one read of the data, shared by all
levels of :func:`isosurfaces`); the counting and output passes work on the bits, 64 voxels per
machine word (empty space costs a few integer operations per word, where flying edges trims each
row), and read the data only next to crossed edges. The sweep follows the memory layout: the
axis with the smallest stride is swept (C or Fortran order alike, through a transposed view, no
copy; the affine's columns are permuted to match and the winding flipped when needed). Work is
split over slabs with ``numba.prange``; prefix sums place each slab's output, so results do not
depend on the thread count. Extra memory: one bit per voxel per level and four int32 counters
per grid row, besides the output arrays.

Conventions
-----------
* A voxel is *above* when ``value >= level``: a level equal to voxel values (integer CT at an
  integer HU) is symbolically perturbed, and the interpolation parameter along an edge is clamped
  to ``[T_MIN, 1 − T_MIN]`` (``T_MIN = 1e-3`` voxel): no vertex on a voxel centre, hence no
  two vertices at one position and no zero-area triangle (a triangle's corners lie on three
  different edges of one cube, away from its corners, and such points are never collinear).
* NaN voxels count as below the level (they never belong to the region); a vertex on an edge to
  a NaN voxel sits at the edge midpoint.
* ``cap=True`` treats samples outside the grid as below the level: the surface is closed by caps
  lying ``T_MIN`` voxel outside the border voxel centres, with normals pointing out of the grid.
"""
from __future__ import annotations

import math
from numbers import Real
from typing import List, Optional, Sequence

import numba
import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.progress import Progress, report
from ..model.volume import SPACES, Volume, convert_affine
from . import _isosurface_kernels as K
from .mc_table import TRI_COUNT, TRI_EDGES

#: clamp of the interpolation parameter along an edge (fraction of a voxel)
T_MIN = 1e-3
#: most slabs per work item of the parallel passes after classification (dynamic scheduling;
#: fewer when the sweep has fewer than 16 work items of this size)
SLAB_CHUNK = 32

_MAX_INDEX = 2**31 - 1
#: the case table for the kernels: uint8, padding (-1) replaced by a valid edge number (0)
_TRI_EDGES = np.where(TRI_EDGES < 0, 0, TRI_EDGES).astype(np.uint8)
#: the same with every triangle's winding reversed (for affines that flip orientation)
_TRI_EDGES_FLIPPED = np.ascontiguousarray(_TRI_EDGES.reshape(256, -1, 3)[:, :, [0, 2, 1]].reshape(256, -1))


def isosurface(volume, level: float, affine: Optional[np.ndarray] = None, space: Optional[str] = None,
               cap: bool = False, progress: Optional[Progress] = None) -> Mesh:
    """The isosurface ``value == level`` of a scan, in mm.

    Parameters
    ----------
    volume : Volume or array_like, shape (I, J, K)
        A :class:`~anatomesh.core.model.volume.Volume` or a 3D array of real numbers (any memory
        layout; never copied unless its dtype is float16 or in non-native byte order).
    level : float
        Isovalue in the volume's units (e.g. HU); voxels with ``value >= level`` are inside.
    affine : (4, 4) array, optional
        Voxel index → mm at voxel centres. Default: the volume's, or the identity for arrays.
    space : "RAS" or "LPS", optional
        Space of the output vertices. Default: the volume's space ("RAS" for arrays, where the
        affine is taken to map into ``space``).
    cap : bool
        Close the surface where it leaves the grid (outside counts as below the level).
    progress : callable, optional
        ``progress(fraction, text)``; may raise :class:`~anatomesh.core.model.errors.Cancelled`.

    Returns
    -------
    Mesh
        ``vertices`` (N, 3) float32 mm, ``faces`` (M, 3) int32 counter-clockwise seen from outside,
        ``normals`` (N, 3) float32 unit, pointing out of the region above the level. Empty when
        the level is outside the data range (no voxel above, or every voxel above).

    Raises
    ------
    AnatomeshError
        Not a 3D real array, a non-finite level, or a singular / non-finite affine.
    """
    return isosurfaces(volume, [level], affine=affine, space=space, cap=cap, progress=progress)[0]


def isosurfaces(volume, levels: Sequence[float], affine: Optional[np.ndarray] = None,
                space: Optional[str] = None, cap: bool = False,
                progress: Optional[Progress] = None) -> List[Mesh]:
    """Several isosurfaces from one read of the data; one :class:`Mesh` per level, in order.

    Same parameters as :func:`isosurface`, with ``levels`` a sequence of isovalues. The only pass
    over the whole volume classifies each row against every level while the row is in cache
    (each cell visited once for all isosurfaces); the later passes touch only the bits
    and the voxels next to crossed edges.
    """
    data, aff, out_space = _resolve_input(volume, affine, space)
    lv = _check_levels(levels)
    view, perm = _sweep_view(data)
    m, n, flip = _frame(aff, perm)
    meshes: List[Optional[Mesh]] = [None] * len(lv)
    thresholds, valid = _thresholds(lv, view.dtype)
    pad = 1 if cap else 0
    nz, ny, nx = view.shape
    dims = (nz + 2 * pad, ny + 2 * pad, nx + 2 * pad)
    notes = ["level outside the data range (no voxel above it, or none below)"] * len(lv)
    work = [i for i in range(len(lv)) if valid[i]]
    if view.size == 0 or min(dims) < 2:
        work, notes = [], ["the volume has no cells (an axis shorter than 2 voxels; try cap=True)"] * len(lv)
    report(progress, 0.0, "isosurface: classifying voxels")
    if work:
        n_words = (dims[2] + 63) // 64
        bits = np.zeros((len(work), dims[0], dims[1], n_words), np.uint64)
        n_above = np.zeros((len(work), nz), np.int64)
        K.classify(view, thresholds[work], pad, bits, n_above)
        for w, i in enumerate(work):
            report(progress, 0.3 + 0.7 * w / len(work), f"isosurface at {lv[i]:g}: triangles")
            total = int(n_above[w].sum())
            if 0 < total < view.size:
                meshes[i] = _extract(view, bits[w], lv[i], pad, dims, m, n, flip, out_space, cap)
    for i in range(len(lv)):
        if meshes[i] is None:
            meshes[i] = _mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32),
                              np.zeros((0, 3), np.float32), lv[i], out_space, cap)
            meshes[i].meta["note"] = notes[i]
    report(progress, 1.0, "isosurface: done")
    return meshes  # type: ignore[return-value]


# ---------------------------------------------------------------------------------------------
def _extract(view, bits, level, pad, dims, m, n, flip, space, cap) -> Mesh:
    # slabs handed out a few at a time as threads free up: the surface is rarely spread evenly
    # along the sweep (one half of a bone surface may hold far more of it than the other)
    with numba.parallel_chunksize(max(1, min(SLAB_CHUNK, dims[0] // 16))):
        return _extract_slabs(view, bits, level, pad, dims, m, n, flip, space, cap)


def _extract_slabs(view, bits, level, pad, dims, m, n, flip, space, cap) -> Mesh:
    nzv, nyv, nxv = dims
    n_xe, n_ye, n_ze, n_tri = (np.empty((nzv, nyv), np.int32) for _ in range(4))
    slab_v, slab_t = np.empty(nzv, np.int64), np.empty(nzv, np.int64)
    K.count(bits, nxv, TRI_COUNT, n_xe, n_ye, n_ze, n_tri, slab_v, slab_t)
    v_start, n_vertices = _exclusive_cumsum(slab_v)
    t_start, n_faces = _exclusive_cumsum(slab_t)
    if n_vertices > _MAX_INDEX or n_faces > _MAX_INDEX:
        raise AnatomeshError(f"the isosurface at {level:g} would have {n_vertices:,} vertices and "
                             f"{n_faces:,} triangles, more than int32 indices allow; crop or "
                             "downsample the scan first")
    vertices = np.empty((n_vertices, 3), np.float32)
    normals = np.empty((n_vertices, 3), np.float32)
    faces = np.empty((n_faces, 3), np.int32)
    K.emit_vertices(view, bits, float(level), T_MIN, pad, m, n, n_xe, n_ye, n_ze, v_start, vertices,
                    normals)
    K.emit_triangles(bits, nxv, TRI_COUNT, _TRI_EDGES_FLIPPED if flip else _TRI_EDGES,
                     n_xe, n_ye, n_ze, n_tri, v_start, t_start, faces)
    return _mesh(vertices, faces, normals, level, space, cap)


def _mesh(vertices, faces, normals, level, space, cap) -> Mesh:
    return Mesh(vertices, faces, normals, name=f"isosurface {level:g}", value=float(level),
                space=space, meta={"level": float(level), "cap": bool(cap), "t_min": T_MIN})


def _exclusive_cumsum(counts: np.ndarray):
    off = np.zeros_like(counts)
    np.cumsum(counts[:-1], out=off[1:])
    return off, int(counts.sum())


# ---------------------------------------------------------------------------------------------
# input checks and frames
# ---------------------------------------------------------------------------------------------
def _resolve_input(volume, affine, space):
    """(data array, 4x4 affine into the output space, output space name)."""
    if isinstance(volume, Volume):
        data, vol_space = volume.data, volume.space
        aff = volume.affine if affine is None else affine
    else:
        data, vol_space = volume, (space or "RAS")
        aff = np.eye(4) if affine is None else affine
    out_space = space or vol_space
    if out_space not in SPACES:
        raise AnatomeshError(f"unknown space {out_space!r}; use one of {SPACES}")
    data = _check_data(data)
    try:
        aff = np.asarray(aff, dtype=np.float64)
    except (TypeError, ValueError):
        raise AnatomeshError("the affine must be a 4x4 array of numbers") from None
    if aff.shape != (4, 4) or not np.all(np.isfinite(aff)):
        raise AnatomeshError(f"the affine must be a finite 4x4 matrix, got shape {aff.shape}")
    det = float(aff[:3, 0] @ np.cross(aff[:3, 1], aff[:3, 2]))
    if not abs(det) > 1e-12 * max(1.0, float(np.abs(aff[:3, :3]).max()) ** 3):
        raise AnatomeshError("the affine's 3x3 part is singular (a voxel size of 0?); check the "
                             "scan's spacing and direction")
    aff = convert_affine(aff, vol_space, out_space)
    return data, aff, out_space


def _check_data(data) -> np.ndarray:
    if not isinstance(data, np.ndarray):
        try:
            data = np.asarray(data)
        except (TypeError, ValueError):
            raise AnatomeshError("the volume must be a 3D array of numbers") from None
    if data.ndim != 3:
        raise AnatomeshError(f"isosurfaces need a 3D volume, got an array of shape {data.shape}; "
                             "pick one volume of a 4D series or stack 2D slices first")
    kind = data.dtype.kind
    if kind == "b":
        data = data.view(np.uint8)
    elif kind not in "iuf":
        raise AnatomeshError(f"the volume must hold real numbers, got dtype {data.dtype}")
    if data.dtype == np.float16:
        data = data.astype(np.float32)  # numba has no float16 (copy)
    if not data.dtype.isnative:
        data = data.astype(data.dtype.newbyteorder("="))  # numba needs native byte order (copy)
    return data


def _check_levels(levels) -> List[float]:
    if isinstance(levels, (str, bytes, Real, complex, np.number)) or (
            isinstance(levels, np.ndarray) and levels.ndim == 0):
        levels = [levels]
    try:
        levels = list(levels)
    except TypeError:
        raise AnatomeshError(f"isovalues {levels!r} are not numbers; give e.g. 300 for bone in CT") from None
    out = []
    for lv in levels:
        if isinstance(lv, (bool, np.bool_)) or not isinstance(lv, Real):
            raise AnatomeshError(f"isovalue {lv!r} is not a number; give e.g. 300 for bone in CT")
        f = float(lv)
        if not math.isfinite(f):
            raise AnatomeshError(f"isovalue {lv!r} is not finite; give a number in the scan's range")
        out.append(f)
    if not out:
        raise AnatomeshError("no isovalue given; give at least one level")
    return out


def _thresholds(levels: List[float], dtype: np.dtype):
    """Per level the threshold ``t`` in the data's dtype with ``v >= t  ⇔  v >= level``.

    Returns (thresholds array of dtype, valid flags); a level no voxel of this dtype can reach
    (or that every value reaches) is not valid — its mesh is empty.
    """
    out = np.zeros(len(levels), dtype)
    valid = []
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        for i, lv in enumerate(levels):
            t = math.ceil(lv)
            valid.append(info.min < t <= info.max)
            out[i] = min(max(t, info.min), info.max)
    else:
        for i, lv in enumerate(levels):
            with np.errstate(over="ignore"):
                t = np.asarray(lv, dtype=dtype)
            if float(t) < lv:
                t = np.nextafter(t, np.asarray(np.inf, dtype))
            out[i] = t
            valid.append(True)
    return out, valid


def _sweep_view(data: np.ndarray):
    """A view with the axis of smallest stride last (the kernels sweep it), and its axis order.

    C order keeps the axes; F order reverses them (a transposed view, no copy).
    """
    key = [abs(s) if n > 1 else np.inf for s, n in zip(data.strides, data.shape)]
    perm = tuple(int(a) for a in np.argsort([-k for k in key], kind="stable"))
    return data.transpose(perm), perm


def _frame(aff: np.ndarray, perm):
    """Map from the kernels' cell frame (x, y, z) = view axes (2, 1, 0) to mm.

    Returns ``m`` (12-tuple: the (3, 4) map, row-major), ``n`` (9-tuple: the inverse transpose of
    its 3x3 part, row-major, which maps index-space gradients to mm) and ``flip`` (the map
    reverses orientation: the winding is reversed so normals still point out).
    """
    mat = np.empty((3, 4))
    for col, view_axis in enumerate((2, 1, 0)):
        mat[:, col] = aff[:3, perm[view_axis]]
    mat[:, 3] = aff[:3, 3]
    a, b, c = mat[:, 0], mat[:, 1], mat[:, 2]
    det = float(a @ np.cross(b, c))
    inv_t = np.stack([np.cross(b, c), np.cross(c, a), np.cross(a, b)], axis=1) / det
    return (tuple(float(x) for x in mat.ravel()), tuple(float(x) for x in inv_t.ravel()), det < 0)
