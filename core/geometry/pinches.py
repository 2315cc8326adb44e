"""Pinch points resolved in geometry: shells that stay 2-manifold when read back by position.

Where a label touches itself along a voxel edge or at a voxel corner (two parts of an organ
meeting there, or the background touching itself inside it), its shell is made 2-manifold by
*vertex copies*: one vertex per fan of faces around the point
(:class:`~anatomesh.core.model.surfaceset.SurfaceSet`, ``splits``). In the set every fan sits at
the one position of its vertex. Files such as STL carry no vertex identity, and every reader
(slicers, admesh, trimesh, Blender's merge by distance) joins vertices by position: the fans
would fuse into a non-manifold edge or vertex again.

The rule: at every pinch point, the fans that must part move :func:`pinch_gap_mm` apart
(:func:`pinch_moves`). Fans of different labels that share faces move together, so their seam
stays one surface; each moving fan goes into its own cone, away from the point's other fans,
along the first direction that makes no face cross. Where two labels alternate around an edge
(a checkerboard), their fans cannot move together: each copy then moves into its own label's
material, which opens a gap of at most the pinch gap between the labels there, never an overlap.
A shell is then 2-manifold by position, with the components the shell view counts (parts that
touch only at a pinch point are separate). The gap is under every printer's resolution (a
slicer prints both parts as touching) and over the merge distances of slicers and mesh tools
(CuraEngine melds vertices within 0.03 mm; PrusaSlicer, admesh, trimesh and Blender merge exact
positions). The same rule serves display and print.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List

import numpy as np

from ..model.mesh import Mesh
from . import _pinch_kernels as _k
from .kernels import union_find_roots

#: How far a moving fan goes from its pinch point, mm ...
PINCH_GAP_MM = 0.05
#: ... and never more than this fraction of the smallest voxel spacing (fine grids).
PINCH_GAP_VOXELS = 0.1
#: coplanarity tolerance of the crossing test, relative to the triangles' size
_REL_EPS = 1e-9
#: the rule as the report states it
RULE = ("at a point or edge where a structure touches itself, the touching parts' vertices "
        "are moved apart by the gap, each into its own side")


@dataclass
class PinchMoves:
    """Where the fans of a set's pinch points go. ``keys`` (K,) int64 packs (label, vertex,
    copy) as ``(label * n_vertices + vertex) * 16 + copy``, sorted; ``offsets`` (K, 3) float32
    mm; ``points`` pinch vertices, ``moved`` fans moved, ``crossing`` moves for which every
    direction crossed a face, ``checkerboards`` groups whose fans moved one by one."""

    keys: np.ndarray
    offsets: np.ndarray
    n_vertices: int
    gap_mm: float
    points: int = 0
    moved: int = 0
    crossing: int = 0
    checkerboards: int = 0

    def summary(self) -> Dict[str, object]:
        """The report's ``pinch_points`` entry."""
        return {"points": self.points, "moved_fans": self.moved, "crossing": self.crossing,
                "checkerboards": self.checkerboards, "gap_mm": round(self.gap_mm, 4), "rule": RULE}


def pinch_gap_mm(affine: np.ndarray) -> float:
    """The gap for a voxel → mm ``affine`` (4, 4): the smaller of :data:`PINCH_GAP_MM` and
    :data:`PINCH_GAP_VOXELS` of the smallest voxel spacing (mm)."""
    spacing = np.sqrt((np.asarray(affine, np.float64)[:3, :3] ** 2).sum(axis=0))
    return float(min(PINCH_GAP_MM, PINCH_GAP_VOXELS * spacing.min()))


def pinch_moves(surfaces, gap_mm: float) -> PinchMoves:
    """The moves that resolve every pinch point of a
    :class:`~anatomesh.core.model.surfaceset.SurfaceSet` (see the module docstring).

    Fans are found from the set's ``splits``: at a vertex with a copy in some label's shell, every
    label's fan there is an *instance* (label, vertex, copy); the two sides of a face at the
    vertex tie their instances into a *group*; a group with two fans of one label is a
    checkerboard. Runs in time linear in the faces, plus a few triangle tests per pinch point.
    """
    n = surfaces.n_vertices
    empty = PinchMoves(np.zeros(0, np.int64), np.zeros((0, 3), np.float32), n, float(gap_mm))
    sp = surfaces.splits
    if not len(sp):
        return empty
    pinch = np.zeros(n, bool)
    pinch[surfaces.faces[sp[:, 0], sp[:, 2]]] = True
    pf = np.flatnonzero(pinch[surfaces.faces].any(axis=1))
    keys, slot_inst = _instances(surfaces, pf, pinch)
    inst_slots, s_off = _csr(slot_inst, np.arange(slot_inst.size), keys.size)
    both = slot_inst.reshape(-1, 2)
    tied = (both >= 0).all(axis=1)
    group = union_find_roots(both[tied, 0], both[tied, 1], keys.size)
    groups, inst_group = np.unique(group, return_inverse=True)
    label, vertex, copy = keys // 16 // n, keys // 16 % n, keys % 16
    span = int(label.max()) + 1  # one label per fan of a group, or a checkerboard
    labels_in = np.bincount(np.unique(inst_group * span + label) // span, minlength=groups.size)
    separable = labels_in == np.bincount(inst_group, minlength=groups.size)
    g_members, g_off = _by(inst_group, groups.size)
    g_vertex = vertex[g_members[g_off[:-1]]]
    v_keys, v_index = np.unique(g_vertex, return_inverse=True)
    v_groups, v_off = _by(v_index, v_keys.size)
    corners = np.ascontiguousarray(surfaces.faces[pf], np.int64)
    disp, crossing = _k.move_fans(corners, (inst_slots, s_off, g_members, g_off), copy, separable,
                                  v_off, v_groups, _near_faces(surfaces, pf, float(gap_mm)),
                                  float(gap_mm), _REL_EPS)
    moved = np.any(disp != 0, axis=1)
    return PinchMoves(keys[moved], disp[moved].astype(np.float32), n, float(gap_mm),
                      points=int(v_keys.size), moved=int(moved.sum()), crossing=int(crossing),
                      checkerboards=int((~separable).sum()))


def apply_moves(vertices: np.ndarray, vertex_ids: np.ndarray, copies: np.ndarray, label: int,
                moves: PinchMoves) -> np.ndarray:
    """The positions (N, 3) float32 of one label's shell (or Blender object) with ``moves``
    applied: vertex i shows set vertex ``vertex_ids[i]`` as copy ``copies[i]``
    (:func:`copy_numbers`)."""
    out = np.array(vertices, np.float32, order="C")
    if not moves.keys.size:
        return out
    keys = (int(label) * moves.n_vertices + np.asarray(vertex_ids, np.int64)) * 16 + copies
    at = np.minimum(np.searchsorted(moves.keys, keys), moves.keys.size - 1)
    hit = moves.keys[at] == keys
    out[hit] += moves.offsets[at[hit]]
    return out


def copy_numbers(vertex_ids: np.ndarray) -> np.ndarray:
    """(N,) int64: 0 for the first vertex with its id, 1, 2, ... for the later ones (a shell
    view lists a vertex's copies after it, in the order of their numbers; a Blender object keeps
    its shell's order)."""
    ids = np.asarray(vertex_ids, np.int64)
    order = np.argsort(ids, kind="stable")
    s = ids[order]
    start = np.r_[0, np.flatnonzero(s[1:] != s[:-1]) + 1] if s.size else np.zeros(0, np.int64)
    run = np.repeat(start, np.diff(np.r_[start, s.size]))
    out = np.empty(ids.size, np.int64)
    out[order] = np.arange(s.size) - run
    return out


def separate_shells(surfaces, meshes: List[Mesh], gap_mm: float) -> Dict[str, object]:
    """Resolve the pinch points of ``surfaces``'s shell views ``meshes`` in place (each with
    ``meta["vertex_ids"]``; ``meta`` gains ``pinch_points``: its fans moved). Returns the
    report's ``pinch_points`` entry (:meth:`PinchMoves.summary`)."""
    moves = pinch_moves(surfaces, gap_mm)
    label = moves.keys // 16 // max(moves.n_vertices, 1)
    for m in meshes:
        ids = m.meta.get("vertex_ids")
        if ids is None:
            continue
        value = shell_label(surfaces, m)
        m.meta["pinch_points"] = int(np.count_nonzero(label == value))
        if m.meta["pinch_points"]:
            m.vertices = apply_moves(m.vertices, ids, copy_numbers(ids), value, moves)
    return moves.summary()


def shell_label(surfaces, mesh: Mesh) -> int:
    """The set label a shell shows (its ``value``, or the level's label for an isosurface set)."""
    for label, value in surfaces.shell_values.items():
        if value == mesh.value:
            return int(label)
    return int(mesh.value)


def _instances(surfaces, pf: np.ndarray, pinch: np.ndarray):
    """``(keys (I,) sorted, slot_inst (P * 6,))``: the instances at the pinch vertices, and the
    instance of every slot ``6 p + 2 k + s`` of the pinch faces ``pf`` (-1: not at a pinch
    vertex, or the background's side)."""
    n = surfaces.n_vertices
    corner_v = surfaces.faces[pf].astype(np.int64)                     # (P, 3)
    lab = surfaces.face_labels[pf].astype(np.int64)                    # (P, 2)
    copy = np.zeros((pf.size, 3, 2), np.int64)
    sp = surfaces.splits
    row = np.searchsorted(pf, sp[:, 0])
    copy[row, sp[:, 2], sp[:, 1]] = sp[:, 3]
    key = (lab[:, None, :] * n + corner_v[:, :, None]) * 16 + copy     # (P, 3, 2)
    valid = pinch[corner_v][:, :, None] & (lab[:, None, :] != surfaces.background)
    keys, inv = np.unique(key[valid], return_inverse=True)
    slot_inst = np.full(key.shape, -1, np.int64)
    slot_inst[valid] = inv.ravel()
    return keys, slot_inst.ravel()


def _near_faces(surfaces, pf: np.ndarray, gap_mm: float):
    """The kernels' ``near`` tuple (see :mod:`._pinch_kernels`): the faces in the cells around
    every pinch vertex's, for the crossing test."""
    pos = np.ascontiguousarray(surfaces.vertices)
    size = _longest_edge(pos, surfaces.faces[pf]) + 2.0 * gap_mm
    lo, hi = pos.min(axis=0).astype(np.float64), pos.max(axis=0).astype(np.float64)
    base = float(np.ceil((hi - lo).max() / size) + 4)
    grid = np.array([lo[0], lo[1], lo[2], size, base])
    points = np.unique(surfaces.faces[surfaces.splits[:, 0], surfaces.splits[:, 2]])
    cells = np.floor((pos[points] - lo) / size).astype(np.int64)
    steps = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)])
    around = (cells[:, None, :] + steps[None]).reshape(-1, 3) + 1
    near = np.zeros(int(base) ** 3, bool)
    near[(around[:, 0] * int(base) + around[:, 1]) * int(base) + around[:, 2]] = True
    none = np.zeros(0, np.int64)
    n = _k.candidate_cells(pos, surfaces.faces, grid, near, none, none)
    face, key = np.empty(n, np.int64), np.empty(n, np.int64)
    _k.candidate_cells(pos, surfaces.faces, grid, near, face, key)
    order = np.argsort(key, kind="stable")
    face, key = face[order], key[order]
    at = np.minimum(np.searchsorted(pf, face), pf.size - 1)
    cand_pinch = np.where(pf[at] == face, at, -1).astype(np.int64)
    real = surfaces.face_labels[pf] != surfaces.background
    cand = np.ascontiguousarray(surfaces.faces[face], np.int64)
    boxes = np.empty((cand.shape[0], 6), pos.dtype)
    _k.face_boxes(pos, cand, boxes)
    cell_keys, starts = np.unique(key, return_index=True)
    cell_off = np.append(starts, key.size).astype(np.int64)
    return (pos, cand, cand_pinch, cell_keys, cell_off, grid, real, boxes)


def _longest_edge(pos: np.ndarray, faces: np.ndarray) -> float:
    """The longest edge of ``faces`` (mm)."""
    longest = 0.0
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = pos[faces[:, a]] - pos[faces[:, b]]
        longest = max(longest, float(np.sqrt((d * d).sum(axis=1)).max(initial=0.0)))
    return longest


def _csr(key: np.ndarray, items: np.ndarray, n: int):
    """``items`` grouped by ``key`` (-1 left out): ``(values, offsets (n + 1,))`` int64."""
    keep = key >= 0
    order = np.argsort(key[keep], kind="stable")
    values = items[keep][order].astype(np.int64)
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(key[keep], minlength=n), out=offsets[1:])
    return values, offsets


def _by(key: np.ndarray, n: int):
    """Indices 0..len(key)-1 grouped by ``key`` in 0..n-1: ``(values, offsets)``."""
    return _csr(np.asarray(key, np.int64), np.arange(len(key)), n)
