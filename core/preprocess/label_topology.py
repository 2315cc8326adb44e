"""Removing excess topology from a label map, per label: enclosed cavities and small handles.

Topology of a label (its voxels as a union of closed unit cubes, so voxels touching at an edge or
a corner are connected; the background is 6-connected): Betti numbers ``b0`` (components),
``b1`` (handles = tunnels; the genus summed over the label's surfaces) and ``b2`` (cavities:
enclosed background pockets), with Euler characteristic ``χ = b0 − b1 + b2`` counted on the cube
complex as ``V − E + F − C`` (vertices, edges, faces, cubes; Kong and Rosenfeld 1989, "Digital
topology: introduction and survey").

* :func:`fill_cavities` — every enclosed pocket (a component of the label's complement that does
  not reach the outside) is filled with the label where it holds background; other labels inside
  stay (labels are never overwritten, so they stay disjoint).
* :func:`close_handles` — morphological closing by a ball of diameter ``size_mm`` (distance
  transforms in mm, so the ball is round on anisotropic voxels) proposes background voxels to add;
  each connected piece of them is added only if it closes a handle (the Euler characteristic rises
  and no cavity appears), so dents and gaps the closing would also fill are left alone — a tunnel
  up to ``size_mm`` across is plugged, the rest of the shape is kept.

Both return the new Volume and, per label, the counts before and after.
"""
from __future__ import annotations

from typing import Dict, Iterable, List, Optional, Tuple

import numpy as np
from scipy import ndimage

from ..model.errors import AnatomeshError
from ..model.progress import Progress, report
from ..model.volume import Volume

_SIX = ndimage.generate_binary_structure(3, 1)
_ALL = np.ones((3, 3, 3), bool)


def label_topology(mask: np.ndarray) -> Dict[str, int]:
    """``{"components", "handles", "cavities", "euler"}`` of a binary mask (see module doc)."""
    m = np.pad(np.asarray(mask, bool), 1)
    b0 = int(ndimage.label(m, _ALL)[1])
    b2 = max(0, int(ndimage.label(~m, _SIX)[1]) - 1)
    chi = euler_characteristic(m)
    return {"components": b0, "handles": b0 + b2 - chi, "cavities": b2, "euler": chi}


def euler_characteristic(m: np.ndarray) -> int:
    """χ = V − E + F − C of the union of closed unit cubes at the True voxels of ``m`` (which
    must be False on its border)."""
    m = np.asarray(m, bool)
    cubes = int(m.sum())
    faces = sum(int((_shift(m, a, 0) | _shift(m, a, 1)).sum()) for a in range(3))
    edges = 0
    for a in range(3):
        b, c = [x for x in range(3) if x != a]
        edges += int((_pair(m, b, c, 0, 0) | _pair(m, b, c, 1, 0) | _pair(m, b, c, 0, 1)
                      | _pair(m, b, c, 1, 1)).sum())
    corners = np.zeros(tuple(n - 1 for n in m.shape), bool)
    for d in np.ndindex(2, 2, 2):
        corners |= m[d[0]:m.shape[0] - 1 + d[0], d[1]:m.shape[1] - 1 + d[1], d[2]:m.shape[2] - 1 + d[2]]
    return int(corners.sum()) - edges + faces - cubes


def _shift(m, axis, d):
    sl = [slice(None)] * 3
    sl[axis] = slice(d, m.shape[axis] - 1 + d)
    return m[tuple(sl)]


def _pair(m, b, c, db, dc):
    sl = [slice(None)] * 3
    sl[b] = slice(db, m.shape[b] - 1 + db)
    sl[c] = slice(dc, m.shape[c] - 1 + dc)
    return m[tuple(sl)]


# ---------------------------------------------------------------------------------------------
def fill_cavities(volume: Volume, values: Optional[Iterable[int]] = None, background: int = 0,
                  progress: Optional[Progress] = None) -> Tuple[Volume, Dict[int, Dict]]:
    """Fill the enclosed background pockets of each label (all present, or ``values``).

    Returns ``(volume, info)``; ``info[value]`` has ``before``/``after`` (label_topology) and
    ``filled_voxels``. The data is copied once when anything changes."""
    data = _labels(volume, "--fill-cavities")
    out, info = data, {}
    for n, v in enumerate(_values(data, values, background)):
        lo, hi = _bbox(out == v, 1, out.shape)
        box = out[_sl(lo, hi)]
        mask = box == v
        before = label_topology(mask)
        comp, count = ndimage.label(~np.pad(mask, 1), _SIX)
        outside = np.unique(np.concatenate([comp[0].ravel(), comp[-1].ravel(), comp[:, 0].ravel(),
                                            comp[:, -1].ravel(), comp[:, :, 0].ravel(),
                                            comp[:, :, -1].ravel()]))
        pocket = ~np.isin(comp, outside)[1:-1, 1:-1, 1:-1] & (box == background)
        filled = int(pocket.sum())
        if filled:
            out = out.copy() if out is data else out
            out[_sl(lo, hi)][pocket] = v
        info[v] = {"before": before, "after": label_topology(out[_sl(lo, hi)] == v),
                   "filled_voxels": filled}
        report(progress, (n + 1) / max(1, len(info)), f"cavities of label {v}")
    return _result(volume, out, "fill_cavities"), info


def close_handles(volume: Volume, size_mm: float, values: Optional[Iterable[int]] = None,
                  background: int = 0, progress: Optional[Progress] = None) -> Tuple[Volume, Dict[int, Dict]]:
    """Plug the handles (tunnels) of each label up to ``size_mm`` across (see module doc).

    Returns ``(volume, info)``; ``info[value]`` has ``before``/``after`` (label_topology),
    ``added_voxels`` and ``pieces_added`` / ``pieces_rejected`` (closing pieces that would only
    fill a dent or a gap, or make a cavity)."""
    if isinstance(size_mm, bool) or not (isinstance(size_mm, (int, float)) and size_mm > 0):
        raise AnatomeshError(f"--close-handles needs a size in mm > 0, got {size_mm!r}")
    data = _labels(volume, "--close-handles")
    h = np.asarray(volume.spacing, np.float64)
    grow = np.ceil(size_mm / h).astype(np.int64) + 1
    out, info, chosen = data, {}, _values(data, values, background)
    for n, v in enumerate(chosen):
        lo, hi = _bbox(out == v, grow, out.shape)
        box = out[_sl(lo, hi)]
        mask = box == v
        before = label_topology(mask)
        candidates = closing(mask, size_mm / 2.0, h) & ~mask & (box == background)
        added, kept, rejected = _plug(mask, candidates, before["cavities"])
        if kept:
            out = out.copy() if out is data else out
            out[_sl(lo, hi)][added] = v
        info[v] = {"before": before, "after": label_topology(out[_sl(lo, hi)] == v),
                   "added_voxels": int(added.sum()), "pieces_added": kept, "pieces_rejected": rejected}
        report(progress, (n + 1) / max(1, len(chosen)), f"handles of label {v}")
    return _result(volume, out, "close_handles"), info


def closing(mask: np.ndarray, radius_mm: float, spacing) -> np.ndarray:
    """Morphological closing of ``mask`` by a ball of ``radius_mm`` (Euclidean, in mm): the
    dilation ``d(x, mask) <= r``, then its erosion ``d(x, outside) > r``; outside the array
    counts as outside."""
    m = np.pad(np.asarray(mask, bool), 1)
    grown = ndimage.distance_transform_edt(~m, sampling=spacing) <= radius_mm
    grown[[0, -1]] = False
    grown[:, [0, -1]] = False
    grown[:, :, [0, -1]] = False
    return (ndimage.distance_transform_edt(grown, sampling=spacing) > radius_mm)[1:-1, 1:-1, 1:-1]


def _plug(mask: np.ndarray, candidates: np.ndarray, cavities: int):
    """Add the connected pieces of ``candidates`` that raise the Euler characteristic of
    ``mask`` without adding a cavity; returns (added voxels, pieces added, pieces rejected)."""
    pieces, count = ndimage.label(candidates, _ALL)
    added = np.zeros(mask.shape, bool)
    current = np.array(mask)
    kept = 0
    for k, sl in enumerate(ndimage.find_objects(pieces), start=1):
        window = tuple(slice(max(0, s.start - 2), s.stop + 2) for s in sl)
        piece = pieces[window] == k
        local = current[window]
        delta = euler_characteristic(np.pad(local | piece, 1)) - euler_characteristic(np.pad(local, 1))
        if delta <= 0:
            continue  # a dent or a gap: the topology stays, so does the shape
        trial = current.copy()
        trial[window] |= piece
        if label_topology(trial)["cavities"] > cavities:
            continue  # it would close a pocket off instead of plugging a tunnel
        current = trial
        added[window] |= piece
        kept += 1
    return added, kept, count - kept


def _labels(volume: Volume, flag: str) -> np.ndarray:
    if volume.data.dtype.kind not in "iub":
        raise AnatomeshError(f"{flag} works on label maps; this scan holds real values")
    return np.asarray(volume.data)


def _values(data: np.ndarray, values, background: int) -> List[int]:
    present = [int(v) for v in np.unique(data) if v != background]
    return present if values is None else [int(v) for v in values if int(v) in set(present)]


def _bbox(mask: np.ndarray, grow, shape):
    idx = [np.flatnonzero(mask.any(axis=tuple(a for a in range(3) if a != ax))) for ax in range(3)]
    lo = np.array([i[0] for i in idx]) - grow
    hi = np.array([i[-1] + 1 for i in idx]) + grow
    return np.maximum(lo, 0), np.minimum(hi, shape)


def _sl(lo, hi):
    return tuple(slice(int(a), int(b)) for a, b in zip(lo, hi))


def _result(volume: Volume, data: np.ndarray, step: str) -> Volume:
    return Volume(data, np.array(volume.affine), volume.space, dict(volume.meta), volume.labels,
                  list(volume.warnings))
