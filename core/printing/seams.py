"""Seams: where parts touch by design, sharing vertex positions and interface faces.

Label maps become surfaces where touching organs share interface faces. Vertices are matched
across parts by exact position ("welded", :func:`anatomesh.core.model.mesh.weld_ids`), so parts
exported with their own copies of the seam vertices are handled the same as parts sharing
indices. A seam is contact, not a gap: the gap search measures away from it
(:func:`seam_index`), and thin creases along it are backed by the neighbouring part when the
parts print together (:func:`seam_neighbourhoods`).
"""
from __future__ import annotations

from typing import List, NamedTuple, Sequence, Tuple

import numpy as np

from ..model.mesh import row_keys, weld_ids


class SeamIndex(NamedTuple):
    """Per part (lists in the parts' order): ``vertices`` the welded ids (sorted int64) it shares
    with other parts; ``faces`` the indices (int64) of its faces whose three corners are shared
    (candidates for faces another part has too); ``keys`` one comparable key per such face
    (:func:`anatomesh.core.model.mesh.row_keys` of its sorted welded corners)."""

    vertices: List[np.ndarray]
    faces: List[np.ndarray]
    keys: List[np.ndarray]


def welded_part_ids(parts: Sequence[Tuple[np.ndarray, np.ndarray]]) -> Tuple[List[np.ndarray], int]:
    """Welded vertex ids of all ``parts`` ((vertices mm, faces) each) together: per part an (N,)
    int64 array, and the number of ids (at least 1)."""
    allv = np.concatenate([v for v, _ in parts]) if len(parts) else np.zeros((0, 3))
    wid = weld_ids(allv)
    offs = np.cumsum([0] + [len(v) for v, _ in parts])
    wids = [wid[offs[i]:offs[i + 1]] for i in range(len(parts))]
    return wids, (int(wid.max()) + 1 if wid.size else 1)


def seam_index(parts: Sequence[Tuple[np.ndarray, np.ndarray]], wids: Sequence[np.ndarray],
               nw: int) -> SeamIndex:
    """The seams of ``parts`` ((vertices mm, faces) each), given their welded vertex ids ``wids``
    (:func:`welded_part_ids`) out of ``nw``; see :class:`SeamIndex`."""
    seen = np.zeros(nw, np.int64)
    uw = [np.unique(wids[i][f.ravel()]) if len(f) else np.zeros(0, np.int64)
          for i, (_, f) in enumerate(parts)]
    for u in uw:
        seen[u] += 1
    multi = seen > 1
    seam_v = [u[multi[u]] for u in uw]
    seam_f, seam_key = [], []
    for i, (_, f) in enumerate(parts):
        if not len(f):
            seam_f.append(np.zeros(0, np.int64))
            seam_key.append(row_keys(np.zeros((0, 3), np.int64)))
            continue
        wf = wids[i][f]
        cand = np.flatnonzero(np.all(multi[wf], axis=1))  # every corner shared: may be a seam face
        seam_f.append(cand)
        seam_key.append(row_keys(np.sort(wf[cand], axis=1)))
    return SeamIndex(seam_v, seam_f, seam_key)


def seam_neighbourhoods(parts: Sequence[Tuple[np.ndarray, np.ndarray]]) -> List[np.ndarray]:
    """Per part a bool mask (N,) of the vertices on a seam — a position another part has too —
    or sharing a face with one: where touching parts printed together back each other up."""
    if not parts:
        return []
    sizes = [len(v) for v, _ in parts]
    wid = weld_ids(np.concatenate([v for v, _ in parts]))
    owner = np.repeat(np.arange(len(parts)), sizes)
    users = np.bincount(np.unique(np.stack([wid, owner], 1), axis=0)[:, 0], minlength=int(wid.max()) + 1)
    shared = users[wid] > 1
    out, start = [], 0
    for (v, f), n in zip(parts, sizes):
        seam = shared[start:start + n]
        near = seam.copy()
        if len(f):
            near[f[seam[f].any(axis=1)].ravel()] = True
        out.append(near)
        start += n
    return out
