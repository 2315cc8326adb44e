"""Round holes in a surface and the tubes that line them: drain holes through a hollowed part's
wall, pins standing on a part and the pockets that take them.

:func:`drill` opens a hole of a given radius around an axis in the surface patch near a point:
the patch is refined (:func:`.surgery.refine_near`) until its edges are a quarter of the radius,
its triangles are split exactly along the cylinder (:func:`.surgery.split_by_level`,
:func:`.surgery.cylinder_root`) and those inside are removed, leaving one boundary loop on the
cylinder. :func:`line_hole` joins two such loops with a tube (:func:`.surgery.zipper`);
:func:`extrude_loop` continues one loop along the axis to a closed end (a pin or a pocket).
Meshes stay closed and consistently oriented; all lengths are mm.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np

from ..geometry.kernels import union_find_roots
from ..model.errors import AnatomeshError
from .surgery import around_axis, cylinder_root, fan, refine_near, ring, split_by_level, zipper

#: patch edges are refined to this fraction of the hole's radius
_EDGE_FRACTION = 0.25
#: points on the generated rings of a tube
_RING_POINTS = 32


def _patch(v, f, point, axis, radius) -> np.ndarray:
    """(M,) bool: faces connected to the face nearest ``point`` within 2.5·radius of it whose
    normals face the same way along the axis (the surface the hole goes through, not the far
    side of a thin wall)."""
    c = (v[f[:, 0]] + v[f[:, 1]] + v[f[:, 2]]) / 3.0
    to_point = np.linalg.norm(c - point, axis=1)
    seed = int(np.argmin(to_point))
    ci = np.union1d(np.flatnonzero(to_point < 2.5 * radius), [seed])  # normals of these only
    g = f[ci]
    n = np.cross(v[g[:, 1]] - v[g[:, 0]], v[g[:, 2]] - v[g[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    at_seed = n[np.searchsorted(ci, seed)]
    sign = np.sign(at_seed @ axis) or 1.0
    ci = ci[(sign * (n @ axis) > 0.2) | (ci == seed)]
    cand = np.zeros(len(f), bool)
    cand[ci] = True
    e = np.concatenate([f[ci][:, [0, 1]], f[ci][:, [1, 2]], f[ci][:, [2, 0]]])
    owner = np.tile(ci, 3)
    key = np.minimum(e[:, 0], e[:, 1]) * len(v) + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(key, kind="stable")
    same = key[order][1:] == key[order][:-1]
    a, b = owner[order][:-1][same], owner[order][1:][same]
    roots = union_find_roots(a.astype(np.int64), b.astype(np.int64), len(f))
    return cand & (roots == roots[seed])


def drill(v: np.ndarray, f: np.ndarray, point: np.ndarray, axis: np.ndarray, radius: float
          ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Open a round hole of ``radius`` around the line through ``point`` along unit ``axis`` in
    the surface patch there. Returns (vertices, faces, loop: the hole's boundary vertex indices,
    counter-clockwise around ``axis`` from angle 0, every one on the cylinder)."""
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    point = np.asarray(point, np.float64)

    def facing(vv, ff):
        return _patch(vv, ff, point, axis, radius)

    v, f, _ = refine_near(v, f, point, 1.5 * radius, _EDGE_FRACTION * radius, select=facing,
                          reach=2.5 * radius)  # the patch's reach (:func:`_patch`)
    patch = _patch(v, f, point, axis, radius)
    rel = v - point
    dist = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
    in_patch = np.zeros(len(v), bool)
    in_patch[f[patch].ravel()] = True
    phi = np.where(in_patch, dist - radius, 1.0)
    inside_v = phi < 0
    if np.any(inside_v[f[~patch]].any(axis=1)):
        raise AnatomeshError(f"a {2 * radius:g} mm hole at {np.round(point, 1).tolist()} does not fit on "
                             "the surface there; choose a smaller diameter")
    v2, f2, positive, parent = split_by_level(v, f, phi, cylinder_root(v, point, axis, radius), active=patch)
    keep = positive | ~patch[parent]
    f2 = f2[keep]
    loop = _hole_loop(f2, len(v2), len(v), point)
    loop, _ = around_axis(loop, v2, point, axis)
    return v2, f2, loop


def _hole_loop(f: np.ndarray, n: int, first_new: int, point) -> np.ndarray:
    """The boundary loop (vertex indices, in its half-edge order) made of the vertices the cut
    created (indices from ``first_new``): the new hole, not one drilled before."""
    from .fixes import boundary_loops

    loops, _ = boundary_loops(f[(f >= first_new).any(axis=1)], n)  # every face at a new vertex
    near = [lp for lp in loops if np.all(lp >= first_new)]
    if len(near) != 1:
        raise AnatomeshError(f"drilling at {np.round(point, 1).tolist()} left {len(near)} holes instead "
                             "of one; choose another place or a smaller diameter")
    return near[0]


def _orient(new_faces: np.ndarray, existing: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """``new_faces`` flipped if needed so that they use the loop's first edge opposite to the
    existing faces (a consistent orientation across the loop)."""
    a, b = int(loop[0]), int(loop[1])
    he = np.concatenate([existing[:, [0, 1]], existing[:, [1, 2]], existing[:, [2, 0]]])
    forward_exists = np.any((he[:, 0] == a) & (he[:, 1] == b))
    hn = np.concatenate([new_faces[:, [0, 1]], new_faces[:, [1, 2]], new_faces[:, [2, 0]]])
    new_forward = np.any((hn[:, 0] == a) & (hn[:, 1] == b))
    return new_faces[:, ::-1] if forward_exists == new_forward else new_faces


def line_hole(v: np.ndarray, f: np.ndarray, loop_a: np.ndarray, loop_b: np.ndarray, point: np.ndarray,
              axis: np.ndarray) -> np.ndarray:
    """Faces (all of the mesh) with a tube joining the hole loops ``loop_a`` and ``loop_b`` (both
    from :func:`drill` around the same axis). Raises when the two holes' orientations disagree
    (their surfaces do not bound one solid)."""
    la, aa = around_axis(loop_a, v, point, axis)
    lb, ab = around_axis(loop_b, v, point, axis)
    tube = _orient(zipper(la, aa, lb, ab), f, la)
    out = np.concatenate([f, tube])
    he = np.concatenate([out[:, [0, 1]], out[:, [1, 2]], out[:, [2, 0]]])
    key = he[:, 0] * len(v) + he[:, 1]
    if np.unique(key).size != key.size:
        raise AnatomeshError("the two holes of a drain do not face each other across one wall")
    return out


def extrude_loop(v: np.ndarray, f: np.ndarray, loop: np.ndarray, point: np.ndarray, axis: np.ndarray,
                 radius: float, start: float, length: float) -> Tuple[np.ndarray, np.ndarray]:
    """Continue the hole ``loop`` (on the cylinder of ``radius`` around ``axis`` through
    ``point``) as a tube from axial position ``start`` to ``start + length`` mm and close it with
    a flat end: a pin when the axis points out of the part, a pocket when it points in.
    Returns (vertices, faces)."""
    la, aa = around_axis(loop, v, point, axis)
    r0 = ring(point + start * axis, axis, radius, _RING_POINTS)
    r1 = ring(point + (start + length) * axis, axis, radius, _RING_POINTS)
    n = len(v)
    i0, i1 = n + np.arange(_RING_POINTS), n + _RING_POINTS + np.arange(_RING_POINTS)
    centre = n + 2 * _RING_POINTS
    ang = np.arange(_RING_POINTS) * 2 * np.pi / _RING_POINTS
    ang = (ang - loop_start_angle(v[la[0]], point, axis)) % (2 * np.pi)
    order = np.argsort(ang)
    i0, i1, ang = i0[order], i1[order], ang[order]
    parts = [zipper(la, aa, i0, ang), zipper(i0, ang, i1, ang), fan(i1, centre)[:, ::-1]]
    vv = np.concatenate([v, r0, r1, (point + (start + length) * axis)[None]])
    new = _orient(np.concatenate(parts), f, la)
    return vv, np.concatenate([f, new])


def loop_start_angle(p0: np.ndarray, point: np.ndarray, axis: np.ndarray) -> float:
    """The angle of ``p0`` around ``axis`` in the frame of :func:`.surgery.loop_angles`."""
    from .surgery import loop_angles

    return float(loop_angles(p0[None], point, axis)[0])
