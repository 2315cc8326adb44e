"""The guards run after a smoothing filter: the fold guard and the volume step.

* :func:`unfold` — faces the filter turned over (or collapsed) get their vertices pulled back
  towards the start until none is;
* :func:`restore_volumes` — every region (a label of a SurfaceSet, a closed connected component
  of a mesh) gets its volume back by a small offset along the normals, inside the same
  constraint: thin structures (ribs, 2–3 voxel vessels) otherwise lose 15–80 % as their
  cross-sections round off (Bade, Haase & Preim 2006, "Comparison of fundamental mesh smoothing
  algorithms for medical surface models", measured the shrinkage of every classic filter).

The third guard, :func:`~anatomesh.core.smooth.untangle.untangle`, undoes crossings between faces.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from . import _filter_kernels as _fk
from . import _guard_kernels as _gk
from .checks import check_vertices, out_dtype
from .constraints import Constraint
from .prepare import constrain, finish, prepare
from ..geometry.neighbors import MeshStructure, check_faces
from ..model.errors import AnatomeshError


def unfold(vertices, start, faces, *, rounds: int = 10, eps: float = 1e-3) -> Tuple[np.ndarray, int]:
    """Undo folds: faces whose normal turned by 90° or more from ``start`` (or collapsed).

    Smoothing can fold slivers where junction curves cut a voxel corner. Each round, every vertex
    of a folded face moves halfway back to its start position (where nothing is folded); at most
    ``rounds`` rounds, then vertices of faces still folded go back to their start. Other vertices
    do not move, so seams stay shared and constraints hold (start positions satisfy them).

    Parameters
    ----------
    vertices, start : (N, 3) float, mm — smoothed and unsmoothed positions
    faces : (M, 3) int
    eps : a face counts as collapsed when ``n · n_start <= eps |n_start|²`` (n unnormalised)

    Returns ``(positions (N, 3) in the dtype of vertices, vertices moved back)``.
    """
    v = check_vertices(vertices)
    s0 = check_vertices(start)
    if s0.shape != v.shape:
        raise AnatomeshError(f"start must have the shape of vertices {v.shape}, got {s0.shape}")
    f = check_faces(faces, v.shape[0])
    dtype = out_dtype(vertices)
    if f.shape[0] == 0:
        return v.astype(dtype), 0
    fi = f.astype(np.int64)
    ref = np.cross(s0[fi[:, 1]] - s0[fi[:, 0]], s0[fi[:, 2]] - s0[fi[:, 0]])
    touched = np.zeros(v.shape[0], bool)
    for _ in range(int(rounds)):
        bad = _gk.folded(v, f, ref, float(eps))
        if not bad.any():
            break
        idx = np.unique(f[bad])
        touched[idx] = True
        v[idx] = 0.5 * (v[idx] + s0[idx])
    for _ in range(100):  # still folded after the halving rounds: back to the start
        bad = _gk.folded(v, f, ref, float(eps))
        if not bad.any():
            break
        idx = np.unique(f[bad])
        touched[idx] = True
        v[idx] = s0[idx]
    return v.astype(dtype, copy=False), int(touched.sum())



def region_volumes(vertices, faces, face_sides, n_regions: int) -> np.ndarray:
    """Volume (mm³) of each region enclosed by faces tagged (inside, outside) region ids.

    ``face_sides`` (M, 2) int: the face normal points from region ``[:, 0]`` to ``[:, 1]``;
    ids < 0 (background) are skipped. Exact for closed regions (divergence theorem).
    """
    v = check_vertices(vertices)
    f = check_faces(faces, v.shape[0])
    normals, areas, centroids = face_frames(v, f)
    return region_sums(tet_volumes(normals, areas, centroids, v), face_sides, n_regions)


def face_frames(v, f):
    m = f.shape[0]
    normals, areas, centroids = np.empty((m, 3)), np.empty(m), np.empty((m, 3))
    _fk.face_normals_areas(v, f, normals, areas, centroids)
    return normals, areas, centroids


def tet_volumes(normals, areas, centroids, v):
    """Signed volume of the tetrahedron (o, face) per face, o a fixed point: A (n · (c − o)) / 3."""
    o = v[0] if len(v) else np.zeros(3)
    return areas * np.einsum("ij,ij->i", normals, centroids - o) / 3.0


def region_sums(per_face, face_sides, n_regions):
    sides = np.asarray(face_sides, np.int64).reshape(-1, 2)
    out = np.zeros(n_regions)
    for col, sign in ((0, 1.0), (1, -1.0)):
        ok = sides[:, col] >= 0
        out += sign * np.bincount(sides[ok, col], per_face[ok], minlength=n_regions)[:n_regions]
    return out


def restore_volumes(vertices, faces, face_sides, targets, *, iterations: int = 3,
                    constraint: Optional[Constraint] = None, gain=None,
                    structure: Optional[MeshStructure] = None) -> np.ndarray:
    """Move surfaces along their normals so each region gets back its target volume.

    The volume-preserving step after smoothing: Taubin's filter keeps volume well on compact
    shapes, but thin ones (ribs, small vessels) shrink as their cross-sections round off. Each
    region ``r`` with a target gets an offset ``λ_r``; a face between regions ``r`` (inside) and
    ``s`` moves by ``λ_r − λ_s`` along its normal (``λ = 0`` for background and regions without
    target). The ``λ`` solve the small linear system (least-squares motion, the face areas
    as weights) that restores every volume to first order; vertices then move by the
    area-weighted mean of their faces' motions and are put back into their constraint. Repeated
    ``iterations`` times (volumes are typically restored to < 0.1 % unless the constraint binds).

    Parameters
    ----------
    vertices : (N, 3) float, mm
    faces : (M, 3) int
    face_sides : (M, 2) int — (inside, outside) region id per face, < 0 for background
    targets : (R,) float — target volume (mm³) per region id; NaN = free (like background)
    constraint, gain, structure : as for the filters (the constraint is re-applied every step)

    Returns (N, 3) positions, the dtype of ``vertices``.
    """
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                  iterations=iterations)
    f = st.s.faces
    tg = np.asarray(targets, np.float64).ravel()
    sides = np.asarray(face_sides, np.int64).reshape(-1, 2).copy()
    if sides.shape[0] != f.shape[0]:
        raise AnatomeshError(f"face_sides has {sides.shape[0]} rows for {f.shape[0]} faces")
    if sides.max(initial=-1) >= tg.size:
        raise AnatomeshError(f"face_sides name region {sides.max()} but only {tg.size} targets")
    free = ~np.isfinite(tg)
    sides[(sides >= 0) & free[np.maximum(sides, 0)]] = -1
    r = tg.size
    inside, outside = sides[:, 0], sides[:, 1]
    both = (inside >= 0) & (outside >= 0)
    pair = inside[both] * r + outside[both]
    buf = np.empty_like(st.pos)
    for _ in range(int(iterations)):
        normals, areas, centroids = face_frames(st.pos, f)
        dv = np.where(free, 0.0, tg - region_sums(tet_volumes(normals, areas, centroids, st.pos),
                                                   sides, r))
        # M λ = dv: M_rr = area of r's shell, M_rs = −(area between r and s)
        diag = np.zeros(r)
        for col in (inside, outside):
            ok = col >= 0
            diag += np.bincount(col[ok], areas[ok], minlength=r)[:r]
        active = diag > 0
        lam = np.zeros(r)
        if not both.any():  # no region touches another: M is diagonal
            lam[active] = dv[active] / diag[active]
        elif np.any(active):
            between = np.bincount(pair, areas[both], minlength=r * r).reshape(r, r)
            m = np.diag(diag) - between - between.T
            lam[active] = np.linalg.lstsq(m[np.ix_(active, active)], dv[active], rcond=None)[0]
        lam_ext = np.r_[lam, 0.0]  # index -1 → background
        t = lam_ext[inside] - lam_ext[outside]
        _gk.offset_update(st.pos, buf, st.s.vf_offsets, st.s.vf, normals, areas, t, st.gain)
        constrain(st, buf)
        st.pos, buf = buf, st.pos
    return finish(st)



def component_regions(s: MeshStructure):
    """Closed connected components as regions (inside = component, outside = background);
    a component with an open or non-manifold edge gets no region (−1)."""
    vlab = s.components()
    flab = vlab[s.faces[:, 0]] if s.n_faces else np.zeros(0, np.int64)
    n = int(vlab.max()) + 1 if vlab.size else 0
    _, _, kind = s.feature_ring(None)  # kind != 0: the vertex has an edge without two faces
    closed = np.ones(n, bool)
    closed[np.unique(vlab[kind != 0])] = False
    comp = np.where(closed[flab], flab, -1)
    return np.stack([comp, np.full_like(comp, -1)], axis=1), n
