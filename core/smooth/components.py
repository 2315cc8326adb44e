"""The component guard: smoothing keeps the volume of every connected component of every shell.

The volume step (:func:`~anatomesh.core.smooth.guards.restore_volumes`) gives each *label* its
volume back. A label made of an organ and a few single-voxel specks gets it back almost wholly on
the organ, while a speck — whose eight corners may all move to the voxel's centre, inside their
cells — is flattened into a sliver (1e-6 of a voxel), and a cavity of one or two voxels closes.
The guard measures every component of every label's shell (the components of
``SurfaceSet.shell(value)``, its pinch copies included: two voxels touching along an edge are two
components; a cavity is a component of negative volume) against its unsmoothed volume and holds
each within a bound, ``|V − V_raw| <= bound · |V_raw|``:

1. the components outside the bound get their own volume regions, restored by the volume step's
   offsets along the normals inside the same constraint
   (:class:`~anatomesh.core.smooth.guards.VolumeRegions`; only the failing components' vertices
   move, shared ones by the area-weighted mean of their faces, so seams stay shared) — on the
   faces around them only, never the whole set; components that share faces are restored in
   turn (one of each touching pair a round: a speck inside another label and that label's
   cavity around it are the same faces);
2. a component still outside is blended back toward its unsmoothed positions,
   ``p = p_raw + t (p − p_raw)`` for its vertices (a vertex of several such components takes
   the smallest ``t``), ``t`` found by bisection until the component is within half the bound
   (``t = 0`` gives its raw volume exactly), so the bound always holds.

Every raw component of a label map encloses a whole number of voxels, so with the default bound
(10 %) no component ends below 0.9 voxel. Both steps move vertices only inside their constraint
boxes (the restore re-applies the constraint; a blend is a convex combination of two positions in
the box). The taxonomy of smoothing's shrinkage is Bade, Haase & Preim 2006, "Comparison of
fundamental mesh smoothing algorithms for medical surface models"; the cells are Gibson 1998,
"Constrained elastic surface nets".
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from . import _component_kernels as _ck
from .guards import VolumeRegions, component_regions, folded_faces, unfold_in_place
from .untangle import faces_around
from ..geometry.neighbors import MeshStructure
from ..model.errors import AnatomeshError
from ..model.surfaceset import SurfaceSet

#: The default bound, percent of each component's unsmoothed volume.
DEFAULT_BOUND_PCT = 10.0
#: Bisection steps of the blend factor (resolution 2⁻¹²).
BLEND_STEPS = 12
#: Rounds of bisected blends before components still outside go straight back to raw.
BLEND_ROUNDS = 4


def check_bound(bound_pct) -> Optional[float]:
    """The bound as a fraction (None: the guard is off); ``bound_pct`` in (0, 100) percent."""
    if bound_pct is None:
        return None
    b = float(bound_pct)
    if not 0.0 < b < 100.0:
        raise AnatomeshError(f"component_bound_pct must be in (0, 100) percent or None (off), "
                             f"got {bound_pct}")
    return b / 100.0


def shell_component_sides(surfaces: SurfaceSet, s: MeshStructure) -> Tuple[np.ndarray, int]:
    """``(sides (M, 2) int32, C)``: the component of every face side within its label's shell.

    A label map's set: the components of each ``surfaces.shell(value)`` (faces joined through
    shared shell vertices, a split copy being a vertex of its own), found on the set's faces
    without building the shells; ids numbered by their first face side, −1 on background sides.
    Independent surfaces: their closed connected components (open ones get −1: no volume)."""
    if surfaces.lattice is None:
        sides, n = component_regions(s)
        return np.ascontiguousarray(sides, np.int32), int(n)
    parent = np.empty(2 * s.n_faces, np.int32)
    _ck.union_shell_sides(s.faces, surfaces.face_labels, np.int32(surfaces.background),
                          s.vf_offsets, s.vf, split_copies(surfaces.splits, s.n_faces), parent)
    n = _ck.number_components(parent, surfaces.face_labels, np.int32(surfaces.background))
    return parent.reshape(-1, 2), int(n)


def split_copies(splits: np.ndarray, n_faces: int) -> np.ndarray:
    """The split copies of a set packed per face, (M,) uint32: bits ``4 k .. 4 k + 3`` with
    ``k = 3 side + corner`` hold the copy (0–15; 0: the shared vertex) that corner of the face
    uses in the shell of the label on that side, from ``splits`` (S, 4) rows (face, side,
    corner, copy)."""
    out = np.zeros(n_faces, np.uint32)
    sp = np.asarray(splits, np.int64).reshape(-1, 4)
    if sp.size:
        if int(sp[:, 3].max()) > 15 or int(sp[:, 3].min()) < 1:
            raise AnatomeshError("split copies must be in 1..15")
        np.bitwise_or.at(out, sp[:, 0], (sp[:, 3] << (4 * (3 * sp[:, 1] + sp[:, 2]))).astype(np.uint32))
    return out


class ComponentGuard:
    """The components of a set's shells and their unsmoothed volumes, built once.

    Parameters
    ----------
    surfaces : SurfaceSet — the unsmoothed set
    rest : (N, 3) float64 — its positions, mm
    structure : MeshStructure of its faces

    Attributes
    ----------
    sides : (M, 2) int32 — component of each face side (:func:`shell_component_sides`)
    n : int — components
    targets : (C,) float64 — their unsmoothed signed volumes, mm³ (cavities negative)
    """

    def __init__(self, surfaces: SurfaceSet, rest: np.ndarray, structure: MeshStructure):
        self.s, self.rest = structure, rest
        self.sides, self.n = shell_component_sides(surfaces, structure)
        self.origin = rest[0].copy() if len(rest) else np.zeros(3)
        self._targets: Optional[np.ndarray] = None

    @property
    def targets(self) -> np.ndarray:
        """The unsmoothed signed volumes (C,) float64 mm³ (measured with the first
        :meth:`volumes` call, in the same pass)."""
        if self._targets is None:
            self._targets = self.volumes(self.rest)
        return self._targets

    def volumes(self, pos: np.ndarray) -> np.ndarray:
        """Signed volume (C,) float64 mm³ of every component at ``pos`` (N, 3) float32/64."""
        out = np.zeros(self.n)
        if self._targets is None and pos is not self.rest:
            self._targets = np.zeros(self.n)
            _ck.component_volumes_pair(pos, self.rest, self.s.faces, self.sides, self.origin,
                                       out, self._targets)
        else:
            _ck.component_volumes(pos, self.s.faces, self.sides, self.origin, out)
        return out

    def failing(self, pos: np.ndarray, bound: float) -> np.ndarray:
        """The components (K,) int64 whose volume at ``pos`` is outside ``bound`` (fraction)."""
        return self.outside(self.volumes(pos), bound)

    def outside(self, volumes: np.ndarray, bound: float) -> np.ndarray:
        """The components (K,) int64 whose ``volumes`` (C,) mm³ are outside ``bound``."""
        return np.flatnonzero(np.abs(volumes - self.targets) > bound * np.abs(self.targets))

    def guard(self, pos: np.ndarray, cons: tuple, gain: np.ndarray, bound: float,
              fold_guard: bool = True) -> Tuple[set, set]:
        """Hold every component within ``bound`` (fraction) at float64 ``pos`` (N, 3), in
        place: restore the failing ones, then blend back those still outside (module
        docstring). ``cons``: the constraint's kernel arrays; ``gain`` (N,) or empty. Returns
        the components that were outside the bound and the ones among them blended back."""
        vol = self.volumes(pos)
        fail = self.outside(vol, bound)
        if fail.size == 0:
            return set(), set()
        seen, tried = set(fail.tolist()), np.zeros(self.n, np.bool_)
        for _ in range(4):  # touching failing components take turns
            todo = fail[~tried[fail]]
            if todo.size == 0:
                break
            chosen = self.independent(todo)
            tried[chosen] = True
            vol = self.moved(pos, vol, chosen, fold_guard, lambda around: self.restore(
                pos, chosen, around, cons, gain, 0.1 * bound))
            fail = self.outside(vol, bound)
            seen.update(fail.tolist())
        blended, rounds = set(), 0
        while fail.size and rounds <= BLEND_ROUNDS + self.n:  # a blend moves shared vertices
            blended.update(fail.tolist())
            exact = rounds >= BLEND_ROUNDS  # then straight back: ends when all are raw
            vol = self.moved(pos, vol, fail, fold_guard and not exact,
                             lambda _: self.blend(pos, fail, bound, exact))
            fail, rounds = self.outside(vol, bound), rounds + 1
        return seen, blended

    def around(self, ids: np.ndarray) -> np.ndarray:
        """The faces (K,) int64, ascending, with a corner on a face of components ``ids``:
        every face that moving those components' vertices changes."""
        mark = np.zeros(self.n, np.bool_)
        mark[ids] = True
        s = self.s
        return _ck.faces_around(s.faces, _ck.faces_of(self.sides, mark), s.vf_offsets, s.vf,
                                s.n_faces)

    def part_volumes(self, pos: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """What the faces ``faces`` (K,) add to each component's volume (C,) mm³ at ``pos``."""
        out = np.zeros(self.n)
        _ck.component_volumes(pos, self.s.faces[faces], self.sides[faces], self.origin, out)
        return out

    def moved(self, pos, volumes, ids, fold_guard: bool, move) -> np.ndarray:
        """Run ``move(around)``, which moves only vertices of faces of components ``ids``
        (``around``: :meth:`around`), then the fold guard on those faces; returns ``volumes``
        (C,) updated by what changed there (all measured again if the fold guard moved a
        vertex with a face elsewhere)."""
        around = self.around(ids)
        volumes = volumes - self.part_volumes(pos, around)
        move(around)
        if fold_guard:
            bad = folded_faces(pos, self.rest, self.s, among=around)
            if bad.size:
                touched = np.zeros(len(pos), np.bool_)
                unfold_in_place(pos, self.rest, self.s, bad=bad, touched=touched)
                inside = np.zeros(self.s.n_faces, np.bool_)
                inside[around] = True
                if not np.all(inside[faces_around(self.s, np.flatnonzero(touched))]):
                    return self.volumes(pos)
        return volumes + self.part_volumes(pos, around)

    def independent(self, ids: np.ndarray) -> np.ndarray:
        """The components (K,) int64 of ``ids`` that share no face with a larger one of
        ``ids`` (their volume regions would be coupled: a speck inside another label and that
        label's cavity around it are the same faces); the others wait for the next round."""
        mark = np.zeros(self.n, np.bool_)
        mark[ids] = True
        drop = _ck.losers(self.sides, mark, np.abs(self.targets))
        return ids[~drop[ids]]

    def _local(self, faces: np.ndarray, ids: np.ndarray):
        """The faces ``faces`` (K,) as a small mesh: ``(vertices (n,) int64 global ids, local
        faces (K, 3) int32, local sides (K, 2) int32: index in ``ids``, −1 for the others)."""
        verts, local = np.unique(self.s.faces[faces], return_inverse=True)
        rid = np.full(self.n + 1, -1, np.int32)  # index −1 → the last entry: none
        rid[ids] = np.arange(ids.size, dtype=np.int32)
        return verts, local.reshape(-1, 3).astype(np.int32), rid[self.sides[faces]]

    def restore(self, pos: np.ndarray, ids: np.ndarray, around: np.ndarray, cons: tuple,
                gain: np.ndarray, tol: float, iterations: int = 30) -> None:
        """Give components ``ids`` (sharing no face) their unsmoothed volume with the volume
        step's offsets, on the faces ``around`` them only (:meth:`around`), in place on float64
        ``pos``: at most ``iterations`` steps, until each is within ``tol`` (fraction) of it (a
        vertex shared with faces of other components moves by the mean of all its faces' moves,
        so a speck on an organ's surface needs several steps)."""
        verts, faces, sides = self._local(around, ids)
        regions = VolumeRegions(faces, sides, self.targets[ids])
        kind, center, frame, frame_inv, radius, start = cons
        local_cons = (kind, center[verts] if len(center) else center, frame, frame_inv, radius,
                      start[verts])
        pos[verts] = regions.restore(np.ascontiguousarray(pos[verts]),
                                     MeshStructure(faces, verts.size), local_cons,
                                     gain[verts] if len(gain) else gain, iterations, tol)

    def blend(self, pos: np.ndarray, ids: np.ndarray, bound: float,
              exact: bool = False) -> np.ndarray:
        """Blend components ``ids`` back toward the unsmoothed positions: ``p = rest + t (pos −
        rest)`` with ``t`` per component found by bisection (``exact``: ``t = 0``) so its volume
        is within half of ``bound``, a vertex of several taking the smallest ``t``. In place on
        ``pos`` (float32 or float64); returns the vertices (n,) int64 it moved."""
        mark = np.zeros(self.n, np.bool_)
        mark[ids] = True
        verts, faces, sides = self._local(_ck.faces_of(self.sides, mark), ids)
        r, p1 = self.rest[verts], pos[verts].astype(np.float64)
        target = self.targets[ids]
        tol = 0.5 * bound * np.abs(target)

        def at(t):
            factor = _ck.vertex_factors(faces, sides, t, verts.size)
            p = r + factor[:, None] * (p1 - r)
            vol = np.zeros(ids.size)
            _ck.component_volumes(p, faces, sides, self.origin, vol)
            return p, np.abs(vol - target) <= tol

        lo, hi = np.zeros(ids.size), np.ones(ids.size)
        for _ in range(0 if exact else BLEND_STEPS):
            mid = 0.5 * (lo + hi)
            ok = at(mid)[1]
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        for _ in range(ids.size + 1):  # shared vertices: a neighbour's t can undo one's check
            p, ok = at(lo)
            if ok.all():
                break
            lo[~ok] = 0.0
        pos[verts] = p
        return verts
