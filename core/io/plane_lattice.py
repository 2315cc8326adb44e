"""Evenly spaced planes: the lattice ``t0 + n * step`` (n integer) that a set of plane positions
along a normal lies on, fitted from the exact positions (never from rounded ones), and how far
each plane lies off it. Shared by the DICOM SEG frame grid and the RTSTRUCT contour grid."""
from __future__ import annotations

from typing import Tuple

import numpy as np


def fitted_lattice(planes: np.ndarray, smallest: float) -> Tuple[float, float]:
    """(step, t0) mm of the least-squares lattice ``planes ≈ t0 + n * step``.

    ``planes`` (P,) float64 ascending positions along the normal, mm, P >= 2; ``smallest`` the
    approximate step (e.g. the smallest distance between planes) that numbers them:
    ``n = round((planes - planes[0]) / smallest)``. Exact positions give the exact step; jittered
    ones the step that keeps every plane closest to its lattice point."""
    n = np.round((planes - planes[0]) / smallest)
    step, t0 = np.polyfit(n, planes, 1)
    return float(step), float(t0)


def lattice_offsets(planes: np.ndarray, step: float) -> np.ndarray:
    """(P,) each plane's distance from the lattice of ``step`` that fits them best, as a fraction
    of ``step`` (0 = on the lattice, 0.5 = half-way between two lattice planes)."""
    k = (np.asarray(planes, np.float64) - planes[0]) / step
    frac = k - np.round(k)
    frac -= frac.mean()
    return np.abs(frac - np.round(frac))


__all__ = ["fitted_lattice", "lattice_offsets"]
