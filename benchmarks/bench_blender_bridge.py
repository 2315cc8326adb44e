"""Benchmark: numpy → Blender mesh through the attribute API vs ``Mesh.from_pydata``.

Builds a closed torus of ~1.08 M triangles (735 x 735 grid, 540 k vertices) and times
``anatomesh.addon.scene.bridge.new_mesh`` (best of 3), moving the vertices in place (the live smoothing
update), reading them back, and one ``from_pydata`` call for comparison. The "attribute floor"
(0.38 s on the reference machine, REFERENCE.md) is the cost of the bare attribute calls; the
target is new_mesh <= 1.2x that floor.

The Smooth panel's live slider end to end, on real scans: ``benchmarks/bench_live.py``.

Run: ``python benchmarks/bench_blender_bridge.py [grid]`` (needs the bpy module).
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="anatomesh_bench_"))
import bpy  # noqa: E402
import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FLOOR_S = 0.38


def torus(n: int):
    """Closed torus (R=100, r=30 mm) as an n x n quad grid split into 2 n² triangles."""
    u = np.linspace(0, 2 * np.pi, n, endpoint=False)
    U, V = np.meshgrid(u, u, indexing="ij")
    x = (100 + 30 * np.cos(V)) * np.cos(U)
    y = (100 + 30 * np.cos(V)) * np.sin(U)
    z = 30 * np.sin(V)
    verts = np.stack([x, y, z], -1).reshape(-1, 3).astype(np.float32)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a, b = i * n + j, ((i + 1) % n) * n + j
    c, d = ((i + 1) % n) * n + (j + 1) % n, i * n + (j + 1) % n
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)]).astype(np.int32)
    return verts, faces


def load_bridge():
    """The bridge module from this checkout (it only needs bpy and numpy)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("anatomesh_bridge", REPO / "addon" / "scene" / "bridge.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 735
    bridge = load_bridge()
    v, f = torus(n)
    print(f"torus: {len(v):,} vertices, {len(f):,} triangles; Blender {bpy.app.version_string}")
    t_new, me = best(lambda: bridge.new_mesh("bench", v, f))
    t_set, _ = best(lambda: bridge.set_positions(me, v * 1.01))
    t_get, _ = best(lambda: bridge.arrays(me))
    t = time.perf_counter()
    me2 = bpy.data.meshes.new("pydata")
    me2.from_pydata(v, [], f)
    me2.update()
    t_py = time.perf_counter() - t
    assert len(me.polygons) == len(me2.polygons) and len(me.edges) == len(me2.edges)
    print(f"new_mesh (attribute API) {t_new:7.3f} s  ({t_new / FLOOR_S:.2f}x the {FLOOR_S} s floor)")
    print(f"from_pydata              {t_py:7.3f} s  ({t_py / t_new:.1f}x slower)")
    print(f"set_positions (live)     {t_set:7.3f} s")
    print(f"arrays (read back)       {t_get:7.3f} s")


if __name__ == "__main__":
    main()
