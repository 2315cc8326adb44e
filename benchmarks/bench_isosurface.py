"""Benchmark: ``isosurface()`` against VTK's flying edges, scikit-image and one numpy pass.

Data: the real chest CT (``shared/data/itkelastix_chest_ct``, 512x512x141 int16 HU, read with
``anatomesh.core.load``; its C-contiguous layout sweeps the slice axis) at a bone (300 HU) and a
skin (-500 HU) level, the same scan copied to Fortran order (in-plane axis contiguous, like a
NIfTI file) and a 512x512x400 CT-sized volume made by tiling the chest CT along z (forward,
mirrored, forward; cropped to 400 slices, so no seams appear).

Reference timings, all warm (best of N, wall clock; the three run in turn, N times):

* ``vtkFlyingEdges3D`` (VTK wheel) with the STDThread SMP backend on 2 threads, normals on,
  scalars off, on the same memory (no copy);
* ``np.count_nonzero(vol > level)``: one numpy pass over the data;
* ``skimage.measure.marching_cubes`` (Lewiner), full mode only (and bone in --quick).

Then each pass of ours alone (classify, count, vertices, triangles; interleaved with the numpy
pass) and the *write floor*: ``np.empty`` + ``fill`` of three arrays the size of the output mesh,
the cost of producing the output bytes alone (page faults and one memset), before any extraction.

Also measured in fresh subprocesses: the peak memory of one call (VmHWM after resetting it via
/proc/self/clear_refs, and the tracemalloc peak) against the input and output sizes, and how much
the first call in a new process costs over a warm call (numba's cache already filled).

Run: ``python benchmarks/bench_isosurface.py [--quick] [--repeat N]``. Timings on a shared
machine are noisy: the load average is printed with the results.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from anatomesh.core import load
from anatomesh.core.extract.isosurface import isosurface
from anatomesh.core.model.mesh import degenerate_faces, duplicate_vertices

DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA",
                           Path(__file__).resolve().parents[2] / "shared" / "data"))
LEVELS = {"bone": 300, "skin": -500}


def best_of(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def interleaved(fns, repeat, medians=None):
    """Best time of each callable, running them in turn (a shared machine's speed drifts).

    ``medians``: a list that receives each callable's median time (the spread of a noisy run).
    """
    times = [[] for _ in fns]
    outs = [None] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            outs[i] = fn()
            times[i].append(time.perf_counter() - t0)
    if medians is not None:
        medians[:] = [float(np.median(t)) for t in times]
    return [min(t) for t in times], outs


def pass_times(data, affine, level, repeat):
    """Best time of each pass of ``isosurface`` (the private kernels, 2 threads) and of one
    numpy pass, interleaved: where the time goes."""
    import importlib

    from anatomesh.core.extract import _isosurface_kernels as K
    from anatomesh.core.extract.mc_table import TRI_COUNT

    iso = importlib.import_module("anatomesh.core.extract.isosurface")
    view, perm = iso._sweep_view(data)
    m, n, flip = iso._frame(np.asarray(affine, float), perm)
    th, _ = iso._thresholds([level], view.dtype)
    nz, ny, nx = view.shape
    bits = np.zeros((1, nz, ny, (nx + 63) // 64), np.uint64)
    n_above = np.zeros((1, nz), np.int64)
    rows = [np.empty((nz, ny), np.int32) for _ in range(4)]
    slab_v, slab_t = np.empty(nz, np.int64), np.empty(nz, np.int64)
    K.classify(view, th, 0, bits, n_above)
    K.count(bits[0], nx, TRI_COUNT, *rows, slab_v, slab_t)
    v_start, n_v = iso._exclusive_cumsum(slab_v)
    t_start, n_t = iso._exclusive_cumsum(slab_t)
    verts, normals = np.empty((n_v, 3), np.float32), np.empty((n_v, 3), np.float32)
    faces = np.empty((n_t, 3), np.int32)
    table = iso._TRI_EDGES_FLIPPED if flip else iso._TRI_EDGES
    fns = [lambda: K.classify(view, th, 0, bits, n_above),
           lambda: K.count(bits[0], nx, TRI_COUNT, *rows, slab_v, slab_t),
           lambda: K.emit_vertices(view, bits[0], float(level), iso.T_MIN, 0, m, n, *rows[:3], v_start,
                                   verts, normals),
           lambda: K.emit_triangles(bits[0], nx, TRI_COUNT, table, *rows, v_start, t_start, faces),
           lambda: output_write(n_v, n_t),
           lambda: np.count_nonzero(data > level)]
    best, _ = interleaved(fns, repeat)
    return dict(zip(["classify", "count", "vertices", "triangles", "write_floor", "numpy"], best),
                n_vertices=n_v, n_faces=n_t)


def output_write(n_vertices, n_faces):
    """The floor of any isosurface extractor's output: allocate the three output arrays of this
    size and write every byte once (np.empty + fill: page faults and a memset, one thread)."""
    out = (np.empty((n_vertices, 3), np.float32), np.empty((n_vertices, 3), np.float32),
           np.empty((n_faces, 3), np.int32))
    for a in out:
        a.fill(1)
    return out


def vtk_flying_edges(data, level):
    """A callable running vtkFlyingEdges3D on ``data`` (its contiguous axis as VTK's x)."""
    import vtk
    from vtk.util import numpy_support

    vtk.vtkSMPTools.SetBackend("STDThread")
    vtk.vtkSMPTools.Initialize(2)
    if data.flags.c_contiguous:
        flat, dims = data.ravel(order="C"), data.shape[::-1]
    else:
        flat, dims = data.ravel(order="F"), data.shape
    img = vtk.vtkImageData()
    img.SetDimensions(*[int(d) for d in dims])
    img.GetPointData().SetScalars(numpy_support.numpy_to_vtk(flat, deep=False))
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(img)
    fe.SetValue(0, float(level))
    fe.ComputeNormalsOn()
    fe.ComputeScalarsOff()

    def run():
        fe.Modified()
        fe.Update()
        return fe.GetOutput()

    return run, flat


def vtk_arrays(poly):
    from vtk.util import numpy_support

    pts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData())
    polys = numpy_support.vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    return pts, polys


def tiled_400(ct):
    stack = np.concatenate([ct, ct[:, :, ::-1], ct], axis=2)[:, :, :400]
    return np.ascontiguousarray(stack)


# ---------------------------------------------------------------------------------------------
# subprocess measurements
# ---------------------------------------------------------------------------------------------
_MEMORY_CHILD = r"""
import json, sys, time, tracemalloc
import numpy as np
from anatomesh.core.extract.isosurface import isosurface
data = np.load(sys.argv[1]); aff = np.load(sys.argv[2]); level = float(sys.argv[3])
order = sys.argv[4]
if order == "F":
    data = np.asfortranarray(data)
small = data[:40, :40, :40].copy(order=order)
isosurface(small, level)  # kernels loaded, threads started

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
open("/proc/self/clear_refs", "w").write("5")  # reset VmHWM to the current RSS
rss0 = status("VmRSS:")
tracemalloc.start()
mesh = isosurface(data, level, affine=aff)
_, peak = tracemalloc.get_traced_memory()
hwm = status("VmHWM:")
out = mesh.vertices.nbytes + mesh.normals.nbytes + mesh.faces.nbytes
print(json.dumps(dict(rss0=rss0, hwm=hwm, tracemalloc_peak=peak, output=out, input=data.nbytes)))
"""

_FIRST_CALL_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
import numpy as np
from anatomesh.core.extract.isosurface import isosurface
t1 = time.perf_counter()
data = np.load(sys.argv[1]); aff = np.load(sys.argv[2]); level = float(sys.argv[3])
t2 = time.perf_counter(); isosurface(data, level, affine=aff); t3 = time.perf_counter()
isosurface(data, level, affine=aff); t4 = time.perf_counter()
print(json.dumps(dict(import_s=t1 - t0, first_s=t3 - t2, warm_s=t4 - t3)))
"""


def child(code, *args):
    res = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True)
    if res.returncode:
        raise RuntimeError(res.stderr)
    return json.loads(res.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------------------------
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="chest CT only, fewer repeats (~30 s)")
    ap.add_argument("--repeat", type=int, default=None, help="timing repeats (best of)")
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 7)

    t0 = time.perf_counter()
    vol = load(DATA / "itkelastix_chest_ct")
    print(f"chest CT {vol.shape} {vol.data.dtype}, C-contiguous={vol.data.flags.c_contiguous}, "
          f"read in {time.perf_counter() - t0:.1f} s")
    datasets = [("chest 512x512x141", vol.data)]
    if not args.quick:
        datasets.append(("chest, Fortran order", np.asfortranarray(vol.data)))
        datasets.append(("tiled 512x512x400", tiled_400(vol.data)))
    isosurface(vol.data[:64, :64, :64], 0.0)  # load the compiled kernels

    rows = []
    for name, data in datasets:
        for tissue, level in LEVELS.items():
            run_vtk, _keep = vtk_flying_edges(data, level)
            med = []
            (ours_t, vtk_t, np_t), (mesh, poly, _) = interleaved(
                [lambda: isosurface(data, level, affine=vol.affine), run_vtk,
                 lambda: np.count_nonzero(data > level)], repeat, med)
            sk_t = None
            if not args.quick or (tissue == "bone" and name.startswith("chest 512")):
                from skimage import measure
                sk_t, _ = best_of(lambda: measure.marching_cubes(data, level, method="lewiner"), 1)
            row = dict(data=name, level=f"{tissue} {level}", tris=mesh.n_faces,
                       vtk_tris=poly.GetNumberOfPolys(), ours=ours_t, vtk=vtk_t, numpy=np_t, skimage=sk_t,
                       ratio_median=med[0] / med[2],
                       passes=pass_times(data, vol.affine, level, repeat))
            if not args.quick:
                pts, polys = vtk_arrays(poly)
                row["ours_bad"] = (degenerate_faces(mesh.vertices, mesh.faces).size,
                                   duplicate_vertices(mesh.vertices).size)
                row["vtk_bad"] = (degenerate_faces(pts, polys).size, duplicate_vertices(pts).size)
            rows.append(row)
            print(f"  {name:22s} {tissue:4s} done", flush=True)

    print(f"\nwarm wall-clock seconds, best of {repeat} (ours, VTK and numpy in turn); load average "
          f"{os.getloadavg()[0]:.1f} (2 cores); VTK: vtkFlyingEdges3D, STDThread, 2 threads, normals on")
    head = (f"{'data':22s} {'level':9s} {'triangles':>10s} {'ours':>7s} {'VTK FE':>7s} {'ours/VTK':>8s} "
            f"{'numpy':>7s} {'ours/np':>7s} {'(median)':>8s} {'skimage':>8s}")
    print(head)
    print("-" * len(head))
    for r in rows:
        sk = f"{r['skimage']:8.2f}" if r["skimage"] is not None else f"{'-':>8s}"
        print(f"{r['data']:22s} {r['level']:9s} {r['tris']:>10,d} {r['ours']:7.3f} {r['vtk']:7.3f} "
              f"{r['ours'] / r['vtk']:8.2f} {r['numpy']:7.3f} {r['ours'] / r['numpy']:7.2f} "
              f"{r['ratio_median']:8.2f} {sk}")
    print("targets: ours/VTK <= 0.8; ours/np <= 3 (best of the interleaved runs; median in brackets)")

    print("\nwhere the time goes (best of each pass, ms; 2 threads except numpy and the write floor):")
    head = (f"{'data':22s} {'level':9s} {'classify':>8s} {'count':>6s} {'verts':>6s} {'tris':>6s} "
            f"{'sum':>6s} {'numpy':>6s} {'sum/np':>6s} {'write floor':>11s} {'floor/np':>8s}")
    print(head)
    print("-" * len(head))
    for r in rows:
        p = r["passes"]
        total = p["classify"] + p["count"] + p["vertices"] + p["triangles"]
        print(f"{r['data']:22s} {r['level']:9s} {1e3 * p['classify']:8.1f} {1e3 * p['count']:6.1f} "
              f"{1e3 * p['vertices']:6.1f} {1e3 * p['triangles']:6.1f} {1e3 * total:6.1f} "
              f"{1e3 * p['numpy']:6.1f} {total / p['numpy']:6.2f} {1e3 * p['write_floor']:11.1f} "
              f"{p['write_floor'] / p['numpy']:8.2f}")
    print("write floor: np.empty + fill of arrays the size of the output (vertices, normals, faces),\n"
          "one thread: what writing the mesh alone costs, before any extraction work")
    if not args.quick:
        print("\nzero-area faces / duplicate vertices (ours vs VTK):")
        for r in rows:
            print(f"  {r['data']:22s} {r['level']:9s} ours {r['ours_bad'][0]} / {r['ours_bad'][1]}   "
                  f"VTK {r['vtk_bad'][0]} / {r['vtk_bad'][1]} (VTK {r['vtk_tris']:,} triangles)")

    with tempfile.TemporaryDirectory() as tmp:
        dpath, apath = Path(tmp) / "ct.npy", Path(tmp) / "affine.npy"
        np.save(dpath, vol.data)
        np.save(apath, vol.affine)
        print("\npeak memory of one call (fresh process), MiB:")
        orders = ["C"] if args.quick else ["C", "F"]
        for order in orders:
            for tissue, level in LEVELS.items():
                m = child(_MEMORY_CHILD, dpath, apath, level, order)
                mib = {k: v / 2**20 for k, v in m.items()}
                extra = mib["hwm"] - mib["rss0"]
                print(f"  {order}-order {tissue:4s}: input {mib['input']:.0f}, "
                      f"output mesh {mib['output']:.0f}, "
                      f"peak RSS growth {extra:.0f} ({extra / mib['output']:.2f}x output), "
                      f"tracemalloc peak {mib['tracemalloc_peak']:.0f} "
                      f"({mib['tracemalloc_peak'] / mib['output']:.2f}x output); limit: input + 3x output")
        f = child(_FIRST_CALL_CHILD, dpath, apath, LEVELS["bone"])
        print(f"\nfresh process, warm numba cache: import {f['import_s']:.2f} s, first call "
              f"{f['first_s']:.2f} s, warm call {f['warm_s']:.2f} s -> first call adds "
              f"{f['first_s'] - f['warm_s']:.2f} s")


if __name__ == "__main__":
    main()
