"""Numba kernel of :func:`anatomesh.core.preprocess.filters.diffusion`: one explicit step of
Perona–Malik anisotropic diffusion on a 6-neighbourhood with per-axis spacing.

``u_new = u + dt * sum_axes sum_{n = ±1} g(|u_n - u| / h) (u_n - u) / h²`` with the conductance
``g(s) = 1 / (1 + (s / K)²)`` (Perona and Malik 1990, "Scale-space and edge detection using
anisotropic diffusion", their second function: no exponential, so the step costs a few
multiply-adds per neighbour). At the border the missing neighbour is the voxel itself, so no flux
crosses it (Neumann). float32 throughout.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always", fastmath=True)
def _flux(d, inv_h, inv_h2, inv_k2):  # pragma: no cover - numba
    s = d * inv_h
    return d * inv_h2 / (np.float32(1.0) + s * s * inv_k2)


@njit(cache=True, parallel=True, nogil=True, fastmath=True)
def diffusion_step(u, out, inv_h, inv_h2, inv_k2, dt):  # pragma: no cover - numba
    """One step from ``u`` into ``out`` (both C-contiguous float32 (I, J, K)); ``inv_h`` and
    ``inv_h2`` are 1/h and 1/h² per axis (mm), ``inv_k2`` = 1/K² (K in value units per mm)."""
    ni, nj, nk = u.shape
    a0, a1, a2 = np.float32(inv_h[0]), np.float32(inv_h[1]), np.float32(inv_h[2])
    b0, b1, b2 = np.float32(inv_h2[0]), np.float32(inv_h2[1]), np.float32(inv_h2[2])
    k2, t = np.float32(inv_k2), np.float32(dt)
    for i in prange(ni):
        im, ip = max(i - 1, 0), min(i + 1, ni - 1)
        for j in range(nj):
            jm, jp = max(j - 1, 0), min(j + 1, nj - 1)
            for k in range(nk):
                km, kp = max(k - 1, 0), min(k + 1, nk - 1)
                c = u[i, j, k]
                acc = (_flux(u[im, j, k] - c, a0, b0, k2) + _flux(u[ip, j, k] - c, a0, b0, k2)
                       + _flux(u[i, jm, k] - c, a1, b1, k2) + _flux(u[i, jp, k] - c, a1, b1, k2)
                       + _flux(u[i, j, km] - c, a2, b2, k2) + _flux(u[i, j, kp] - c, a2, b2, k2))
                out[i, j, k] = c + t * acc
