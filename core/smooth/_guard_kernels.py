"""Numba kernels of the guards run after a filter (private to ``core/smooth``): the fold guard
and the volume step's offset along face normals."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._filter_kernels import FAST


@njit(parallel=True, fastmath=FAST, cache=True)
def folded(pos, faces, ref_normals, eps):
    """Faces whose normal (unnormalised) has turned by 90° or more from ``ref_normals``, or
    collapsed: ``n · n_ref <= eps |n_ref|²``. Faces with a zero reference normal never count."""
    m = faces.shape[0]
    out = np.zeros(m, np.bool_)
    for f in prange(m):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e1x, e1y, e1z = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
        e2x, e2y, e2z = pos[c, 0] - pos[a, 0], pos[c, 1] - pos[a, 1], pos[c, 2] - pos[a, 2]
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        rx, ry, rz = ref_normals[f, 0], ref_normals[f, 1], ref_normals[f, 2]
        r2 = rx * rx + ry * ry + rz * rz
        if r2 > 0.0 and nx * rx + ny * ry + nz * rz <= eps * r2:
            out[f] = True
    return out


@njit(parallel=True, fastmath=FAST, cache=True)
def offset_update(src, dst, vf_offsets, vf, normals, areas, t, gain):
    """Move each vertex by the area-weighted mean of its faces' offsets ``t_f`` along their unit
    normals: ``p' = p + Σ A_f t_f n_f / Σ A_f``, times the gain."""
    has_gain = gain.shape[0] > 0
    for i in prange(src.shape[0]):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        sa = 0.0
        for a in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[a]
            w = areas[f] * t[f]
            sx += w * normals[f, 0]
            sy += w * normals[f, 1]
            sz += w * normals[f, 2]
            sa += areas[f]
        px, py, pz = src[i, 0], src[i, 1], src[i, 2]
        if sa > 0.0:
            k = 1.0 / sa
            if has_gain:
                k *= gain[i]
            px, py, pz = px + k * sx, py + k * sy, pz + k * sz
        dst[i, 0] = px
        dst[i, 1] = py
        dst[i, 2] = pz
