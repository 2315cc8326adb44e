"""Freed heap memory handed back to the system (glibc's malloc_trim)."""
import sys

import numpy as np
import pytest

from anatomesh.core.model.memory import release_free_memory


def resident_mib() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's heap: Linux only")
def test_free_holes_in_the_heap_go_back_to_the_system():
    """200 MB of 100 kB arrays (below malloc's mmap threshold: in the heap), nine in ten freed
    while every tenth keeps the heap's top in place: free() cannot return those holes, the
    release does."""
    blocks = [np.ones(12_500) for _ in range(2_000)]  # 100 kB each, every page touched
    kept = blocks[::10]
    del blocks
    before = resident_mib()
    assert release_free_memory()
    after = resident_mib()
    assert before - after > 100, (before, after)
    assert all(float(b.sum()) == 12_500 for b in kept)  # what is still in use is untouched
