"""Numba kernels of the fast uniform umbrella passes (the Taubin/Laplacian hot path), private to
``core/smooth``.

Layout: positions are "structure of arrays" P (3, N + 1) — a row per coordinate, column N zero
(the pad) — and neighbours are padded columns ``cols`` (width, N) uint32 (column-major ELLPACK,
see ``MeshStructure.padded``). The neighbour loop then has a fixed trip count and no branch
and unrolls. It runs in float32 (live sliders) or float64 alike.
"""
from __future__ import annotations

import math

from numba import njit, prange

from ._filter_kernels import FAST, project_l1

#: width of the padded neighbour rows (``MeshStructure.padded``): a compile-time constant, so
#: the neighbour loop unrolls; 97 % of marching-cubes vertices have at most 8 neighbours, the
#: rest are read from the CSR
PAD_WIDTH = 8
#: width of the helper columns' lists (``MeshStructure.padded``): a row longer than PAD_WIDTH
#: keeps 7 neighbours in its columns; on a marching-cubes surface such rows have 9.4 on
#: average, so a helper sums 2.4 and 4 slots rarely need a chain
EXT_WIDTH = 4


@njit(parallel=True, fastmath=FAST, cache=True)
def to_columns(src, m, dst):
    """``dst[:, i] = m @ src[i]`` for every row of ``src`` (N, 3) into ``dst`` (3, ≥ N): a
    linear change of frame and the switch to the column layout, in parallel."""
    for i in prange(src.shape[0]):
        x, y, z = src[i, 0], src[i, 1], src[i, 2]
        dst[0, i] = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z
        dst[1, i] = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z
        dst[2, i] = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z


@njit(parallel=True, fastmath=FAST, cache=True)
def from_columns(src, m, dst):
    """``dst[i] = m @ src[:, i]`` for every row of ``dst`` (N, 3): back from the column layout."""
    for i in prange(dst.shape[0]):
        x, y, z = src[0, i], src[1, i], src[2, i]
        dst[i, 0] = m[0, 0] * x + m[0, 1] * y + m[0, 2] * z
        dst[i, 1] = m[1, 0] * x + m[1, 1] * y + m[1, 2] * z
        dst[i, 2] = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z


@njit(cache=True, inline="always")
def _move(i, x, y, z, sx, sy, sz, k, e, gain, axis, C, S, r2, metric):
    """The new position of vertex ``i`` at (x, y, z) whose neighbours sum to (sx, sy, sz):
    ``p + axis @ (gain_i (k s − e p))``, clamped to the unit box around ``C[:, i]`` (the
    constraint's normalised frame) and then pulled towards ``S[:, i]`` until
    ``|metric @ (p − S_i)|² <= r2``. ``gain``, ``axis``, ``C``, ``S`` may each be None: numba
    then compiles that step out (a kernel per combination), and the rest stays branch-free
    but for the cap's select."""
    dx = k * sx - e * x
    dy = k * sy - e * y
    dz = k * sz - e * z
    if gain is not None:
        g = gain[i]
        dx, dy, dz = g * dx, g * dy, g * dz
    if axis is not None:
        dx, dy, dz = (axis[0, 0] * dx + axis[0, 1] * dy + axis[0, 2] * dz,
                      axis[1, 0] * dx + axis[1, 1] * dy + axis[1, 2] * dz,
                      axis[2, 0] * dx + axis[2, 1] * dy + axis[2, 2] * dz)
    return _box_cap(i, x + dx, y + dy, z + dz, C, S, r2, metric)


@njit(cache=True, inline="always")
def _box_cap(i, px, py, pz, C, S, r2, metric):
    """(px, py, pz) clamped to the unit box around ``C[:, i]``, then capped (:func:`_cap`);
    ``C`` or ``S`` None: that step compiled out."""
    if C is not None:
        one = C.dtype.type(1)  # a literal 1 would turn float32 into float64
        px, py, pz = _unit(px, C[0, i], one), _unit(py, C[1, i], one), _unit(pz, C[2, i], one)
    if S is not None:
        px, py, pz = _cap(i, px, py, pz, S, r2, metric)
    return px, py, pz


@njit(cache=True, inline="always")
def _unit(x, c, one):
    """x clamped to [c − one, c + one]: one coordinate of the unit box."""
    return min(max(x, c - one), c + one)


@njit(cache=True, inline="always")
def _cap(i, px, py, pz, S, r2, metric):
    """Pull (px, py, pz) straight towards ``S[:, i]`` until ``|metric @ (p − S_i)|² <= r2``
    (metric maps frame offsets to mm; linear maps keep lines and ratios)."""
    sx, sy, sz = S[0, i], S[1, i], S[2, i]
    ux, uy, uz = px - sx, py - sy, pz - sz
    mx = metric[0, 0] * ux + metric[0, 1] * uy + metric[0, 2] * uz
    my = metric[1, 0] * ux + metric[1, 1] * uy + metric[1, 2] * uz
    mz = metric[2, 0] * ux + metric[2, 1] * uy + metric[2, 2] * uz
    d2 = mx * mx + my * my + mz * mz
    if d2 > r2:
        t = math.sqrt(r2 / d2)
        px, py, pz = sx + ux * t, sy + uy * t, sz + uz * t
    return px, py, pz


@njit(parallel=True, fastmath=FAST, cache=True)
def helper_sums(P, ext, level_at, n):
    """Fill the helper columns ``P[:, n + 1 + h]`` of long rows (see
    ``_neighbors_kernels.padded_columns``) with the sums of ``P`` over ``ext[:, h]``, level by
    level (a chained helper is summed before the one that reads it)."""
    zero = P[0, n]
    for level in range(level_at.shape[0] - 1):
        for h in prange(level_at[level], level_at[level + 1]):
            sx = zero
            sy = zero
            sz = zero
            for a in range(EXT_WIDTH):
                j = ext[a, h]
                sx += P[0, j]
                sy += P[1, j]
                sz += P[2, j]
            P[0, n + 1 + h] = sx
            P[1, n + 1 + h] = sy
            P[2, n + 1 + h] = sz


@njit(parallel=True, fastmath=FAST, cache=True)
def padded_pass(P, Q, cols, inv_count, factor, gain, axis, C, S, r2, metric):
    """One uniform umbrella pass ``Q_i = P_i + factor (mean(P_j) − P_i)`` over padded columns
    (helper columns of ``P`` already summed, :func:`helper_sums`) with the gain, axis map, box
    and cap fused in (:func:`_move`). ``P``, ``Q``: (3, ≥ N + 1), column N zero; ``C``, ``S``:
    (3, ≥ N) or None."""
    n = cols.shape[1]
    zero = P[0, n]
    for i in prange(n):
        sx = zero
        sy = zero
        sz = zero
        for a in range(PAD_WIDTH):  # a constant trip count: unrolled
            j = cols[a, i]
            sx += P[0, j]
            sy += P[1, j]
            sz += P[2, j]
        c = inv_count[i]
        e = factor if c > zero else zero
        px, py, pz = _move(i, P[0, i], P[1, i], P[2, i], sx, sy, sz, factor * c, e, gain, axis,
                           C, S, r2, metric)
        Q[0, i] = px
        Q[1, i] = py
        Q[2, i] = pz


@njit(cache=True, inline="always")
def _along(P, cols, inv_count, factor, gain, k, i, zero):
    """Vertex i's coordinate k after a pass moving along frame axis k only (before the box)."""
    sk = zero
    for a in range(PAD_WIDTH):
        sk += P[k, cols[a, i]]
    c = inv_count[i]
    e = factor if c > zero else zero
    d = factor * c * sk - e * P[k, i]
    if gain is not None:
        d = gain[i] * d
    return P[k, i] + d


@njit(parallel=True, fastmath=FAST, cache=True)
def padded_pass_along(P, Q, cols, inv_count, factor, gain, k, C, S, r2, metric):
    """:func:`padded_pass` with the axis map ``e_k e_kᵀ`` (moves along frame axis ``k`` only,
    e.g. a staircase pass across thick slices): the same positions, from a third of the
    gathers (the other coordinates' moves are exact zeros there)."""
    n = cols.shape[1]
    zero = P[0, n]
    for i in prange(n):
        x = _along(P, cols, inv_count, factor, gain, k, i, zero)
        px, py, pz = P[0, i], P[1, i], P[2, i]
        if k == 0:
            px = x
        elif k == 1:
            py = x
        else:
            pz = x
        px, py, pz = _box_cap(i, px, py, pz, C, S, r2, metric)
        Q[0, i] = px
        Q[1, i] = py
        Q[2, i] = pz


@njit(parallel=True, fastmath=FAST, cache=True)
def padded_pass_row(P, Q, cols, inv_count, factor, gain, k, C):
    """:func:`padded_pass_along` without a cap, when ``Q``'s other rows already hold ``P``'s
    (they do not move along axis k, and the box leaves a coordinate inside it as it is): reads
    and writes row k alone, about half the bytes a vertex."""
    n = cols.shape[1]
    zero = P[0, n]
    for i in prange(n):
        x = _along(P, cols, inv_count, factor, gain, k, i, zero)
        if C is not None:
            x = _unit(x, C[k, i], C.dtype.type(1))
        Q[k, i] = x


@njit(parallel=True, fastmath=FAST, cache=True)
def constrain_columns(Q, n, C, S, r2, metric, diamond):
    """The constraint in place on the first ``n`` columns of ``Q``: the unit box or, when
    ``diamond``, the unit L1 ball around ``C[:, i]`` (``C`` None: neither); then the cap of
    :func:`_cap` (``S`` None: none)."""
    for i in prange(n):
        px, py, pz = Q[0, i], Q[1, i], Q[2, i]
        if C is not None:
            if diamond:
                cx, cy, cz = C[0, i], C[1, i], C[2, i]
                u0, u1, u2 = project_l1(px - cx, py - cy, pz - cz)
                px, py, pz = cx + u0, cy + u1, cz + u2
            else:
                px, py, pz = _box_cap(i, px, py, pz, C, None, r2, metric)
        if S is not None:
            px, py, pz = _cap(i, px, py, pz, S, r2, metric)
        Q[0, i] = px
        Q[1, i] = py
        Q[2, i] = pz


@njit(cache=True)
def padded_passes(a, b, cols, inv_count, ext, level_at, factors, on_axis, gain, axis, along,
                  diamond, C, S, r2, metric):
    """Run ``len(factors)`` passes alternating between ``a`` and ``b`` (pass ``p`` uses
    ``factors[p]`` and the axis map when ``on_axis[p]``; ``along`` >= 0: the axis map is
    ``e_along e_alongᵀ``, :func:`padded_pass_along`), in one call: no Python work between
    passes. ``diamond``: ``C`` is the centre of diamonds, applied after each pass
    (:func:`constrain_columns`), not of boxes. Returns 0 when the result is in ``a``, 1 when
    in ``b``."""
    n = cols.shape[1]
    run = 0  # passes along one axis without a cap just before this one
    for p in range(factors.shape[0]):
        src, dst = (a, b) if p % 2 == 0 else (b, a)
        helper_sums(src, ext, level_at, n)
        f = factors[p]
        if diamond:
            if on_axis[p] and along >= 0:
                padded_pass_along(src, dst, cols, inv_count, f, gain, along, None, None, r2,
                                  metric)
            elif on_axis[p]:
                padded_pass(src, dst, cols, inv_count, f, gain, axis, None, None, r2, metric)
            else:
                padded_pass(src, dst, cols, inv_count, f, gain, None, None, None, r2, metric)
            constrain_columns(dst, n, C, S, r2, metric, True)
        elif on_axis[p] and along >= 0 and S is None and run >= 2:
            # the last two wrote the other rows clamped into the box, and clamped again they
            # stay: a and b agree there
            padded_pass_row(src, dst, cols, inv_count, f, gain, along, C)
        elif on_axis[p] and along >= 0:
            padded_pass_along(src, dst, cols, inv_count, f, gain, along, C, S, r2, metric)
        elif on_axis[p]:
            padded_pass(src, dst, cols, inv_count, f, gain, axis, C, S, r2, metric)
        else:
            padded_pass(src, dst, cols, inv_count, f, gain, None, C, S, r2, metric)
        run = run + 1 if not diamond and on_axis[p] and along >= 0 and S is None else 0
    return factors.shape[0] % 2
