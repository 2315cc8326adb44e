"""Benchmark: the first run after install, with a cold numba cache (target: the first
extraction after install is usable within 10 s on the sample).

1. Blender (the ``bpy`` module, the add-on enabled, a fresh numba cache): the background warm-up
   starts (what enabling the extension does), the sample's 41-label map is imported at once with
   ``bpy.ops.anatomesh.import_scan(extract=True)`` (deferred while its kernels compile, run by
   itself when they are ready), and the times are from the start to: the 41 objects in the scene,
   the organs smoothed (their first smoothing waits for the "label smoothing" step and then runs
   by itself), the sliders' smoothing kernels ready, every kernel compiled; and how many kernels
   Blender's own process compiled meanwhile (0: it never froze compiling).
2. The command line's warm-up, ``python -m anatomesh.app.warmup --default-only`` in a fresh cache,
   with one process and with two sharing the compiling: when each step became ready.

Run: ``python benchmarks/bench_first_run.py [--skip-cli]`` (about 5 min on 2 cores).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "data" / "sample" / "example_seg.nii.gz"


def blender_first_run() -> None:
    """Part 1: enable, import at once, wait for the objects, the smoothing, everything."""
    import bpy

    import anatomesh
    from anatomesh.addon.scene import bridge
    from anatomesh.addon.operators import warmup
    from anatomesh.app.warmup.compile import counting_compiles

    anatomesh.register()
    t0 = time.perf_counter()
    assert warmup.start(force=True)  # what enabling the extension does in a Blender with a UI
    with counting_compiles() as compiled:  # in Blender's own process
        assert bpy.ops.anatomesh.import_scan(filepath=str(SAMPLE), extract=True) == {"FINISHED"}
        marks = wait_for_warmup(bpy.context.scene, warmup, bridge, t0)
    total = time.perf_counter() - t0
    print(f"Blender, cold cache ({os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}): "
          f"{marks['objects'][1]} objects of the sample after {marks['objects'][0]:.1f} s "
          f"(target 10 s); the organs smoothed after {marks['smoothed']:.1f} s; the sliders' "
          f"smoothing kernels ready after {marks['smoothing']:.1f} s; every kernel after "
          f"{total:.1f} s; kernels compiled in Blender's process: {len(compiled)}; error: "
          f"{warmup.STATE['error'] or 'none'}")


def wait_for_warmup(scene, warmup, bridge, t0) -> dict:
    """Run the add-on's timer until the warm-up ends; the times (seconds since ``t0``) of the
    marks: ``objects`` (with their count), ``smoothed``, ``smoothing`` (the sliders' kernels)."""
    import bpy

    marks = {}
    while warmup.STATE["running"] or "smoothed" not in marks:
        warmup._poll()  # the add-on's timer (Blender runs it every 0.25 s)
        now = time.perf_counter() - t0
        coll = bpy.data.collections.get(scene.anatomesh.last_collection or "")
        if coll is not None and "objects" not in marks:
            marks["objects"] = (now, len(coll.all_objects))
        if coll is not None and "smoothed" not in marks:
            obj = coll.all_objects[0]
            rest = bridge.point_attribute(obj.data, bridge.REST_ATTRIBUTE, "vector")
            if rest is not None and abs(bridge.positions(obj.data) - rest).max() > 1e-3:
                marks["smoothed"] = now
        if warmup.ready("smoothing") and "smoothing" not in marks:
            marks["smoothing"] = now
        time.sleep(0.05)
    return marks


def cli_warmups() -> None:
    """Part 2: the command line's warm-up in a fresh cache, 1 and 2 processes."""
    for lanes in (2, 1):
        cache = tempfile.mkdtemp(prefix="anatomesh_cold_cli_")
        cmd = [sys.executable, "-m", "anatomesh.app.warmup", "--default-only", "--lanes", str(lanes)]
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True,
                             env=dict(os.environ, NUMBA_CACHE_DIR=cache))
        steps, times = [], []
        for line in p.stdout:  # "warmup i/n step" once the steps before it are ready; "warmup done"
            if line.startswith("warmup "):
                steps.append(line.split(" ", 2)[2].strip())
                times.append(time.perf_counter() - t0)
        p.wait()
        ready = [f"{step} {t:.1f} s" for step, t in zip(steps[:-1], times[1:])]
        print(f"warmup, {lanes} process(es), ready after: " + "; ".join(ready))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-cli", action="store_true")
    args = ap.parse_args(argv)
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="anatomesh_bench_"))
    # a cold cache, before numba is imported: this process and its children
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="anatomesh_cold_blender_")
    blender_first_run()
    if not args.skip_cli:
        cli_warmups()


if __name__ == "__main__":
    main()
