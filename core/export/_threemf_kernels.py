"""Numba kernels that format rows of numbers into XML text (ASCII bytes) for the 3MF writer.

A row template is one uint8 array ``tpl`` cut at ``cuts`` (k + 2 offsets for k numbers): row =
``tpl[cuts[0]:cuts[1]] num0 tpl[cuts[1]:cuts[2]] num1 … tpl[cuts[k]:cuts[k+1]]``.

Floats get 9 significant digits like C's ``%.9g`` (fixed notation for exponents -4..8, else
``d.ddde±XX``; trailing zeros dropped). Nine digits always read back to the same float32: the
decimal step at 9 digits is at most 1e-8 of the value, below half a float32 ulp (≥ 2^-25 ≈ 3e-8
of it), so the one-rounding error of the float64 scaling used here cannot pick a wrong float32.
"""
import numpy as np
from numba import njit

#: bytes a row may need beyond its template: per number at most 16 ("-1.23456789e-308")
MAX_NUMBER_BYTES = 24


@njit(cache=True)
def _put_uint(out, pos, x):
    """Decimal digits of the non-negative int ``x`` at ``out[pos:]``; returns the new position."""
    if x == 0:
        out[pos] = 48
        return pos + 1
    n = 0
    y = x
    while y > 0:
        y //= 10
        n += 1
    for i in range(n - 1, -1, -1):
        out[pos + i] = 48 + x % 10
        x //= 10
    return pos + n


@njit(cache=True)
def _put_float9(out, pos, x):
    """``x`` (finite float64) with 9 significant digits; returns the new position."""
    if x == 0.0:
        out[pos] = 48
        return pos + 1
    if x < 0.0:
        out[pos] = 45  # '-'
        pos += 1
        x = -x
    e = int(np.floor(np.log10(x)))
    m = np.int64(0)
    for _ in range(3):  # log10 may be off by one near powers of ten
        p = 8 - e
        y = x * 10.0 ** p if p >= 0 else x / 10.0 ** (-p)
        m = np.int64(np.rint(y))  # half to even, as C does on exact ties
        if m >= 1000000000:
            e += 1
        elif m < 100000000:
            e -= 1
        else:
            break
    if m >= 1000000000:  # rounding carried into a tenth digit (e.g. 9.999999999)
        m //= 10
        e += 1
    digits = np.empty(9, np.int64)
    for i in range(8, -1, -1):
        digits[i] = m % 10
        m //= 10
    nd = 9
    while nd > 1 and digits[nd - 1] == 0:
        nd -= 1
    if -4 <= e < 9:
        if e < 0:
            out[pos] = 48
            out[pos + 1] = 46
            pos += 2
            for _ in range(-e - 1):
                out[pos] = 48
                pos += 1
            for i in range(nd):
                out[pos] = 48 + digits[i]
                pos += 1
        else:
            for i in range(e + 1):
                out[pos] = 48 + digits[i]
                pos += 1
            if nd > e + 1:
                out[pos] = 46
                pos += 1
                for i in range(e + 1, nd):
                    out[pos] = 48 + digits[i]
                    pos += 1
        return pos
    out[pos] = 48 + digits[0]
    pos += 1
    if nd > 1:
        out[pos] = 46
        pos += 1
        for i in range(1, nd):
            out[pos] = 48 + digits[i]
            pos += 1
    out[pos] = 101  # 'e'
    out[pos + 1] = 45 if e < 0 else 43
    pos += 2
    ae = -e if e < 0 else e
    if ae < 10:
        out[pos] = 48
        pos += 1
    return _put_uint(out, pos, ae)


@njit(cache=True)
def _put_bytes(out, pos, tpl, a, b):
    for i in range(a, b):
        out[pos] = tpl[i]
        pos += 1
    return pos


@njit(cache=True)
def float_rows(values, tpl, cuts, out):
    """Rows of ``values`` (n, k) float64 (finite) into ``out`` (uint8, large enough:
    n * (len(tpl) + k * MAX_NUMBER_BYTES)); returns the number of bytes written."""
    pos = 0
    n, k = values.shape
    for r in range(n):
        for j in range(k):
            pos = _put_bytes(out, pos, tpl, cuts[j], cuts[j + 1])
            pos = _put_float9(out, pos, values[r, j])
        pos = _put_bytes(out, pos, tpl, cuts[k], cuts[k + 1])
    return pos


@njit(cache=True)
def uint_rows(values, tpl, cuts, out):
    """Rows of ``values`` (n, k) int64 (≥ 0) into ``out``; returns the number of bytes written."""
    pos = 0
    n, k = values.shape
    for r in range(n):
        for j in range(k):
            pos = _put_bytes(out, pos, tpl, cuts[j], cuts[j + 1])
            pos = _put_uint(out, pos, values[r, j])
        pos = _put_bytes(out, pos, tpl, cuts[k], cuts[k + 1])
    return pos
