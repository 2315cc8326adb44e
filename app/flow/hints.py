"""Hints ``anatomesh inspect`` gives before meshing: which preprocessing the scan calls for.

* thick slices (slice spacing at least :data:`ANISOTROPY` x the in-plane spacing): label maps
  → ``--interpolate`` (the staircase of thick slices), scalar scans → ``--resample``;
* noisy CT (robust noise estimate in soft tissue above :data:`NOISE_HU`): ``--smooth-volume``;
* large scans (more than :data:`LARGE_VOXELS` voxels): ``--roi``.
"""
from __future__ import annotations

from typing import List

import numpy as np

from ...core.io.describe import looks_like_hounsfield
from ...core.model.volume import Volume

ANISOTROPY = 2.0
NOISE_HU = 25.0
LARGE_VOXELS = 150_000_000


def hints(volume: Volume) -> List[str]:
    """One line per suggestion (possibly none)."""
    out = []
    sp = np.asarray(volume.spacing)
    thick, fine = float(sp.max()), float(sp.min())
    if thick >= ANISOTROPY * fine:
        what = "--interpolate (shape-based, to isotropic voxels)" if volume.is_label_map else \
            f"--resample {fine:.3g} (isotropic; --resample-method cubic for the smoothest surfaces)"
        out.append(f"slices {thick:.3g} mm apart ({thick / fine:.1f}x the in-plane {fine:.3g} mm): "
                   f"consider {what}")
    if not volume.is_label_map:
        sigma = noise_hu(volume)
        if sigma is not None and sigma > NOISE_HU:
            out.append(f"noise about {sigma:.0f} HU in soft tissue: consider --smooth-volume "
                       "diffusion:10 (edge-preserving) or gaussian:1")
    if int(np.prod(volume.shape)) > LARGE_VOXELS:
        out.append(f"{int(np.prod(volume.shape)):,} voxels: consider --roi X0,Y0,Z0,X1,Y1,Z1 (mm) to "
                   "mesh a region only")
    return out


def noise_hu(volume: Volume):
    """Robust noise of a CT in HU: 1.4826 x the median absolute difference between in-plane
    neighbours that both lie in soft tissue (-100..200 HU), divided by sqrt(2); None when the
    scan is not in HU or has too little soft tissue."""
    data = np.asarray(volume.data)
    flat = np.ravel(data, order="K")
    if not looks_like_hounsfield(flat[:: max(1, flat.size // 1_000_000)]):
        return None
    k = max(1, data.shape[2] // 16)
    planes = np.asarray(data[:, :, ::k], np.float64)
    a, b = planes[:-1], planes[1:]
    soft = (a > -100) & (a < 200) & (b > -100) & (b < 200)
    if soft.sum() < 1000:
        return None
    d = (a - b)[soft]
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))
