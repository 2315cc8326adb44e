"""The marching-cubes case table, generated from a fixed face rule (not typed in).

Why generate it: the classic 15-class table of Lorensen and Cline (1987) is inconsistent on
ambiguous faces — two cells sharing a face may cut it differently and leave holes (Dürst 1988,
"Letters: additional reference to marching cubes"). Here every case is built from the same rule applied to each cube face, so both
cells that share a face cut it with the *same* segments and the surface is closed and 2-manifold
wherever it does not leave the grid (the idea behind VTK's full 256-case table, Schroeder et al.
2001; the face rule is a fixed "separate the above corners" choice, like Nielson and Hamann's
asymptotic decider with the saddle always below the level).

Conventions (the kernels in :mod:`._mc_kernels` rely on them)
---------------------------------------------------------------
* Axes ``x, y, z`` of the cell frame; ``x`` is the contiguous axis the kernels sweep.
* Corner ``c = dx + 2*dy + 4*dz``; case bit ``c`` is set when that corner is *above* the level
  (``value >= level``).
* Edges: x-edges ``dy + 2*dz`` (0..3), y-edges ``4 + dx + 2*dz`` (4..7), z-edges
  ``8 + dx + 2*dy`` (8..11).
* Triangles are counter-clockwise seen from the *below* side: their right-hand normal points out
  of the region above the level (along the negative gradient).

Construction of one case
------------------------
1. On each of the 6 faces, walking its corners counter-clockwise seen from outside the cube, every
   maximal run of above corners is cut off by one segment from the crossing where the walk enters
   the run to the crossing where it leaves it. On an ambiguous face (above corners on a diagonal)
   this separates the above corners. The segment has the below side on its left seen from outside,
   which makes its direction opposite in the two cells sharing the face.
2. Every crossed edge lies on two faces, where it starts one segment and ends another, so the
   segments link into closed directed loops.
3. Each loop is triangulated as a disk. Among all its triangulations we keep those whose diagonals
   never join two points on a common cube face (the neighbouring cell could draw the same segment
   → an edge with three triangles) and take the one with the largest minimum angle, measured with
   the points at edge midpoints.

:func:`check_table` asserts the properties (each crossed edge in exactly one loop, each face
segment used once, orientation against the trilinear interpolant, no forbidden diagonal); the
tests run it; building the table at import asserts that loops close and that every loop
has an allowed triangulation.
"""
from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

#: corner positions in the unit cell, (8, 3) int: corner c = dx + 2*dy + 4*dz
CORNERS = np.array([(c & 1, (c >> 1) & 1, (c >> 2) & 1) for c in range(8)], dtype=np.int64)


def _edge_corners() -> np.ndarray:
    e = []
    for dz in (0, 1):  # x-edges, index dy + 2*dz
        for dy in (0, 1):
            c0 = 2 * dy + 4 * dz
            e.append((c0, c0 + 1))
    for dz in (0, 1):  # y-edges, index 4 + dx + 2*dz
        for dx in (0, 1):
            c0 = dx + 4 * dz
            e.append((c0, c0 + 2))
    for dy in (0, 1):  # z-edges, index 8 + dx + 2*dy
        for dx in (0, 1):
            c0 = dx + 2 * dy
            e.append((c0, c0 + 4))
    return np.array(e, dtype=np.int64)


#: (12, 2) corner pair of each edge, lower corner (smaller coordinate) first
EDGE_CORNERS = _edge_corners()
#: (12,) axis of each edge (0 = x, 1 = y, 2 = z)
EDGE_AXIS = np.repeat(np.arange(3), 4)
#: (12, 3) edge midpoints in the unit cell
EDGE_MIDPOINTS = (CORNERS[EDGE_CORNERS[:, 0]] + CORNERS[EDGE_CORNERS[:, 1]]) / 2.0


def _faces() -> List[Tuple[np.ndarray, List[int], List[int]]]:
    """Each face: (outward normal, corners counter-clockwise seen from outside, edge after each corner)."""
    faces = []
    for axis in range(3):
        for side in (0, 1):
            normal = np.zeros(3)
            normal[axis] = 2 * side - 1
            corners = [c for c in range(8) if CORNERS[c, axis] == side]
            centre = CORNERS[corners].mean(axis=0)
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            w = np.cross(normal, u)  # (u, w, normal) right-handed: angle grows counter-clockwise
            ang = [np.arctan2((CORNERS[c] - centre) @ w, (CORNERS[c] - centre) @ u) for c in corners]
            ring = [corners[i] for i in np.argsort(ang)]
            edges = [_edge_of(ring[i], ring[(i + 1) % 4]) for i in range(4)]
            faces.append((normal, ring, edges))
    return faces


def _edge_of(c0: int, c1: int) -> int:
    lo, hi = min(c0, c1), max(c0, c1)
    for e, (a, b) in enumerate(EDGE_CORNERS):
        if a == lo and b == hi:
            return e
    raise ValueError(f"corners {c0} and {c1} share no edge")


#: the 6 faces: (outward normal, corner ring counter-clockwise from outside, ring edges)
FACES = _faces()
#: (12, 2) the two faces each edge lies on
EDGE_FACES = np.array([[f for f, (_, _, ring) in enumerate(FACES) if e in ring] for e in range(12)])


def above(case: int, corner: int) -> bool:
    return bool((case >> corner) & 1)


def face_segments(case: int) -> List[Tuple[int, int, int]]:
    """Directed contour segments ``(face, from_edge, to_edge)`` of one case on all 6 faces."""
    segs = []
    for f, (_, ring, edges) in enumerate(FACES):
        s = [above(case, c) for c in ring]
        for i in range(4):
            # corner i starts an above run if it is above and its predecessor is below
            if s[i] and not s[i - 1]:
                j = i
                while s[(j + 1) % 4]:
                    j = (j + 1) % 4
                segs.append((f, edges[i - 1], edges[j]))  # enter through edge (i-1, i), leave (j, j+1)
    return segs


def case_loops(case: int) -> List[List[int]]:
    """The closed contour loops of one case, each a list of edge indices in loop order."""
    nxt: Dict[int, int] = {}
    for _, a, b in face_segments(case):
        assert a not in nxt, f"case {case}: edge {a} starts two segments"
        nxt[a] = b
    assert sorted(nxt) == sorted(nxt.values()), f"case {case}: segments do not close"
    loops, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop, e = [], start
        while e not in seen:
            seen.add(e)
            loop.append(e)
            e = nxt[e]
        assert e == start, f"case {case}: loop does not return to its start"
        loops.append(loop)
    return loops


def _polygon_triangulations(k: int) -> List[List[Tuple[int, int, int]]]:
    """All triangulations of a convex k-gon with vertices 0..k-1 (triangles keep the order)."""
    if k not in _TRIANGULATIONS:
        _TRIANGULATIONS[k] = list(_triangulations(tuple(range(k))))
    return _TRIANGULATIONS[k]


_TRIANGULATIONS: Dict[int, List[List[Tuple[int, int, int]]]] = {}


def _triangulations(idx: Tuple[int, ...]):
    if len(idx) < 3:
        yield []
        return
    a, b = idx[0], idx[-1]
    for m in range(1, len(idx) - 1):  # apex of the triangle on side (a, b)
        for left in _triangulations(idx[: m + 1]):
            for right in _triangulations(idx[m:]):
                yield left + right + [(a, idx[m], b)]


#: (12, 12) bool: the two edges lie on a common cube face
SHARE_FACE = np.array([[bool(set(EDGE_FACES[a]) & set(EDGE_FACES[b])) for b in range(12)]
                       for a in range(12)])


def _min_angles() -> np.ndarray:
    """(12, 12, 12) smallest angle (radians) of the triangle on three edge midpoints."""
    p = EDGE_MIDPOINTS
    a, b, c = np.meshgrid(np.arange(12), np.arange(12), np.arange(12), indexing="ij")
    out = np.full(a.shape, np.pi)
    with np.errstate(invalid="ignore", divide="ignore"):
        for u, v, w in ((a, b, c), (b, c, a), (c, a, b)):
            d1, d2 = p[v] - p[u], p[w] - p[u]
            lengths = np.linalg.norm(d1, axis=-1) * np.linalg.norm(d2, axis=-1)
            cosang = np.einsum("...i,...i", d1, d2) / lengths
            ang = np.arccos(np.clip(np.nan_to_num(cosang, nan=1.0), -1.0, 1.0))
            out = np.minimum(out, ang)
    return out


_MIN_ANGLE = _min_angles()


def triangulate_loop(loop: List[int]) -> List[Tuple[int, int, int]]:
    """Triangles (edge indices, loop orientation kept) for one loop; see the module docstring."""
    k = len(loop)
    best, best_score = None, -1.0
    for tris in _polygon_triangulations(k):
        ok = True
        score = np.pi
        for t in tris:
            for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                if (b - a) % k not in (1, k - 1) and SHARE_FACE[loop[a], loop[b]]:
                    ok = False
            score = min(score, _MIN_ANGLE[loop[t[0]], loop[t[1]], loop[t[2]]])
        if ok and score > best_score + 1e-12:
            best, best_score = tris, score
    assert best is not None, f"loop {loop}: no triangulation without a face diagonal"
    return [(loop[a], loop[b], loop[c]) for a, b, c in best]


def case_triangles(case: int) -> List[Tuple[int, int, int]]:
    """All triangles of one case as edge-index triples."""
    tris = []
    for loop in case_loops(case):
        tris.extend(triangulate_loop(loop))
    return tris


def build_table():
    """The lookup arrays the kernels use.

    Returns
    -------
    tri_count : (256,) int64, triangles per case
    tri_edges : (256, 3 * max_tris) int64, edge index triples (−1 padded)
    edge_mask : (256,) int64, bit e set when edge e is crossed
    """
    all_tris = [case_triangles(c) for c in range(256)]
    max_tris = max(len(t) for t in all_tris)
    tri_count = np.array([len(t) for t in all_tris], dtype=np.int64)
    tri_edges = np.full((256, 3 * max_tris), -1, dtype=np.int64)
    for c, tris in enumerate(all_tris):
        if tris:
            tri_edges[c, : 3 * len(tris)] = np.array(tris).ravel()
    edge_mask = np.zeros(256, dtype=np.int64)
    for c in range(256):
        for e, (c0, c1) in enumerate(EDGE_CORNERS):
            if above(c, c0) != above(c, c1):
                edge_mask[c] |= 1 << e
    return tri_count, tri_edges, edge_mask


def _trilinear_gradient(vals: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Gradient at point p (3,) of the trilinear interpolant of corner values vals (8,)."""
    w = np.where(CORNERS == 1, p, 1.0 - p)  # (8, 3) weights per axis
    dw = np.where(CORNERS == 1, 1.0, -1.0)
    g = [vals @ (dw[:, a] * w[:, (a + 1) % 3] * w[:, (a + 2) % 3]) for a in range(3)]
    return np.array(g)


def check_table(tri_count, tri_edges, edge_mask) -> None:
    """Assert the properties the kernels rely on; raises AssertionError naming the case.

    * every crossed edge is used, and by exactly one loop; no uncrossed edge is used;
    * every face segment is an edge of exactly one triangle; triangles sharing an interior
      diagonal use it in opposite directions; no diagonal joins two points on one cube face;
    * orientation: with corner values +1 (above) and −2 (below) — a trilinear interpolant that
      separates above corners on ambiguous faces, like the face rule — the area vector of every
      loop points down the interpolant's gradient (out of the above region).
    """
    for case in range(256):
        n = int(tri_count[case])
        tris = tri_edges[case, : 3 * n].reshape(-1, 3)
        crossed = {e for e in range(12) if (edge_mask[case] >> e) & 1}
        loops = case_loops(case)
        in_loops = [e for lp in loops for e in lp]
        assert sorted(in_loops) == sorted(crossed), f"case {case}: loops do not cover crossed edges once"
        assert set(tris.ravel().tolist()) == crossed, f"case {case}: triangles miss crossed edges"
        assert n == len(crossed) - 2 * len(loops), f"case {case}: wrong triangle count"
        # half-edges: face segments once each (same direction as the segment), diagonals paired
        half = {}
        for t in tris:
            for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                assert (a, b) not in half, f"case {case}: half-edge {a}->{b} used twice"
                half[(a, b)] = True
        segs = {(a, b) for _, a, b in face_segments(case)}
        for a, b in half:
            if (a, b) in segs:
                continue
            assert (b, a) in half, f"case {case}: diagonal {a}-{b} not shared by two triangles"
            assert not SHARE_FACE[a, b], f"case {case}: diagonal {a}-{b} lies on a cube face"
        assert segs <= set(half), f"case {case}: a face segment is not a triangle edge"
        # orientation against the trilinear interpolant
        vals = np.array([1.0 if above(case, c) else -2.0 for c in range(8)])
        pts = np.zeros((12, 3))
        for e, (c0, c1) in enumerate(EDGE_CORNERS):
            v0, v1 = vals[c0], vals[c1]
            t = 0.5 if v0 == v1 else -v0 / (v1 - v0)
            pts[e] = CORNERS[c0] + t * (CORNERS[c1] - CORNERS[c0])
        for lp in loops:
            ring = pts[lp]
            area = np.cross(ring, np.roll(ring, -1, axis=0)).sum(axis=0)  # Newell's area vector
            grad = np.zeros(3)
            for e in lp:  # gradient sampled where the loop crosses the edges
                grad += _trilinear_gradient(vals, pts[e])
            assert area @ grad < 0, f"case {case}: loop {lp} oriented against the gradient"


TRI_COUNT, TRI_EDGES, EDGE_MASK = build_table()
#: largest number of triangles of one case
MAX_TRIS = int(TRI_COUNT.max())

__all__ = ["TRI_COUNT", "TRI_EDGES", "EDGE_MASK", "EDGE_CORNERS", "EDGE_AXIS", "MAX_TRIS",
           "build_table", "check_table", "case_loops", "case_triangles", "face_segments"]
