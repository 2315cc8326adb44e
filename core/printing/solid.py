"""Is each part a clean solid: thin sliver faces, tiny loose shells, and parts crossing each other.

The crossing face pairs themselves are found by
:func:`anatomesh.core.geometry.intersections.crossing_pairs` (Möller 1997, "A fast
triangle-triangle intersection test", over a uniform grid); :func:`split_crossings` sorts them
into each part's self-intersections and the pairs of parts that cross. Closedness, manifoldness
and orientation come from :func:`anatomesh.core.geometry.topology.topology`, degenerate faces
from :func:`anatomesh.core.model.mesh.degenerate_faces`. Units are mm, mm², mm³, degrees.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..geometry.intersections import Crossings, crossing_pairs
from ..geometry.spatial import TriangleGrid
from ..geometry.topology import component_measures
from ..model.mesh import Mesh, check_arrays
from .locate import location
from .profiles import CONTACT_MM, SLIVER_ANGLE_DEG

#: where a face is probed for reaching into another part: its corners, edge midpoints, centroid
#: (barycentric weights)
_PROBES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5],
                    [1 / 3, 1 / 3, 1 / 3]])


def sliver_faces(vertices: np.ndarray, faces: np.ndarray, min_angle_deg: float = SLIVER_ANGLE_DEG):
    """Faces whose smallest angle is below ``min_angle_deg``: (indices (K,) int64, angles (K,) deg).

    Degenerate faces (zero area) have angle 0 and are included."""
    v, f = check_arrays(vertices, faces)
    if f.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    p = v[f]
    ang = np.empty((f.shape[0], 3))
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        cr = np.linalg.norm(np.cross(a, b), axis=1)
        ang[:, k] = np.degrees(np.arctan2(cr, np.einsum("ij,ij->i", a, b)))
    amin = ang.min(1)
    idx = np.flatnonzero(~(amin >= min_angle_deg))
    return idx, amin[idx]


def tiny_shells(vertices: np.ndarray, faces: np.ndarray, min_volume_mm3: float) -> List[Dict]:
    """Connected components enclosing less than ``min_volume_mm3`` (absolute volume).

    Returns ``[{"faces": index array, "volume_mm3", "area_mm2", "location"}]``, smallest first;
    uses :func:`anatomesh.core.geometry.topology.component_measures`."""
    v, f = check_arrays(vertices, faces)
    out = []
    if f.shape[0] == 0:
        return out
    for comp in component_measures(v, f):
        vol = abs(comp["volume_mm3"])
        if vol < min_volume_mm3:
            loc = location(v[f[comp["faces"]].ravel()])
            out.append({"faces": comp["faces"], "volume_mm3": vol, "area_mm2": comp["area_mm2"],
                        "location": loc})
    out.sort(key=lambda d: d["volume_mm3"])
    return out


def part_intersections(meshes: Sequence[Mesh]) -> List[Dict]:
    """Pairs of parts whose faces cross (shared seams and faces that only touch excepted, see
    :func:`touching_pairs`).

    Returns ``[{"a", "b" (names), "faces_a", "faces_b" (index arrays), "location"}]``."""
    parts = [check_arrays(m.vertices, m.faces) for m in meshes]
    grids = [TriangleGrid(v, f) if len(f) else None for v, f in parts]
    return split_crossings(meshes, crossing_pairs(parts), grids)[1]


def split_crossings(meshes: Sequence[Mesh], crossings: Crossings,
                    grids: Optional[Sequence[Optional[TriangleGrid]]] = None
                    ) -> Tuple[List[np.ndarray], List[Dict]]:
    """Sort the crossing face pairs of all parts together (:func:`crossing_pairs` of the parts in
    the order of ``meshes``) per part. With ``grids`` (one per part, of its own vertices and
    faces), pairs of faces of two parts that only touch (:func:`touching_pairs`) are left out.

    Returns (per part its self-intersecting face pairs (K, 2) int64, local face indices;
    per crossing pair of parts ``{"a", "b" (names), "ia", "ib" (indices, ia < ib), "faces_a",
    "faces_b" (local face index arrays), "location" (mm)}``)."""
    v, f, part, offs_f, pairs = crossings
    self_pairs = [np.zeros((0, 2), np.int64) for _ in meshes]
    cross = []
    if pairs.shape[0] == 0:
        return self_pairs, cross
    if grids is not None:
        pairs = pairs[~touching_pairs(crossings, grids)]
    pa, pb = part[pairs[:, 0]], part[pairs[:, 1]]
    same = pa == pb
    for i in np.unique(pa[same]):
        sel = pairs[same & (pa == i)]
        self_pairs[i] = sel - offs_f[i]
    diff = ~same
    if np.any(diff):
        a = np.minimum(pa[diff], pb[diff])
        b = np.maximum(pa[diff], pb[diff])
        fa = np.where(pa[diff] == a, pairs[diff, 0], pairs[diff, 1])
        fb = np.where(pa[diff] == a, pairs[diff, 1], pairs[diff, 0])
        keys = a * len(meshes) + b
        for k in np.unique(keys):
            sel = keys == k
            i, j = int(k // len(meshes)), int(k % len(meshes))
            faces_all = np.r_[fa[sel], fb[sel]]
            cross.append({"a": meshes[i].name or str(i), "b": meshes[j].name or str(j),
                          "ia": i, "ib": j,
                          "faces_a": np.unique(fa[sel]) - offs_f[i],
                          "faces_b": np.unique(fb[sel]) - offs_f[j],
                          "location": location(v[f[faces_all].ravel()])})
    return self_pairs, cross


def touching_pairs(crossings: Crossings, grids: Sequence[Optional[TriangleGrid]]) -> np.ndarray:
    """(K,) bool over ``crossings.pairs``: pairs of faces of two different parts that touch
    without crossing: two parts whose shared interface is triangulated differently on each side
    (around the pins and pockets of :mod:`.connectors`, whose drilling refines each side on its
    own), the mouth of a pocket's wall meeting the pin part's interface face.

    Two faces touch when neither reaches more than :data:`.profiles.CONTACT_MM` into the other
    part (probed at its corners, edge midpoints and centroid: distance to the other part's
    surface, inside it by ray parity) and, where they lie in one plane, their outward normals
    are opposite (the parts on either side of it; with the same normal one part lies inside the
    other). ``grids`` has one :class:`~anatomesh.core.geometry.spatial.TriangleGrid` per part, of
    that part's own vertices and faces; pairs within one part are never touching here."""
    v, f, part, offs_f, pairs = crossings
    out = np.zeros(len(pairs), bool)
    if pairs.shape[0] == 0:
        return out
    pa, pb = part[pairs[:, 0]], part[pairs[:, 1]]
    cand = np.flatnonzero(pa != pb)
    deep = np.zeros(len(pairs), bool)
    for mine, other in ((0, 1), (1, 0)):  # the faces of one side probed into the other's part
        target = part[pairs[cand, other]]
        for j in np.unique(target):
            sel = cand[target == j]
            deep[sel] |= _reaches_into(v[f[pairs[sel, mine]]], grids[j])
    tri_a, tri_b = v[f[pairs[cand, 0]]], v[f[pairs[cand, 1]]]
    na, nb = _unit_normals(tri_a), _unit_normals(tri_b)
    flat = (np.abs(np.einsum("kij,kj->ki", tri_b - tri_a[:, :1], na)).max(1) <= CONTACT_MM) & \
           (np.abs(np.einsum("kij,kj->ki", tri_a - tri_b[:, :1], nb)).max(1) <= CONTACT_MM)
    same_side = flat & (np.einsum("kj,kj->k", na, nb) > 0)
    out[cand] = ~deep[cand] & ~same_side
    return out


def _reaches_into(tri: np.ndarray, grid: Optional[TriangleGrid]) -> np.ndarray:
    """(K,) bool: triangles ``tri`` (K, 3, 3) mm with a probe point (:data:`_PROBES`) inside the
    part of ``grid`` farther than :data:`.profiles.CONTACT_MM` from its surface."""
    if grid is None or len(tri) == 0:
        return np.zeros(len(tri), bool)
    pts = np.einsum("pc,kcj->kpj", _PROBES, tri).reshape(-1, 3)
    d, _, _ = grid.closest(pts, max_distance=2 * CONTACT_MM)
    off = np.flatnonzero(~(d <= CONTACT_MM))
    inside = np.zeros(len(pts), bool)
    if off.size:
        inside[off] = grid.contains(pts[off])
    return inside.reshape(len(tri), len(_PROBES)).any(axis=1)


def _unit_normals(tri: np.ndarray) -> np.ndarray:
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
