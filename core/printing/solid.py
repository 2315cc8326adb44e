"""Is each part a clean solid: thin sliver faces, tiny loose shells, and parts crossing each other.

The crossing face pairs themselves are found by
:func:`anatomesh.core.geometry.intersections.crossing_pairs` (Möller 1997, "A fast
triangle-triangle intersection test", over a uniform grid); :func:`split_crossings` sorts them
into each part's self-intersections and the pairs of parts that cross. Closedness, manifoldness
and orientation come from :func:`anatomesh.core.geometry.topology.topology`, degenerate faces
from :func:`anatomesh.core.model.mesh.degenerate_faces`. Units are mm, mm², mm³, degrees.
"""
from __future__ import annotations

from typing import Dict, List, Sequence, Tuple

import numpy as np

from ..geometry.intersections import Crossings, crossing_pairs
from ..geometry.topology import component_measures
from ..model.mesh import Mesh, check_arrays
from .locate import location
from .profiles import SLIVER_ANGLE_DEG


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
    """Pairs of parts whose faces cross (shared seams excepted).

    Returns ``[{"a", "b" (names), "faces_a", "faces_b" (index arrays), "location"}]``."""
    parts = [check_arrays(m.vertices, m.faces) for m in meshes]
    return split_crossings(meshes, crossing_pairs(parts))[1]


def split_crossings(meshes: Sequence[Mesh], crossings: Crossings) -> Tuple[List[np.ndarray], List[Dict]]:
    """Sort the crossing face pairs of all parts together (:func:`crossing_pairs` of the parts in
    the order of ``meshes``) per part.

    Returns (per part its self-intersecting face pairs (K, 2) int64, local face indices;
    per crossing pair of parts ``{"a", "b" (names), "ia", "ib" (indices, ia < ib), "faces_a",
    "faces_b" (local face index arrays), "location" (mm)}``)."""
    v, f, part, offs_f, pairs = crossings
    self_pairs = [np.zeros((0, 2), np.int64) for _ in meshes]
    cross = []
    if pairs.shape[0] == 0:
        return self_pairs, cross
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
