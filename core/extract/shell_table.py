"""The 2x2x2 splitting table: which faces of a label around a lattice corner form one fan.

Cuberille / surface-nets surfaces (Gibson 1998) put a vertex at every lattice corner ``p`` where
the 8 voxels around ``p`` are not all equal. For one label ``L`` the faces of ``L`` around ``p``
(the *block faces* between an ``L`` voxel and a non-``L`` voxel) can form more than one fan —
two ``L`` voxels touching only along an edge or at ``p``, or ``L`` around a pinched complement.
A 2-manifold shell for ``L`` needs one vertex copy per fan. This module precomputes the fans.

Local numbering around ``p`` = lattice point (a, b, c), which sits at index-space position
(a - 0.5, b - 0.5, c - 0.5):

* voxel ``q = u + 2 v + 4 w`` (u, v, w in {0, 1}) is voxel (a - 1 + u, b - 1 + v, c - 1 + w);
  a label's *config* is the 8-bit mask of the voxels holding it;
* block face ``d * 4 + r`` (d = axis 0..2, r = 0..3) lies between voxels ``q`` and
  ``q | (1 << d)`` where bit d of q is 0 and the other two bits of q, lower axis first, are r;
* half-edge ``h = 2 d + s`` is the lattice edge from ``p`` along axis d toward side s (s = 0:
  minus, 1: plus); the 4 voxels around it are those with bit d == s.

Fans are found by union-find over the 12 block faces, linking the faces of ``L`` that meet at
each half-edge. A half-edge has 0, 2 or 4 faces of ``L``. With 2, they are linked. With 4, ``L``
holds a diagonal pair of the 4 voxels there, and two pairings are possible:

* *separated* (the default; 6-connectivity for ``L``): link the two faces of each ``L`` voxel;
* *joined*: link the two faces of each non-``L`` voxel.

"Separated" everywhere fails in one case: when the two ``L`` voxels of a diagonal lattice edge are
6-connected inside the 2x2x2 blocks at *both* ends of the edge, the two sheets through the edge
meet in one fan at both ends, and the edge would carry 4 triangles. Such an edge is *joined*
instead (``JOINABLE`` marks the half-edges where the pair is 6-connected inside the block; an
edge is joined when it is joinable from both ends). Then every diagonal edge has its two sheets
in different fans at one end at least (joined: at both, because the ``L`` loop through the edge
separates the two non-``L`` voxels; separated: at the end where the pair is not connected), so
every edge of every shell has exactly two triangles and every vertex copy one fan.

Tables (built once, lazily, by :func:`tables`):

``CYCLE`` int8 (256 * 64, 12)
    ``CYCLE[config * 64 + joined_bits, face]``: fan index (0, 1, ...) of block face ``face`` for a
    label with ``config``, or -1 when the face is not a face of that label. ``joined_bits`` has
    bit h set for each half-edge h resolved as joined. Fans are numbered by their lowest face.
``JOINABLE`` uint8 (256,)
    Bit h set when half-edge h is diagonal for the config and its two label voxels are
    6-connected within the block.
``NEEDS_SPLIT`` uint8 (256,)
    1 when the config may need more than one vertex copy (more than one fan without joins, or a
    joinable half-edge).
``FACE_VOXELS`` int64 (12, 2)
    The two local voxels of each block face.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Dict

import numpy as np


def _face_voxels() -> np.ndarray:
    out = np.zeros((12, 2), np.int64)
    for d in range(3):
        e1, e2 = [e for e in range(3) if e != d]
        for r in range(4):
            q0 = ((r & 1) << e1) | ((r >> 1) << e2)
            out[d * 4 + r] = (q0, q0 | (1 << d))
    return out


FACE_VOXELS = _face_voxels()
_FV = [(int(a), int(b)) for a, b in FACE_VOXELS]  # plain ints: fast in the Python loops below


def _halfedge_faces(h: int) -> list:
    """Block faces around half-edge h (faces among the 4 voxels with bit d == s)."""
    d, s = h >> 1, h & 1
    return [f for f in range(12) if f // 4 != d
            and all(((q >> d) & 1) == s for q in _FV[f])]


HALFEDGE_FACES = [_halfedge_faces(h) for h in range(6)]


def _is_boundary(config: int, f: int) -> bool:
    q0, q1 = _FV[f]
    return bool((config >> int(q0)) & 1) != bool((config >> int(q1)) & 1)


def _connected_in_block(config: int, q0: int, q1: int) -> bool:
    """Are voxels q0 and q1 (both in config) 6-connected through voxels of config?"""
    seen, stack = {q0}, [q0]
    while stack:
        q = stack.pop()
        for d in range(3):
            n = q ^ (1 << d)
            if (config >> n) & 1 and n not in seen:
                seen.add(n)
                stack.append(n)
    return q1 in seen


def _joinable(config: int) -> int:
    bits = 0
    for h in range(6):
        faces = [f for f in HALFEDGE_FACES[h] if _is_boundary(config, f)]
        if len(faces) == 4:
            d, s = h >> 1, h & 1
            inside = [q for q in range(8) if (q >> d) & 1 == s and (config >> q) & 1]
            if _connected_in_block(config, inside[0], inside[1]):
                bits |= 1 << h
    return bits


def _cycles(config: int, joined: int) -> np.ndarray:
    """Fan index of each of the 12 block faces for ``config`` (-1: not a face of the label)."""
    parent = list(range(12))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for h in range(6):
        faces = [f for f in HALFEDGE_FACES[h] if _is_boundary(config, f)]
        if len(faces) == 2:
            pairs = [faces]
        elif len(faces) == 4:
            # pair faces sharing a voxel on the kept-together side: L voxels (separated) or
            # non-L voxels (joined)
            keep_in = not ((joined >> h) & 1)
            pairs = []
            for q in sorted(set(q for f in faces for q in _FV[f])):
                if bool((config >> q) & 1) == keep_in:
                    pairs.append([f for f in faces if q in _FV[f]])
        else:
            pairs = []
        for f, g in pairs:
            parent[find(f)] = find(g)
    out = np.full(12, -1, np.int8)
    ids: Dict[int, int] = {}
    for f in range(12):
        if _is_boundary(config, f):
            out[f] = ids.setdefault(find(f), len(ids))
    return out


@lru_cache(maxsize=None)
def tables():
    """``(CYCLE, JOINABLE, NEEDS_SPLIT)`` as described in the module docstring."""
    joinable = np.array([_joinable(c) for c in range(256)], np.uint8)
    cycle = np.full((256 * 64, 12), -1, np.int8)
    needs = np.zeros(256, np.uint8)
    for c in range(256):
        j = int(joinable[c])
        for bits in range(64):
            if bits & ~j:
                continue  # never looked up: only joinable half-edges are ever joined
            cycle[c * 64 + bits] = _cycles(c, bits)
        needs[c] = 1 if (j or cycle[c * 64].max() > 0) else 0
    return cycle, joinable, needs
