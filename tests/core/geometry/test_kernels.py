"""The shared kernel helpers of ``core/geometry/kernels``."""
import re
from pathlib import Path

import numpy as np
from numba import njit, prange

from anatomesh.core.geometry.kernels import scalar_loop


def _gather_sum(marked: bool):
    """A fresh (uncached) kernel summing ``p`` over 8 index columns, the shape of the umbrella
    pass's neighbour loop, with or without :func:`scalar_loop`."""
    def kernel(p, cols, out):
        for i in prange(cols.shape[1]):
            if marked:
                scalar_loop()
            s = 0.0
            for a in range(8):
                s += p[cols[a, i]]
            out[i] = s
    return njit(parallel=True)(kernel)


def _gathers(kernel) -> int:
    asm = "".join(kernel.inspect_asm(sig) for sig in kernel.signatures)
    return len(re.findall(r"^\s*v\w*gather\w*", asm, re.M))


def test_scalar_loop_keeps_the_loop_scalar_and_changes_no_result():
    rng = np.random.default_rng(3)
    p = rng.normal(size=5001)
    cols = rng.integers(0, 5001, size=(8, 5000)).astype(np.uint32)
    expected = p[cols].sum(axis=0)
    scalar_loop()  # outside numba: does nothing
    for marked in (False, True):
        out = np.zeros(5000)
        kernel = _gather_sum(marked)
        kernel(p, cols, out)
        np.testing.assert_allclose(out, expected, rtol=1e-12)
        if marked:
            assert _gathers(kernel) == 0
        else:
            vectorized = _gathers(kernel)
    # on a CPU with vector gathers (AVX2/AVX-512) the unmarked loop used them
    cpu = Path("/proc/cpuinfo")
    assert vectorized > 0 or not (cpu.exists() and re.search(r"avx2|avx512", cpu.read_text()))
