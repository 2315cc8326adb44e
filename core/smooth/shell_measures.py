"""What smoothing did to each shell of a surface set, measured on the whole set at once.

The measures of :func:`anatomesh.core.geometry.measure.compare` per label shell — volume and area
before and after, largest vertex displacement, folded and degenerate faces, smallest angles,
topology, and the symmetric Hausdorff and mean distance to the unsmoothed shell — computed once
per face and per vertex of the set, then summed per label (a face counts for both labels on its
sides, inwards for the inside label, outwards for the outside one). The unsmoothed side (areas,
volumes, topology) is computed once, so measuring again after another smoothing costs a few face
passes. Distances are sampled at vertices and face centroids in both directions, each sample
measured to the faces around it in the other surface (a vertex: its faces; a centroid: its face
and the three across its edges)
(:func:`anatomesh.core.geometry.local_distance.distances_by_group`): upper bounds of the
nearest-triangle distances, equal to them wherever the nearest point lies on those faces, reduced
per label as they are measured (no per-sample arrays).
"""
from __future__ import annotations

from typing import Dict, List, Optional, Tuple

import numba
import numpy as np

from . import _shell_kernels as _k
from ..geometry.local_distance import distances_by_group
from ..geometry.kernels import union_find_roots
from ..geometry.neighbors import MeshStructure, vertex_faces
from ..model.mesh import Mesh
from ..model.surfaceset import SurfaceSet

_TOPO_KEYS = ("components", "genus", "closed", "manifold", "oriented", "degenerate_faces")
#: the per-face measures summed per label: area, signed volume, flipped, degenerate,
#: smallest angle, angle below 10°, 1 (the face count); True: negated on the outside label
_SIGNED = np.array([False, True, False, False, False, False, False])
#: faces measured at a time (memory: a (7, block) table, not (7, M))
_BLOCK = 1 << 16


def label_sides(surfaces: SurfaceSet) -> Tuple[np.ndarray, List[int]]:
    """``(sides (M, 2) int32, values)``: the index in ``values`` (``surfaces.values()``, the
    labels with faces) of the label on each side of every face, −1 for the background."""
    values = surfaces.values()
    index = np.full(max(values + [surfaces.background, 0]) + 1, -1, np.int32)
    index[np.asarray(values, np.int64)] = np.arange(len(values))
    return np.ascontiguousarray(index[surfaces.face_labels]), values


def shell_key(value) -> int:
    """The report key of a shell: its value, an int when whole."""
    key = 0 if value is None else value
    return int(key) if float(key).is_integer() else float(key)


class ShellMeasures:
    """The per-shell measures of one surface set against its unsmoothed positions.

    Parameters
    ----------
    surfaces : SurfaceSet — the unsmoothed set
    rest : (N, 3) float64 — its positions, mm
    structure : MeshStructure of its faces
    """

    def __init__(self, surfaces: SurfaceSet, rest: np.ndarray, structure: MeshStructure):
        self.surfaces, self.rest, self.s = surfaces, rest, structure
        self.sides, self.values = label_sides(surfaces)
        self.origin = rest[0] if len(rest) else np.zeros(3)
        self.before = self._sums(rest)[0]
        self._topology: Optional[List[dict]] = None
        self._by_label: Optional[Tuple[np.ndarray, np.ndarray]] = None

    def _sums(self, pos: np.ndarray, angles: bool = False) -> Tuple[np.ndarray, np.ndarray]:
        """The per-label sums (L, 7) float64 of the face measures at ``pos`` (rows: see
        ``_SIGNED``), in face order, and, when ``angles``, each face's smallest angle (M,)
        float64 (degrees). Memory: the per-face table is filled and summed a block of faces at
        a time."""
        m = self.s.n_faces
        out, angle = np.zeros((len(self.values), 7)), np.empty(m if angles else 0)
        table = np.empty((7, min(m, _BLOCK)))
        for lo in range(0, m, _BLOCK):
            hi = min(lo + _BLOCK, m)
            _k.face_measures(pos, self.s.faces[lo:hi], self.origin, self.rest, table, angles)
            _k.label_sums(self.sides[lo:hi], table, _SIGNED, out)
            if angles:
                angle[lo:hi] = table[4, :hi - lo]
        return out, angle

    def topology_before(self) -> List[dict]:
        """Per shell: components, genus, closed, manifold, oriented, degenerate faces of the
        unsmoothed shell, as :func:`anatomesh.core.geometry.topology.topology` gives them; cached.
        All shells at once: their meshes side by side, edges counted around each vertex."""
        if self._topology is None:
            self._topology = shell_topology(self.surfaces.shells(), self.before[:, 3])
        return self._topology

    def measure(self, after: np.ndarray, *, distances: bool = True, topology: bool = True) -> Dict:
        """Per shell value, the measures of :func:`anatomesh.core.geometry.measure.compare`
        (without curvature) at float64 positions ``after``. ``topology=False``: the topology
        entries hold only ``degenerate_faces`` (smoothing moves vertices, never the faces:
        the rest cannot change), saving the per-shell topology pass."""
        now, angle = self._sums(after, angles=True)
        angles = self._angle_stats(angle)
        del angle  # memory: the distances below need their own per-face samples
        worst_disp = np.empty(len(self.values))
        _k.label_max_displacement(self.sides, self.s.faces, after, self.rest, worst_disp)
        dist = self._distances(after) if distances else None
        out = {}
        topologies = self.topology_before() if topology else \
            [{"degenerate_faces": int(d)} for d in self.before[:, 3]]
        for k, (value, topo) in enumerate(zip(self.values, topologies)):
            out[self._key(value)] = self._shell(k, now[k], worst_disp[k], angles[:, k], topo, dist)
        return out

    def _key(self, value: int):
        return shell_key(self.surfaces.shell_values.get(value, value))

    def _shell(self, k, now, worst_disp, angles, topo, dist) -> dict:
        b = self.before[k]
        n = max(now[6], 1.0)
        r = {"faces": int(now[6]), "volume_before_mm3": float(b[1]),
             "volume_after_mm3": float(now[1]),
             "volume_change_pct": 100.0 * (now[1] - b[1]) / abs(b[1]) if b[1] else 0.0,
             "area_before_mm2": float(b[0]), "area_after_mm2": float(now[0]),
             "max_displacement_mm": float(worst_disp)}
        if dist is not None:
            r["hausdorff_mm"] = float(dist[0][k])
            r["mean_distance_mm"] = float(dist[1][k] / max(dist[2][k], 1))
        r["quality_after"] = {"min_angle_deg": float(angles[0]),
                              "p01_min_angle_deg": float(angles[1]),
                              "mean_min_angle_deg": float(now[4] / n),
                              "fraction_below_10deg": float(now[5] / n)}
        r["flipped_faces"] = int(now[2])
        after = dict(topo, degenerate_faces=int(now[3]))
        r["topology_before"], r["topology_after"] = dict(topo), after
        r["topology_changed"] = [key for key in _TOPO_KEYS if topo.get(key) != after.get(key)]
        return r

    def _angle_stats(self, angle: np.ndarray) -> np.ndarray:
        """(2, shells): the smallest face angle and its 1st percentile in each shell."""
        if self._by_label is None:  # the faces of each label, in face order
            self._by_label = _k.faces_by_label(self.sides, len(self.values))
        faces, starts = self._by_label
        out = np.zeros((2, len(self.values)))
        for k in range(len(self.values)):
            part = angle[faces[starts[k]:starts[k + 1]]]  # a copy: the percentile may reorder it
            if part.size:
                out[0, k], out[1, k] = part.min(), np.percentile(part, 1, overwrite_input=True)
        return out

    def _distances(self, after: np.ndarray):
        """Per label: the worst sample, the sum of samples and their count, both directions."""
        return distances_by_group(after, self.rest, self.s, self.sides, len(self.values))


def shell_topology(shells: List[Mesh], degenerate: np.ndarray) -> List[dict]:
    """Topology of every shell (components, genus, closed, manifold, oriented; ``degenerate``
    faces given), as :func:`anatomesh.core.geometry.topology.topology` gives it, for all shells
    at once: their meshes side by side, edges and fans counted around each vertex, components by
    union-find."""
    sizes = np.array([m.n_vertices for m in shells], np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    faces = np.concatenate([m.faces.astype(np.int64) + o for m, o in zip(shells, offsets)] or
                           [np.zeros((0, 3), np.int64)])
    n = int(offsets[-1])
    vf_offsets, vf = vertex_faces(faces, n)
    most = int(np.diff(vf_offsets).max(initial=1))
    stats = np.zeros((n, 5), np.int64)
    _k.vertex_stats(faces, vf_offsets, vf, stats,
                    np.empty((numba.get_num_threads(), 5 * most), np.int64))
    roots = union_find_roots(np.r_[faces[:, 0], faces[:, 1]], np.r_[faces[:, 1], faces[:, 2]], n)
    used = np.diff(vf_offsets) > 0
    shell = np.repeat(np.arange(len(shells)), sizes)
    k = len(shells)
    per = [np.bincount(shell, stats[:, j], minlength=k).astype(np.int64) for j in range(4)]
    pinched = np.bincount(shell, stats[:, 4] > 1, minlength=k)
    ncomp = np.bincount(shell, used & (roots == np.arange(n)), minlength=k).astype(np.int64)
    nused = np.bincount(shell, used, minlength=k).astype(np.int64)
    out = []
    for i, m in enumerate(shells):
        closed = per[1][i] == 0 and per[2][i] == 0 and m.n_faces > 0
        manifold = per[2][i] == 0 and pinched[i] == 0
        euler = int(nused[i] - per[0][i] + m.n_faces)
        c = int(ncomp[i])
        genus = (2 * c - euler) // 2 if closed and manifold and (2 * c - euler) % 2 == 0 else None
        out.append({"components": c, "genus": genus, "closed": bool(closed),
                    "manifold": bool(manifold), "oriented": bool(per[3][i] == 0),
                    "degenerate_faces": int(degenerate[i])})
    return out


def shell_warnings(label: str, r: dict, volume_warning_pct: float) -> List[str]:
    """The warning lines of one shell's measures."""
    out = []
    if abs(r["volume_change_pct"]) > volume_warning_pct:
        out.append(f"{label}: volume changed by {r['volume_change_pct']:+.1f} %")
    if r["flipped_faces"]:
        out.append(f"{label}: {r['flipped_faces']} faces folded over by smoothing")
    if r["topology_changed"]:
        out.append(f"{label}: {', '.join(r['topology_changed'])} changed by smoothing")
    return out
