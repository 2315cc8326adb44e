"""The values of a volume counted in one pass: the distinct values and the voxels holding each.

Used by the readers' label-map detection (:mod:`.label_tables`) and by the input facts of
``anatomesh inspect`` and the run report (:mod:`.describe`). The voxels are read once, in their
memory order, through a flat view of the array (C- or Fortran-ordered arrays are not copied;
other layouts go slab by slab), by a numba kernel that counts into a table: 256 or 65536 bins
for 8- and 16-bit data, ``max - min + 1`` bins for wider integers. Only very wide value ranges
(more than :data:`MAX_TABLE` distinct possible values) fall back on ``np.unique`` slab by slab.
Pieces are counted on two threads (the kernel releases the GIL), and the counts of the last
array are remembered: the reader's label-map check and the report's input facts share one pass
(the array is recognised by identity, address and
:func:`~anatomesh.core.model.fingerprint.sample_fingerprint`: after editing an array in place,
pass a new one).
"""
from __future__ import annotations

import weakref
from concurrent.futures import ThreadPoolExecutor
from typing import Iterator, Optional, Tuple

import numpy as np

from ..model.fingerprint import sample_fingerprint

#: widest value range (max - min + 1) counted with a table
MAX_TABLE = 1 << 22
#: elements per piece of the flat view (floats are converted to int64 piece by piece)
CHUNK = 1 << 24
_last: Optional[tuple] = None  # (weakref to the array, fingerprint, (values, counts))


def value_counts(data: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Distinct values of an integer-valued array and their voxel counts, in one pass.

    Parameters
    ----------
    data : ndarray, any shape
        Integer or bool values, or floats holding whole numbers (the caller checks that, e.g.
        with :func:`anatomesh.core.io.label_tables.is_integer_valued`).

    Returns
    -------
    values : (D,) int64, ascending
    counts : (D,) int64, voxels holding each value (all > 0; they sum to ``data.size``)
    """
    a = np.asarray(data)
    if a.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    key = (a.__array_interface__["data"][0], sample_fingerprint(a))
    if _last is not None and _last[0]() is a and _last[1] == key:
        return _last[2][0].copy(), _last[2][1].copy()
    out = _count(a)
    _remember(a, key, out)
    return out[0].copy(), out[1].copy()


def _remember(a: np.ndarray, key: tuple, out) -> None:
    global _last
    try:
        _last = (weakref.ref(a), key, out)
    except TypeError:  # not weak-referenceable
        _last = None


def _count(a: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """:func:`value_counts` of a non-empty array."""
    if not a.dtype.isnative:
        a = a.astype(a.dtype.newbyteorder("="))
    if a.dtype == np.bool_:
        a = a.view(np.uint8)
    if a.dtype.kind in "iu" and a.dtype.itemsize <= 2:
        bits = 8 * a.dtype.itemsize
        counts = _table(flat_views(a.view(np.uint8 if bits == 8 else np.uint16)), 0, 1 << bits)
        stored = np.flatnonzero(counts)
        values = stored.astype(np.int64)
        if a.dtype.kind == "i":  # two's complement: stored bits back to signed values
            values = np.where(values >= 1 << (bits - 1), values - (1 << bits), values)
            order = np.argsort(values, kind="stable")
            return values[order], counts[stored[order]]
        return values, counts[stored]
    lo, hi = a.min(), a.max()
    if float(hi) - float(lo) < MAX_TABLE:
        counts = _table((f if f.dtype.kind in "iu" else f.astype(np.int64) for f in flat_views(a)),
                        int(lo), int(hi) - int(lo) + 1)
        present = np.flatnonzero(counts)
        return present.astype(np.int64) + np.int64(lo), counts[present]
    return _unique_counts(a)


def _table(pieces: Iterator[np.ndarray], offset: int, bins: int) -> np.ndarray:
    """``counts[v - offset]`` (bins,) int64 over every piece, two pieces at a time."""
    from ._values_kernels import SPLIT_BINS, add_counts

    rows = 4 if bins <= SPLIT_BINS else 1
    tables = [np.zeros((rows, bins), np.int64) for _ in range(2)]
    with ThreadPoolExecutor(2) as pool:
        pending = []
        for i, flat in enumerate(pieces):
            if len(pending) == 2:
                pending.pop(0).result()
            pending.append(pool.submit(add_counts, flat, np.int64(offset), tables[i % 2]))
        for p in pending:
            p.result()
    return tables[0].sum(axis=0) + tables[1].sum(axis=0)


def flat_views(a: np.ndarray, chunk: int = CHUNK) -> Iterator[np.ndarray]:
    """1D pieces of ``a`` (at most ``chunk`` elements) covering every element once: views of
    the array in memory order when it is C- or Fortran-contiguous, else one (copied) slab at a
    time along the first axis."""
    if a.flags.c_contiguous or a.flags.f_contiguous:
        flat = a.reshape(-1, order="C" if a.flags.c_contiguous else "F")
        for start in range(0, flat.size, chunk):
            yield flat[start:start + chunk]
    else:
        for s in (a if a.ndim > 1 else a[None]):
            yield np.ravel(s, order="K")


def _unique_counts(a: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """``value_counts`` for value ranges too wide for a table: ``np.unique`` slab by slab."""
    total = {}
    for flat in flat_views(a):
        vals, n = np.unique(flat, return_counts=True)
        for v, c in zip(vals.tolist(), n.tolist()):
            total[int(v)] = total.get(int(v), 0) + c
    values = np.array(sorted(total), np.int64)
    return values, np.array([total[v] for v in values.tolist()], np.int64)
