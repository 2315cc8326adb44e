"""Cohorts: studies per minute of ``anatomesh.app.batch.run`` with 1 and 2 workers (process pool
and Dask distributed), its overhead per study against a bare loop of ``app.run.run``, and the
peak memory of a worker.

Usage: python benchmarks/bench_batch.py [--copies K] [--rounds N] [--configs bare,pool-1,...]

Studies: K copies each of three real maps from ../shared/data (TotalSegmentator CT, 41 labels,
122x101x30; TotalSegmentator MR, 23 labels, 117x91x20; pyradiomics brain tumour, 1 label,
256x256x25), the default recipe (organ smoothing, STL). Every configuration runs in a fresh
Python process (each pays its own start-up: imports, worker processes, numba's cached kernels),
configurations interleaved, best of N rounds:

  bare     a loop of app.run.run over the studies (one output folder each)
  pool-1/2 app.batch.run, the process pool with 1/2 workers
  dask-1/2 app.batch.run on a distributed.LocalCluster of 1/2 worker processes, 1 thread each
           (the cluster is started before the clock)

Overhead per study: the batch's own work inside a worker (hashing the input, thumbnail, report
stamp, rename) against the pipeline's time there, and end to end (pool-1 against bare, fixed
start-up included). Peak memory: the largest peak resident set of a worker process. The load
average of the machine (shared with other jobs) is printed with each run.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", REPO.parent / "shared" / "data"))
MAPS = {"ct": DATA / "totalsegmentator" / "example_seg.nii.gz",
        "mr": DATA / "totalsegmentator" / "example_seg_mr.nii.gz",
        "brain": DATA / "pyradiomics_brain1" / "brain1_label.nrrd"}
CONFIGS = ("bare", "pool-1", "pool-2", "dask-1", "dask-2")


def make_studies(folder: Path, copies: int) -> int:
    folder.mkdir(parents=True)
    for name, src in MAPS.items():
        suffix = ".nrrd" if src.name.endswith(".nrrd") else ".nii.gz"
        for i in range(copies):
            shutil.copy(src, folder / f"{name}{i:02d}{suffix}")
    return copies * len(MAPS)


def child(config: str, studies: Path, out: Path) -> dict:
    """One configuration in this (fresh) process; returns its measures."""
    from anatomesh.app import batch
    from anatomesh.app.flow.recipe import Recipe
    from anatomesh.app.flow.run import run

    paths = sorted(studies.iterdir())
    load0 = os.getloadavg()[0]
    if config == "bare":
        t0 = time.perf_counter()
        for p in paths:
            run(Recipe(input=str(p), out_dir=str(out / p.name.split(".")[0])))
        wall = time.perf_counter() - t0
        return {"wall": wall, "load": [load0, os.getloadavg()[0]], "n": len(paths)}
    kind, n = config.split("-")
    if kind == "pool":
        t0 = time.perf_counter()
        rows = batch.run(studies, None, out, workers=int(n))
        wall = time.perf_counter() - t0
    else:
        from distributed import LocalCluster

        with LocalCluster(n_workers=int(n), threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            t0 = time.perf_counter()
            rows = batch.run(studies, None, out, scheduler=cluster)
            wall = time.perf_counter() - t0
    assert all(r["status"] == "done" for r in rows), [r["error"] for r in rows if r["error"]]
    stamps = [json.loads((out / d / "report.json").read_text())["batch"] for d in {r["study"] for r in rows}]
    return {"wall": wall, "load": [load0, os.getloadavg()[0]], "n": len(stamps),
            "seconds": sum(s["seconds"] for s in stamps), "run_seconds": sum(s["run_seconds"] for s in stamps),
            "peak_mb": max(s["worker_peak_mb"] or 0 for s in stamps)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--copies", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--configs", default=",".join(CONFIGS))
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--studies", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child, Path(args.studies), Path(args.out))))
        return
    configs = args.configs.split(",")
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        n = make_studies(Path(tmp, "studies"), args.copies)
        print(f"{n} studies ({args.copies} copies of ct 41 labels, mr 23 labels, brain 1 label), default "
              f"recipe; {os.cpu_count()} cores; best of {args.rounds} rounds")
        for r in range(args.rounds):
            for config in configs:
                out = Path(tmp, f"out-{config}-{r}")
                done = subprocess.run([sys.executable, __file__, "--child", config, "--studies",
                                       str(Path(tmp, "studies")), "--out", str(out)],
                                      capture_output=True, text=True)
                if done.returncode:
                    raise SystemExit(f"{config} failed:\n{done.stderr[-3000:]}")
                m = json.loads(done.stdout.strip().splitlines()[-1])
                print(f"  round {r + 1} {config:<7} {m['wall']:7.1f} s  {n / m['wall'] * 60:6.1f} studies/min  "
                      f"load {m['load'][0]:.1f}->{m['load'][1]:.1f}", flush=True)
                if config not in best or m["wall"] < best[config]["wall"]:
                    best[config] = m
                shutil.rmtree(out, ignore_errors=True)
    report(best, n)


def report(best: dict, n: int) -> None:
    print("best:")
    for config, m in best.items():
        extra = ""
        if "seconds" in m:
            inside = (m["seconds"] - m["run_seconds"]) / m["run_seconds"] * 100
            extra = (f"  per study {m['seconds'] / n:5.2f} s in the worker (pipeline {m['run_seconds'] / n:5.2f} s, "
                     f"batch's own work +{inside:.1f} %), worker peak {m['peak_mb']:.0f} MiB")
        print(f"  {config:<7} {m['wall']:7.1f} s  {n / m['wall'] * 60:6.1f} studies/min{extra}")
    if "bare" in best and "pool-1" in best:
        bare, pool = best["bare"]["wall"], best["pool-1"]["wall"]
        print(f"  end to end, pool-1 vs bare app.run.run loop: {(pool - bare) / n:+.2f} s per study "
              f"({(pool / bare - 1) * 100:+.1f} %, start-up of the workers included)")


if __name__ == "__main__":
    main()
