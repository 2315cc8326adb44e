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
from .checks import check_vertices, mesh_structure, out_dtype
from .constraints import Constraint
from .prepare import finish, prepare
from ..geometry.neighbors import MeshStructure, check_faces
from ..model.errors import AnatomeshError


def unfold(vertices, start, faces, *, rounds: int = 10, eps: float = 1e-3,
           structure: Optional[MeshStructure] = None) -> Tuple[np.ndarray, int]:
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
    structure : the faces' neighbourhoods, if already built

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
    s = mesh_structure(f, v.shape[0], structure)
    moved = unfold_in_place(v, s0, s, rounds, eps)
    return v.astype(dtype, copy=False), moved


def folded_faces(pos: np.ndarray, start: np.ndarray, s: MeshStructure,
                 eps: float = 1e-3, among: Optional[np.ndarray] = None) -> np.ndarray:
    """The faces :func:`unfold` finds folded, (K,) int64: ``pos`` (N, 3) float64, or float32
    read as float64 (the same faces as on its float64 copy, without making it). ``among``
    (L,) int: check only these faces."""
    if among is None:
        return np.flatnonzero(_gk.folded(pos, start, s.faces, float(eps)))
    among = np.asarray(among, np.int64)
    return among[_gk.folded(pos, start, np.ascontiguousarray(s.faces[among]), float(eps))]


def unfold_in_place(pos: np.ndarray, start: np.ndarray, s: MeshStructure,
                    rounds: int = 10, eps: float = 1e-3,
                    touched: Optional[np.ndarray] = None, bad: Optional[np.ndarray] = None) -> int:
    """:func:`unfold` on float64 (N, 3) ``pos``, in place (no checks); returns the vertices
    moved, and marks them in ``touched`` (N,) bool if given (all False on entry). After the
    first full scan (none when its result ``bad`` of :func:`folded_faces` is given) only faces
    around moved vertices are checked again."""
    bad = folded_faces(pos, start, s, eps) if bad is None else bad
    if bad.size == 0:
        return 0
    if touched is None:
        touched = np.zeros(pos.shape[0], np.bool_)
    _gk.unfold_rounds(pos, start, s.faces, float(eps), s.vf_offsets, s.vf, bad,
                      int(rounds), touched)
    return int(touched.sum())


def region_volumes(vertices, faces, face_sides, n_regions: int) -> np.ndarray:
    """Volume (mm³) of each region enclosed by faces tagged (inside, outside) region ids.

    ``face_sides`` (M, 2) int: the face normal points from region ``[:, 0]`` to ``[:, 1]``;
    ids < 0 (background) are skipped. Exact for closed regions (divergence theorem).
    """
    v = check_vertices(vertices)
    f = check_faces(faces, v.shape[0])
    regions = VolumeRegions(f, face_sides, np.zeros(n_regions))
    return regions.volumes(v)[0]


class VolumeRegions:
    """The regions of :func:`restore_volumes`, with everything that does not depend on the
    positions (region ids per face, which targets are free) and working buffers, built once.

    Parameters
    ----------
    faces : (M, 3) int32
    face_sides : (M, 2) int — (inside, outside) region id per face, < 0 for background
    targets : (R,) float — target volume (mm³) per region; NaN = free (like background)
    """

    def __init__(self, faces: np.ndarray, face_sides, targets):
        tg = np.asarray(targets, np.float64).ravel()
        sides = np.asarray(face_sides).reshape(-1, 2)
        if sides.shape[0] != faces.shape[0]:
            raise AnatomeshError(f"face_sides has {sides.shape[0]} rows for {faces.shape[0]} faces")
        if sides.max(initial=-1) >= tg.size:
            raise AnatomeshError(f"face_sides name region {sides.max()} but only {tg.size} targets")
        self.free = ~np.isfinite(tg)
        self.faces, self.targets, self.r = faces, tg, tg.size
        self.inside = _region_ids(sides[:, 0], self.free)
        self.outside = _region_ids(sides[:, 1], self.free)
        self.touching = bool(np.any((self.inside >= 0) & (self.outside >= 0)))
        self.areas: Optional[np.ndarray] = None  # per-face working buffers, made on use
        self.tet: Optional[np.ndarray] = None
        self.between = np.zeros((self.r, self.r) if self.touching else (1, 1))
        self.missing = np.zeros(self.r)  # target − volume at the last offsets (0: free)

    def volumes(self, pos: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """``(volume (R,) mm³, shell area (R,) mm²)`` of every region at float64 ``pos``; fills
        the face normals and areas, and the areas shared by two regions (``between``)."""
        origin = pos[0] if len(pos) else np.zeros(3)
        if self.areas is None:
            self.areas, self.tet = np.empty(self.faces.shape[0]), np.empty(self.faces.shape[0])
        _gk.face_terms(pos, self.faces, origin, self.areas, self.tet)
        volume, diag = np.zeros(self.r), np.zeros(self.r)
        _gk.region_terms(self.inside, self.outside, self.areas, self.tet, volume, diag,
                         self.between, self.touching)
        return volume, diag

    def release_buffers(self) -> None:
        """Drop the per-face working buffers (16 bytes a face; made again by :meth:`volumes`)."""
        self.areas = self.tet = None

    def offsets(self, pos: np.ndarray) -> np.ndarray:
        """The offset λ (R + 1,) of every region (last: background, 0) that restores the
        target volumes to first order; see :func:`restore_volumes`."""
        volume, diag = self.volumes(pos)
        dv = np.where(self.free, 0.0, self.targets - volume)
        self.missing = dv
        active = diag > 0  # M λ = dv: M_rr = area of r's shell, M_rs = −(area between r and s)
        lam = np.zeros(self.r + 1)
        if not self.touching:
            lam[:-1][active] = dv[active] / diag[active]
        elif np.any(active):
            m = np.diag(diag) - self.between - self.between.T
            lam[:-1][active] = _solve(m[np.ix_(active, active)], dv[active])
        return lam

    def restore(self, pos: np.ndarray, s: MeshStructure, cons: tuple, gain: np.ndarray,
                iterations: int = 3, tol: Optional[float] = None) -> np.ndarray:
        """:func:`restore_volumes` on float64 ``pos``; ``cons``: the constraint's kernel
        arrays (:meth:`Constraint.arrays`), ``gain`` (N,) or empty; ``tol``: stop early once
        every region is within this fraction of its target. Returns the new positions
        (``pos`` or a buffer)."""
        buf = np.empty_like(pos)
        for _ in range(int(iterations)):
            lam = self.offsets(pos)  # also the face areas at pos
            if tol is not None and np.all(np.abs(self.missing) <= tol * np.abs(self.targets)):
                break
            _gk.vertex_moves(pos, buf, self.faces, s.vf_offsets, s.vf, self.areas, lam,
                             self.inside, self.outside, gain)
            if cons[0] != 0 or cons[4] < np.inf:
                _fk.constrain_all(buf, *cons)
            pos, buf = buf, pos
        return pos


def _region_ids(side: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(M,) int32 region ids of one side of the faces, −1 for background and free regions."""
    ids = side.astype(np.int32)
    ids[(ids < 0) | free[np.maximum(ids, 0)]] = -1
    return ids


def _solve(m: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``m x = b`` for the small (R, R) symmetric system of the volume offsets: Cholesky when
    ``m`` is positive definite (every cluster of touching regions reaches the background), else
    least squares. Gaussian elimination in a numba kernel, not LAPACK: BLAS threads woken next
    to numba's own cost far more per call than the solve itself."""
    x = _gk.solve_spd(np.ascontiguousarray(m, np.float64), np.ascontiguousarray(b, np.float64))
    if np.all(np.isfinite(x)):
        return x
    return np.linalg.lstsq(m, b, rcond=None)[0]


def restore_volumes(vertices, faces, face_sides, targets, *, iterations: int = 3,
                    constraint: Optional[Constraint] = None, gain=None,
                    structure: Optional[MeshStructure] = None,
                    regions: Optional[VolumeRegions] = None) -> np.ndarray:
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
    regions : the :class:`VolumeRegions` of these faces, sides and targets, if already built

    Returns (N, 3) positions, the dtype of ``vertices``.
    """
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                 iterations=iterations)
    if regions is None:
        regions = VolumeRegions(st.s.faces, face_sides, targets)
    st.pos = regions.restore(st.pos, st.s, st.cons, st.gain, iterations)
    return finish(st)


def component_regions(s: MeshStructure):
    """Closed connected components as regions (inside = component, outside = background);
    a component with an open or non-manifold edge gets no region (−1)."""
    vlab = s.components()
    flab = vlab[s.faces[:, 0]] if s.n_faces else np.zeros(0, np.int64)
    n = int(vlab.max()) + 1 if vlab.size else 0
    closed = np.ones(n, bool)
    closed[np.unique(vlab[s.open_vertices()])] = False
    comp = np.where(closed[flab], flab, -1).astype(np.int32)
    return np.stack([comp, np.full_like(comp, -1)], axis=1), n
