"""Generic-CPU kernels against kernels compiled for this CPU: whole ``anatomesh mesh`` commands.

Release wheels and extension zips ship numba's kernels compiled with ``NUMBA_CPU_NAME=generic``
(``tools/build_wheel.py``); this measures what that costs. Each case of
``benchmarks/bench_command.py`` (chest CT ``--level 300``, the 61-label map, the 834x512x512
body+bone map) and the bundled sample runs as a fresh process with two numba caches of its own:
one compiled for this CPU, one for a generic CPU (filled by an untimed first run). Runs are
interleaved and the best of ``--repeat`` kept; the ratio is generic / host. ::

    python benchmarks/bench_generic_cpu.py [--repeat 3] [--cases ct,labels61,big,sample]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bench_command as bc


def case_args(name: str, work: Path) -> list:
    """The input (path and extra flags) of a case; the big map is built in ``work``."""
    return {"ct": lambda: [str(bc.CT), "--level", "300"], "labels61": lambda: [str(bc.LABELS61)],
            "big": lambda: [str(bc.build_big(work))], "sample": lambda: [str(bc.SAMPLE)]}[name]()


def timed(args, out: Path, env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "anatomesh.app.cli", "mesh", *args, "--out", str(out), "--overwrite"],
                   env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--cases", default="ct,labels61,big,sample")
    args = p.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="anatomesh_generic_"))
    inputs = {name: case_args(name, work) for name in args.cases.split(",")}
    base = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    envs = {"host": dict(base, NUMBA_CACHE_DIR=str(work / "cache-host")),
            "generic": dict(base, NUMBA_CACHE_DIR=str(work / "cache-generic"), NUMBA_CPU_NAME="generic")}
    print(f"{'case':>9} {'host s':>7} {'generic s':>9} {'generic/host':>12}")
    for case, a in inputs.items():
        best = {}
        for rep in range(args.repeat + 1):  # the first round fills the caches, untimed
            for name, env in envs.items():
                seconds = timed(a, work / f"out-{case}-{name}", env)
                if rep:
                    best[name] = min(best.get(name, seconds), seconds)
        print(f"{case:>9} {best['host']:>7.2f} {best['generic']:>9.2f} {best['generic'] / best['host']:>12.2f}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
