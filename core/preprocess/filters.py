"""Smoothing a scan before extraction, with kernels sized in millimetres per axis.

A kernel given in mm becomes a different number of voxels along each axis, so thick slices get
a kernel that is thin in voxels along the slice axis — anisotropic data gets an anisotropic
kernel (a 1 mm Gaussian on 0.5 x 0.5 x 5 mm voxels is 2 x 2 x 0.2 voxels).

* :func:`gaussian` — Gaussian of standard deviation ``sigma_mm`` (``scipy.ndimage.gaussian_filter``,
  separable, borders repeat the edge voxel);
* :func:`median` — median over a box ``size_mm`` wide (``scipy.ndimage.median_filter``): removes
  salt-and-pepper noise and keeps edges;
* :func:`diffusion` — edge-preserving anisotropic diffusion (Perona and Malik 1990, "Scale-space
  and edge detection using anisotropic diffusion"): smooths within regions, not across edges.

Each returns a new float32 :class:`~anatomesh.core.model.volume.Volume` (same geometry) with
``meta["smoothed"]`` saying what ran.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
from scipy import ndimage

from ..model.errors import AnatomeshError
from ..model.progress import Progress, report
from ..model.volume import Volume
from . import _diffusion_kernels as K

#: explicit diffusion steps use this fraction of the largest stable time step
STABILITY = 0.8
#: the conductance K is this percentile of the gradient magnitude (Perona and Malik 1990, after
#: Canny's noise estimator)
CONDUCTANCE_PERCENTILE = 90.0


def gaussian(volume: Volume, sigma_mm, truncate: float = 3.0) -> Volume:
    """Gaussian smoothing, ``sigma_mm`` (one value or one per axis i, j, k) in mm."""
    sigma = _per_axis(sigma_mm, "gaussian sigma", allow_zero=True) / np.asarray(volume.spacing)
    data = ndimage.gaussian_filter(_scalar(volume).astype(np.float32, copy=False), sigma,
                                   mode="nearest", truncate=truncate, output=np.float32)
    return _result(volume, data, {"filter": "gaussian", "sigma_mm": _list(sigma_mm),
                                  "sigma_voxels": _list(sigma)})


def median(volume: Volume, size_mm) -> Volume:
    """Median over a box ``size_mm`` wide (one value or per axis; mm): per axis the odd number
    of voxels nearest to it (at least 1)."""
    size = median_window(size_mm, volume.spacing)
    data = ndimage.median_filter(_scalar(volume), size=tuple(int(s) for s in size), mode="nearest")
    return _result(volume, data.astype(np.float32, copy=False),
                   {"filter": "median", "size_mm": _list(size_mm), "size_voxels": size.tolist()})


def median_window(size_mm, spacing) -> np.ndarray:
    """Odd window widths in voxels (int64 (3,)) for a box ``size_mm`` wide on ``spacing``."""
    n = np.maximum(1, np.round(_per_axis(size_mm, "median size") / np.asarray(spacing))).astype(np.int64)
    return n + (n % 2 == 0)


def diffusion(volume: Volume, iterations: int, conductance: Optional[float] = None,
              time_step: Optional[float] = None, progress: Optional[Progress] = None) -> Volume:
    """Perona–Malik anisotropic diffusion (explicit steps, 6 neighbours, spacing in mm).

    Parameters
    ----------
    iterations : int
        Number of steps (each a diffusion time ``time_step`` mm²: where the conductance is 1,
        ``n`` steps blur like a Gaussian of sigma ``sqrt(2 n time_step)`` mm).
    conductance : float, optional
        K in value units per mm: gradients well below K are smoothed, above it kept. Default: the
        90th percentile of the gradient magnitude (Perona and Malik 1990, after Canny).
    time_step : float, optional
        mm²; default :data:`STABILITY` x the largest stable step ``1 / sum(2 / h²)``.

    Returns a float32 Volume; ``meta["smoothed"]`` holds the parameters used.
    """
    if isinstance(iterations, bool) or int(iterations) != iterations or not 1 <= iterations <= 10000:
        raise AnatomeshError(f"diffusion needs a whole number of iterations in 1..10000, got {iterations!r}")
    h = np.asarray(volume.spacing, np.float64)
    limit = 1.0 / float(np.sum(2.0 / h**2))
    dt = STABILITY * limit if time_step is None else float(time_step)
    if not 0 < dt <= limit:
        raise AnatomeshError(f"diffusion time step must be in (0, {limit:.4g}] mm² for this spacing, got {dt}")
    u = np.array(_scalar(volume), dtype=np.float32, order="C")
    k = gradient_percentile(u, h) if conductance is None else float(conductance)
    if not k > 0:
        k = 1.0  # a constant volume: nothing to diffuse
    out = np.empty_like(u)
    inv_h, inv_h2 = 1.0 / h, 1.0 / h**2
    for it in range(int(iterations)):
        K.diffusion_step(u, out, inv_h, inv_h2, 1.0 / k**2, dt)
        u, out = out, u
        report(progress, (it + 1) / iterations, f"diffusion: step {it + 1}/{iterations}")
    return _result(volume, u, {"filter": "diffusion", "iterations": int(iterations),
                               "conductance": round(k, 4), "time_step_mm2": round(dt, 5),
                               "flat_sigma_mm": round(math.sqrt(2 * dt * iterations), 3)})


def gradient_percentile(u: np.ndarray, spacing, percentile: float = CONDUCTANCE_PERCENTILE,
                        sample: int = 2_000_000) -> float:
    """The ``percentile`` of the forward-difference gradient magnitude (value units per mm) over
    an evenly strided sample of about ``sample`` voxels."""
    step = max(1, int(round((u.size / sample) ** (1 / 3))))
    s = np.asarray(u[::step, ::step, ::step], np.float64)
    g = np.zeros(tuple(max(0, n - 1) for n in s.shape))
    if g.size == 0:
        return 0.0
    for axis in range(3):
        d = np.diff(s, axis=axis) / (spacing[axis] * step)
        g += d[tuple(slice(0, n) for n in g.shape)] ** 2
    return float(np.percentile(np.sqrt(g), percentile))


# ---------------------------------------------------------------------------------------------
def _scalar(volume: Volume) -> np.ndarray:
    if volume.is_label_map:
        raise AnatomeshError("volume smoothing blends values and is for scalar scans; for a label "
                             "map use --fuzzy-boundary or --interpolate")
    return volume.data


def _per_axis(value, what: str, allow_zero: bool = False) -> np.ndarray:
    v = np.asarray(value, np.float64).ravel()
    if v.size == 1:
        v = np.repeat(v, 3)
    ok = v.size == 3 and np.all(np.isfinite(v)) and (np.all(v >= 0) if allow_zero else np.all(v > 0))
    if not ok or not np.any(v > 0):
        raise AnatomeshError(f"{what} must be a distance in mm > 0 (one number or one per axis), got {value!r}")
    return v


def _list(x):
    return [round(float(v), 4) for v in np.atleast_1d(np.asarray(x, np.float64))]


def _result(volume: Volume, data: np.ndarray, info) -> Volume:
    meta = dict(volume.meta, smoothed=info)
    return Volume(data, np.array(volume.affine), volume.space, meta, None, list(volume.warnings))
