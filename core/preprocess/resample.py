"""Resampling a scan to another voxel spacing, within a region of interest, in bounded memory.

The new grid keeps the scan's axes (same directions, same field of view, centred on it) and takes
the asked spacing exactly, so resampling is *separable*: one 1D filter along each axis in turn.
Methods (``method``):

* ``"linear"`` — 2 taps (trilinear interpolation);
* ``"cubic"`` — cubic B-spline (Unser, Aldroubi and Eden 1991, "Fast B-spline transforms for
  continuous image representation and interpolation"; Unser 1999, "Splines: a perfect fit for
  signal and image processing"): the samples are turned into spline coefficients by the recursive
  prefilter (``scipy.ndimage.spline_filter1d``), then 4 taps of the cubic B-spline per axis —
  the same values as ``scipy.ndimage.map_coordinates(order=3, mode="mirror")``;
* ``"lanczos"`` — Lanczos windowed sinc with a = 3 (Duchon 1979, "Lanczos filtering in one and
  two dimensions"), 6 taps, weights normalised to sum 1; when an axis is *down*-sampled the
  kernel is stretched by the ratio of spacings, so it low-passes before decimating (no aliasing).

Samples past the border mirror about the edge voxel (``-1 → 1``, scipy's ``"mirror"`` mode).

Memory: the output (float32) plus one *slab* — a run of planes along the axis with the largest
memory stride, converted to float32 and filtered — whose size is bounded by ``slab_mb``. A
512x512x1000 CT resampled to 1 mm needs the output and ~``slab_mb`` MB more, never a float copy of
the whole input. (The cubic prefilter is global in principle, but its influence decays as
0.268^n: each slab reads :data:`SPLINE_MARGIN` extra planes on both sides, ~1e-11 of the value.)

A region of interest (:func:`roi_bounds`, :func:`crop`) is a box in mm; the scan is cut to the
voxels inside it before anything else (a view, no copy).
"""
from __future__ import annotations

import math
from typing import Optional, Sequence, Tuple

import numpy as np
from scipy import ndimage

from ..model.errors import AnatomeshError
from ..model.progress import Progress, report
from ..model.volume import Volume, convert_affine
from . import _resample_kernels as K

METHODS = ("linear", "cubic", "lanczos")
LANCZOS_A = 3
#: extra planes each slab reads for the cubic prefilter (0.268^20 ~ 4e-12)
SPLINE_MARGIN = 20
#: default memory for one slab (MB): input planes as float32 plus the filtered planes
SLAB_MB = 256.0


def resample(volume: Volume, spacing, method: str = "linear", roi=None, roi_space: Optional[str] = None,
             slab_mb: float = SLAB_MB, progress: Optional[Progress] = None) -> Volume:
    """The scan on a grid of ``spacing`` mm (same axes), optionally cut to a box first.

    Parameters
    ----------
    volume : Volume
        A scalar scan (any real dtype, any memory layout).
    spacing : float or 3 floats
        New voxel size in mm along the volume's axes i, j, k (one number: isotropic).
    method : "linear", "cubic" or "lanczos"
    roi : 6 floats, optional
        Box ``(x0, y0, z0, x1, y1, z1)`` in mm in ``roi_space`` (default: the volume's space).
    slab_mb : float
        Memory for one slab of work, MB (see the module docstring).

    Returns
    -------
    Volume
        float32 data with the memory layout of the input, the new affine (voxel centres), the
        same space, metadata and ``meta["resampled_from"]`` (old shape and spacing).

    Raises
    ------
    AnatomeshError
        For a label map, an unknown method, a spacing that is not positive, or an empty box.
    """
    if volume.is_label_map:
        raise AnatomeshError("resampling blends values and is for scalar scans; for a label map "
                             "use --interpolate (shape-based) instead")
    if method not in METHODS:
        raise AnatomeshError(f"unknown resampling method {method!r}; use one of {', '.join(METHODS)}")
    if roi is not None:
        volume = crop(volume, *roi_bounds(volume, roi, roi_space))
    old = np.asarray(volume.spacing)
    new = _spacing(spacing)
    positions = [grid_positions(n, s, t) for n, s, t in zip(volume.shape, old, new)]
    data = resample_data(volume.data, positions, method, slab_mb, progress)
    affine = np.array(volume.affine)
    affine[:3, :3] = affine[:3, :3] * (new / old)[None, :]
    affine[:3, 3] = volume.affine[:3, :3] @ np.array([p[0] for p in positions]) + volume.affine[:3, 3]
    meta = dict(volume.meta, resampled_from={"shape": list(volume.shape),
                                             "spacing": [round(float(s), 6) for s in old],
                                             "method": method})
    return Volume(data, affine, volume.space, meta, None, list(volume.warnings))


def grid_positions(n: int, old: float, new: float) -> np.ndarray:
    """Positions (float64, in old voxel indices) of the samples of an axis of ``n`` voxels of
    ``old`` mm resampled to ``new`` mm: ``round(n * old / new)`` samples (at least 1), exactly
    ``new`` apart, centred on the old axis."""
    m = max(1, int(round(n * old / new)))
    step = new / old
    return (n - 1) / 2.0 + (np.arange(m) - (m - 1) / 2.0) * step


def resample_data(data: np.ndarray, positions: Sequence[np.ndarray], method: str = "linear",
                  slab_mb: float = SLAB_MB, progress: Optional[Progress] = None) -> np.ndarray:
    """Resample a 3D array at the separable grid ``positions`` (one float array per axis, in
    input voxel indices); float32 result of shape ``(len(p0), len(p1), len(p2))`` in the input's
    memory order, computed slab by slab along the axis of largest stride (see module doc)."""
    if data.ndim != 3:
        raise AnatomeshError(f"resampling needs a 3D volume, got shape {data.shape}")
    perm = tuple(int(a) for a in np.argsort([-abs(s) if n > 1 else 0 for s, n in
                                             zip(data.strides, data.shape)], kind="stable"))
    view = data.transpose(perm)
    pos = [np.asarray(positions[a], np.float64) for a in perm]
    taps = [filter_taps(p, n, method) for p, n in zip(pos, view.shape)]
    out = np.empty(tuple(len(p) for p in pos), np.float32)
    plane = max(1, view.shape[1] * view.shape[2] + out.shape[1] * out.shape[2])
    margin = SPLINE_MARGIN if method == "cubic" else 0
    budget = max(1, int(slab_mb * 2**20 / (4 * 2 * plane)))  # planes of input per slab
    n_in, n_out = view.shape[0], out.shape[0]
    per_slab = max(1, int((budget - taps[0][0].shape[1] - 2 * margin) * n_out / max(n_in, 1)))
    keep = [len(p) == n and np.allclose(p, np.arange(n), atol=1e-9) for p, n in zip(pos, view.shape)]
    for o0 in range(0, n_out, per_slab):
        o1 = min(n_out, o0 + per_slab)
        idx0, w0 = taps[0][0][o0:o1], taps[0][1][o0:o1]
        a = o0 if keep[0] else max(0, int(idx0.min()) - margin)
        b = o1 if keep[0] else min(n_in, int(idx0.max()) + 1 + margin)
        src = view[a:b]
        if method == "cubic":  # the spline coefficients: a float32 copy, filtered in place
            src = np.array(src, dtype=np.float32, order="C")
            for axis in range(3):
                if not keep[axis]:  # samples at the old positions need no coefficients
                    ndimage.spline_filter1d(src, 3, axis=axis, mode="mirror", output=src)
        axes = [axis for axis in range(3) if not keep[axis]]
        if not axes:
            out[o0:o1] = src
        for n, axis in enumerate(axes):  # the last pass writes into the output
            idx, w = (idx0 - a, w0) if axis == 0 else taps[axis]
            src = _pass(src, axis, idx, w, out[o0:o1] if n == len(axes) - 1 else None)
        report(progress, o1 / n_out, f"resampling: {o1}/{n_out} planes")
    return out.transpose(np.argsort(perm))


def _pass(src: np.ndarray, axis: int, idx: np.ndarray, w: np.ndarray,
          dst: Optional[np.ndarray] = None) -> np.ndarray:
    """One 1D pass along ``axis`` into ``dst`` (a new float32 array when None)."""
    if dst is None:
        shape = list(src.shape)
        shape[axis] = idx.shape[0]
        dst = np.empty(shape, np.float32)
    fn = (K.resample_axis0, K.resample_axis1, K.resample_axis2)[axis]
    fn(src, np.ascontiguousarray(idx), np.ascontiguousarray(w), dst)
    return dst


def filter_taps(positions: np.ndarray, n: int, method: str) -> Tuple[np.ndarray, np.ndarray]:
    """Per output sample the input indices (mirrored into ``[0, n)``) and weights of the
    ``method``'s filter: ``(idx (O, T) int64, w (O, T) float32)``."""
    p = np.asarray(positions, np.float64)
    step = float(p[1] - p[0]) if len(p) > 1 else 1.0
    if method == "linear":
        base = np.floor(p)[:, None] + np.arange(2)[None, :]
        w = np.maximum(0.0, 1.0 - np.abs(p[:, None] - base))
    elif method == "cubic":
        base = np.floor(p)[:, None] + np.arange(-1, 3)[None, :]
        w = bspline3(p[:, None] - base)
    elif method == "lanczos":
        scale = max(1.0, step)
        reach = int(math.ceil(LANCZOS_A * scale))
        base = np.floor(p)[:, None] + np.arange(-reach + 1, reach + 1)[None, :]
        w = lanczos((p[:, None] - base) / scale, LANCZOS_A)
        w /= w.sum(axis=1, keepdims=True)
    else:
        raise AnatomeshError(f"unknown resampling method {method!r}; use one of {', '.join(METHODS)}")
    return mirror(base.astype(np.int64), n), w.astype(np.float32)


def mirror(i: np.ndarray, n: int) -> np.ndarray:
    """Indices reflected about the edge samples into ``[0, n)`` (``-1 → 1``, ``n → n - 2``)."""
    if n == 1:
        return np.zeros_like(i)
    period = 2 * n - 2
    i = np.abs(i) % period
    return np.where(i >= n, period - i, i)


def bspline3(x: np.ndarray) -> np.ndarray:
    """The cubic B-spline basis function β³(x)."""
    a = np.abs(x)
    return np.where(a < 1, (4 - 6 * a**2 + 3 * a**3) / 6, np.where(a < 2, (2 - a) ** 3 / 6, 0.0))


def lanczos(x: np.ndarray, a: int = LANCZOS_A) -> np.ndarray:
    """The Lanczos kernel sinc(x) sinc(x / a) on |x| < a, else 0."""
    return np.where(np.abs(x) < a, np.sinc(x) * np.sinc(x / a), 0.0)


# ---------------------------------------------------------------------------------------------
# region of interest
# ---------------------------------------------------------------------------------------------
def roi_bounds(volume: Volume, box, space: Optional[str] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Voxel index range ``[lo, hi)`` (int64 (3,) each) of the voxels whose centres lie inside
    ``box`` = ``(x0, y0, z0, x1, y1, z1)`` mm in ``space`` (default: the volume's).

    Raises :class:`AnatomeshError` when the box is malformed or holds no voxel centre."""
    b = np.asarray(box, np.float64).ravel()
    if b.size != 6 or not np.all(np.isfinite(b)):
        raise AnatomeshError(f"--roi must be 6 numbers x0,y0,z0,x1,y1,z1 in mm, got {box!r}")
    lo_mm, hi_mm = np.minimum(b[:3], b[3:]), np.maximum(b[:3], b[3:])
    affine = convert_affine(volume.affine, volume.space, space or volume.space)
    corners = np.array([[x, y, z, 1.0] for x in (lo_mm[0], hi_mm[0]) for y in (lo_mm[1], hi_mm[1])
                        for z in (lo_mm[2], hi_mm[2])])
    ijk = (np.linalg.inv(affine) @ corners.T)[:3]
    lo = np.maximum(np.ceil(ijk.min(axis=1) - 1e-6), 0).astype(np.int64)
    hi = np.minimum(np.floor(ijk.max(axis=1) + 1e-6) + 1, volume.shape).astype(np.int64)
    if np.any(hi <= lo):
        ext = _extent(volume, space or volume.space)
        raise AnatomeshError(f"the --roi box {_fmt(b)} mm ({space or volume.space}) holds no voxel of the "
                             f"scan, which spans {ext}; give a box inside it")
    return lo, hi


def crop(volume: Volume, lo, hi) -> Volume:
    """The voxels ``[lo, hi)`` (index ranges per axis) as a Volume: a view of the data, the
    affine moved to the new first voxel, ``meta["cropped_from"]`` recording the box."""
    lo, hi = np.asarray(lo, np.int64), np.asarray(hi, np.int64)
    data = volume.data[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    affine = np.array(volume.affine)
    affine[:3, 3] = volume.affine[:3, :3] @ lo + volume.affine[:3, 3]
    meta = dict(volume.meta, cropped_from={"shape": list(volume.shape), "lo": lo.tolist(),
                                           "hi": hi.tolist()})
    return Volume(data, affine, volume.space, meta, volume.labels, list(volume.warnings))


def _spacing(spacing) -> np.ndarray:
    s = np.asarray(spacing, np.float64).ravel()
    if s.size == 1:
        s = np.repeat(s, 3)
    if s.size != 3 or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise AnatomeshError(f"--resample needs a spacing in mm > 0 (one number, or X,Y,Z), got {spacing!r}")
    return s


def _extent(volume: Volume, space: str) -> str:
    affine = convert_affine(volume.affine, volume.space, space)
    n = np.asarray(volume.shape) - 1
    corners = np.array([[i, j, k, 1.0] for i in (0, n[0]) for j in (0, n[1]) for k in (0, n[2])])
    mm = (affine @ corners.T)[:3]
    return _fmt(np.r_[mm.min(axis=1), mm.max(axis=1)]) + " mm"


def _fmt(b) -> str:
    return ",".join(f"{x:g}" for x in np.round(b, 1))
