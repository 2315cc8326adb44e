"""Numba kernel replaying a prefix of a logged collapse sequence (private to
:mod:`anatomesh.core.decimate`): the levels of a progressive mesh (Hoppe 1996, "Progressive
meshes") are rebuilt from it without running the decimation again."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def replay_collapses(keep, drop, where, count, V):
    """The vertex map and positions after the first ``count`` logged collapses.

    ``keep``/``drop`` (C,) int32 and ``where`` (C, 3) float64: collapse ``i`` merged ``drop``
    into ``keep`` and moved ``keep`` to ``where[i]``. ``V`` (N, 3) float64 positions before any
    collapse. Returns ``rep`` (N,) int64 — the vertex each input vertex has become (itself when
    it survives) — and the positions (N, 3) float64 (exactly the values the collapse run stored).
    """
    n = V.shape[0]
    rep = np.arange(n)
    P = V.copy()
    for i in range(count):
        k = keep[i]
        P[k, 0], P[k, 1], P[k, 2] = where[i, 0], where[i, 1], where[i, 2]
    # backwards: when drop[i] merged into keep[i], keep[i] was alive; its own fate is decided by
    # later collapses, already resolved
    for i in range(count - 1, -1, -1):
        rep[drop[i]] = rep[keep[i]]
    return rep, P
