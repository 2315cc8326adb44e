"""Numba kernels for :mod:`anatomesh.core.geometry.measure` (private: no input checks here)."""
from __future__ import annotations

import math

from numba import njit

from .kernels import other_corners


# ---------------------------------------------------------------------------------------------
# curvature (Meyer, Desbrun, Schröder & Barr 2003) and triangle angles
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _angle(ax, ay, az, bx, by, bz):
    dot = ax * bx + ay * by + az * bz
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), dot)


@njit(cache=True)
def vertex_curvatures(v, faces, vf_offsets, vf, H, K, A):
    """Per vertex: mean curvature H (1/mm, > 0 convex), Gaussian curvature K (1/mm²) and the
    mixed Voronoi area A (mm²) of Meyer et al. 2003.

    ``K_vec = Σ (cot α_ij + cot β_ij)(x_i − x_j) / (2 A)``, ``H = K_vec · n / 2`` with n the
    area-weighted vertex normal; ``K = (2π − Σ θ_j) / A`` (angle deficit).
    """
    n = v.shape[0]
    for i in range(n):
        lx = 0.0
        ly = 0.0
        lz = 0.0
        nx = 0.0
        ny = 0.0
        nz = 0.0
        area = 0.0
        angles = 0.0
        for t in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[t]
            j, k = other_corners(faces, f, i)  # the face reads (i, j, k)
            eij = (v[j, 0] - v[i, 0], v[j, 1] - v[i, 1], v[j, 2] - v[i, 2])
            eik = (v[k, 0] - v[i, 0], v[k, 1] - v[i, 1], v[k, 2] - v[i, 2])
            ejk = (v[k, 0] - v[j, 0], v[k, 1] - v[j, 1], v[k, 2] - v[j, 2])
            ti = _angle(eij[0], eij[1], eij[2], eik[0], eik[1], eik[2])
            tj = _angle(-eij[0], -eij[1], -eij[2], ejk[0], ejk[1], ejk[2])
            tk = math.pi - ti - tj
            cx = eij[1] * eik[2] - eij[2] * eik[1]
            cy = eij[2] * eik[0] - eij[0] * eik[2]
            cz = eij[0] * eik[1] - eij[1] * eik[0]
            fa = 0.5 * math.sqrt(cx * cx + cy * cy + cz * cz)
            nx += cx
            ny += cy
            nz += cz
            angles += ti
            if fa <= 0.0:
                continue
            cotj = math.cos(tj) / max(math.sin(tj), 1e-12)
            cotk = math.cos(tk) / max(math.sin(tk), 1e-12)
            lij = eij[0] ** 2 + eij[1] ** 2 + eij[2] ** 2
            lik = eik[0] ** 2 + eik[1] ** 2 + eik[2] ** 2
            # (x_i - x_j) weighted by the cotangent of the angle opposite edge ij (at k), etc.
            lx -= cotk * eij[0] + cotj * eik[0]
            ly -= cotk * eij[1] + cotj * eik[1]
            lz -= cotk * eij[2] + cotj * eik[2]
            half_pi = 0.5 * math.pi
            if ti <= half_pi and tj <= half_pi and tk <= half_pi:
                area += (lij * cotk + lik * cotj) / 8.0
            elif ti > half_pi:
                area += fa / 2.0
            else:
                area += fa / 4.0
        A[i] = area
        if area > 0.0:
            ln = math.sqrt(nx * nx + ny * ny + nz * nz)
            hn = 0.0
            if ln > 0.0:
                hn = (lx * nx + ly * ny + lz * nz) / ln
            H[i] = hn / (2.0 * area) / 2.0
            K[i] = (2.0 * math.pi - angles) / area
        else:
            H[i] = 0.0
            K[i] = 0.0


@njit(cache=True)
def triangle_angles(v, faces, out):
    """Interior angles (radians) of each triangle, (M, 3) at its three corners."""
    for f in range(faces.shape[0]):
        for c in range(3):
            a = faces[f, c]
            b = faces[f, (c + 1) % 3]
            d = faces[f, (c + 2) % 3]
            out[f, c] = _angle(v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2],
                               v[d, 0] - v[a, 0], v[d, 1] - v[a, 1], v[d, 2] - v[a, 2])
