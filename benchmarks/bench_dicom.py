"""Time the DICOM series reader on the real series in shared/data (headers, pixels, layout).

Usage: python benchmarks/bench_dicom.py [folder ...]  (default: the chest, head and JPEG 2000 CTs)
The first read in a process includes loading numba's cached kernel; the best of 3 is also given,
with the CPU time (all threads), which says more than wall time on a shared machine.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from anatomesh.core.io.dicom import read_dicom

DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA",
                           Path(__file__).resolve().parents[2] / "shared" / "data"))
DEFAULT = ["itkelastix_chest_ct", "slicer_ctheadaxial", "totalsegmentator/example_ct_dicom"]


def main(folders) -> None:
    for folder in folders:
        path = Path(folder) if Path(folder).is_dir() else DATA / folder
        times, cpu = [], []
        for _ in range(3):
            t0, c0 = time.perf_counter(), time.process_time()
            vol = read_dicom(path)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        print(f"{path.name}: {vol.shape} {vol.data.dtype} {vol.meta['transfer_syntax']}: "
              f"first {times[0]:.2f} s, best {min(times):.2f} s wall "
              f"(CPU {min(cpu):.2f} s, all threads)")


if __name__ == "__main__":
    main(sys.argv[1:] or DEFAULT)
