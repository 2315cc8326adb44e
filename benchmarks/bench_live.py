"""Benchmark: the Smooth panel's live slider in Blender, end to end, with the full guarded default.

A scan is imported and extracted with the add-on's operators (``bpy.ops.anatomesh.import_scan``,
Blender as the ``bpy`` module), then the scan's smoothing strength is changed the way the slider
changes it (``collection.anatomesh.smooth_strength = x``): the property's update re-smooths from
the cached unsmoothed surfaces with the command line's driver (``organ``: filter in the voxel
cells, staircase pass, fold guard, volume step, untangling) and writes the positions into the
objects. The time is from the assignment to its return, best of ``--repeat`` new strengths after
one warm-up change; with Blender's evaluation of the changed objects for the viewport (their
modifiers, such as the drawn gap between touching structures) it is printed beside. Targets: 61-label TotalSegmentator map <= 150 ms; the chest CT's
300 HU (bone) isosurface, ~1M triangles, <= 500 ms.

Run: ``python benchmarks/bench_live.py [--repeat 8] [--cases labels61,bone]`` (needs the bpy
module; numba's cache for the add-on goes to build/numba-cache-bench-live).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", REPO.parent / "shared" / "data"))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="anatomesh_bench_"))
os.environ.setdefault("NUMBA_CACHE_DIR", str(REPO / "build" / "numba-cache-bench-live"))
import bpy  # noqa: E402

CASES = {
    "labels61": dict(filepath=str(DATA / "totalsegmentator" / "example_seg_fast_force_split.nii.gz"),
                     label_table=str(DATA / "totalsegmentator" / "label_names_total_and_total_mr.json"),
                     target=0.150),
    "bone": dict(filepath=str(DATA / "itkelastix_chest_ct"), levels="300", target=0.500),
}


def extract(case: dict):
    """Import + extract one case with the operators; returns the scan collection."""
    scene = bpy.context.scene
    if "levels" in case:
        assert bpy.ops.anatomesh.import_scan(filepath=case["filepath"], extract=False) == {"FINISHED"}
        assert bpy.ops.anatomesh.extract(levels=case["levels"]) == {"FINISHED"}
    else:
        assert bpy.ops.anatomesh.import_scan(filepath=case["filepath"], label_table=case["label_table"],
                                             extract=True) == {"FINISHED"}
    return bpy.data.collections[scene.anatomesh.last_collection]


def slider(coll, repeat: int):
    """Best seconds of one strength change (the property update re-smooths) over ``repeat``, and
    of the change with the viewport's evaluation of the objects after it."""
    strengths = [0.45 + 0.01 * i for i in range(repeat + 1)]
    coll.anatomesh.smooth_strength = strengths[0]  # warm-up: the session's caches
    bpy.context.evaluated_depsgraph_get()
    best, best_shown = float("inf"), float("inf")
    for s in strengths[1:]:
        t = time.perf_counter()
        coll.anatomesh.smooth_strength = s
        best = min(best, time.perf_counter() - t)
        bpy.context.evaluated_depsgraph_get()
        best_shown = min(best_shown, time.perf_counter() - t)
    return best, best_shown


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=8)
    ap.add_argument("--cases", default="labels61,bone")
    args = ap.parse_args(argv)
    import anatomesh

    from anatomesh.addon.operators import warmup

    anatomesh.register()
    t = time.perf_counter()
    warmup.wait()  # the first-run compile in the background (nothing to do on a warm cache)
    print(f"kernels ready after {time.perf_counter() - t:.1f} s")
    print(f"Blender {bpy.app.version_string}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for name in args.cases.split(","):
        case = CASES[name]
        t = time.perf_counter()
        coll = extract(case)
        t_extract = time.perf_counter() - t
        faces = sum(len(o.data.polygons) for o in coll.objects)
        best, shown = slider(coll, args.repeat)
        print(f"{name:9s} {len(coll.objects):3d} objects {faces:>9,} triangles: import+extract+smooth "
              f"{t_extract:6.2f} s; live slider (organ, all guards) best {1000 * best:6.0f} ms "
              f"(target <= {1000 * case['target']:.0f} ms), evaluated for the viewport {1000 * shown:6.0f} ms")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
