"""Time the writers on a million triangles: STL, PLY, OBJ, 3MF and GLB, against trimesh's exporters
when trimesh is installed (same mesh, same process).

Usage: python benchmarks/bench_export.py [--repeat N]
The mesh is 13 icospheres of 81,920 triangles side by side (1,064,960 triangles), the same one
the export tests check for size. Best of N runs, interleaved; file sizes in MB.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from helpers.meshes import tiled_spheres  # noqa: E402

from anatomesh.core.export import SCENE_FORMATS, write_mesh  # noqa: E402
from anatomesh.core.model.mesh import Mesh  # noqa: E402


def writers(mesh: Mesh):
    out = {f"ours {fmt}": (lambda p, fmt=fmt: write_mesh(mesh, p, fmt), fmt) for fmt in ("stl", "ply", "obj")}
    out.update({f"ours {fmt}": (lambda p, fmt=fmt: SCENE_FORMATS[fmt]([mesh], p), fmt) for fmt in ("3mf", "glb")})
    try:
        import trimesh
    except ImportError:
        return out
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    for fmt in ("stl", "ply", "obj", "3mf", "glb"):
        out[f"trimesh {fmt}"] = (lambda p, fmt=fmt: tm.export(str(p), file_type=fmt), fmt)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    v, f = tiled_spheres()
    mesh = Mesh(v, f, name="spheres")
    fns = writers(mesh)
    best = {k: float("inf") for k in fns}
    sizes = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            for name, (fn, fmt) in fns.items():
                path = Path(tmp) / f"{name.replace(' ', '_')}.{fmt}"
                t0 = time.perf_counter()
                fn(path)
                best[name] = min(best[name], time.perf_counter() - t0)
                sizes[name] = path.stat().st_size / 1e6
    print(f"{mesh.n_faces:,} triangles, {mesh.n_vertices:,} vertices; best of {args.repeat}")
    for name in fns:
        fmt = name.split()[1]
        peer = best.get(f"trimesh {fmt}")
        ratio = f"  {best[name] / peer:5.2f}x trimesh" if peer and name.startswith("ours") else ""
        print(f"  {name:<12} {best[name]:7.3f} s  {sizes[name]:7.1f} MB{ratio}")


if __name__ == "__main__":
    main()
