"""Benchmark: label_surfaces() against VTK's vtkSurfaceNets3D and vtkDiscreteFlyingEdges3D.

Usage::

    python benchmarks/bench_labels.py            # 61-label, 41-label and a large map
    python benchmarks/bench_labels.py --quick    # the two small maps only (< 30 s)

All tools run in this process with 2 threads (numba: ``set_num_threads(2)``; VTK:
``vtkSMPTools`` STDThread backend, ``Initialize(2)``). Times are the best and the median of
``--repeat`` runs after one warm-up run. For each tool the script also counts how many per-label
shells come out closed (every edge in exactly two faces) and 2-manifold (edges and vertices),
using ``anatomesh.core.model.mesh.topology``:

* ours: ``SurfaceSet.shell(value)`` for every label;
* vtkSurfaceNets3D: each label's faces picked from its output by the ``BoundaryLabels`` cell
  array (quads split in two triangles), smoothing off and on;
* vtkDiscreteFlyingEdges3D: one run per label (as 3D Slicer does), the whole grid each time.

VTK gets the map padded with one voxel of background (as 3D Slicer pads it): without that, both
VTK filters leave every label touching the grid border open (34 of the 61 labels, 33 of the 41).

The large map is the 61-label TotalSegmentator map upsampled 3x with nearest neighbour
(366 x 303 x 336 voxels at 1 mm), as suggested in shared/data/README.md.
Timings are noisy when other jobs share the 2 cores: the script prints the load average.

Extract + smooth (``--smooth``, or by default after the extraction rows): the whole in-process
call as the pipeline makes it — ``label_surfaces`` + ``smooth_surfaces`` with the default
("organ": Taubin in the voxel cells, junctions, fold guard, volume step, untangling) and its
per-shell report — against ``vtkSurfaceNets3D`` with its built-in smoothing and against 3D
Slicer's rule (``vtkDiscreteFlyingEdges3D`` per label + ``vtkWindowedSincPolyDataFilter`` 20
iterations, pass band 0.01 + ``vtkPolyDataNormals``), interleaved (ours, theirs, ours, ...),
best of ``--repeat``. Target: ours / surface nets <= 1.0.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA",
                           Path(__file__).resolve().parents[2] / "shared" / "data"))
THREADS = 2


def timed(fn, repeat):
    """(best wall s, median wall s, median process CPU s, last result) of ``repeat`` runs."""
    fn()  # warm-up (numba cache load, VTK first-run allocations)
    wall, cpu = [], []
    out = None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return min(wall), statistics.median(wall), statistics.median(cpu), out


def shell_ok(vertices, faces):
    from anatomesh.core.geometry.topology import topology

    t = topology(vertices, faces)
    return t.closed, t.closed and t.manifold, t.closed and t.manifold and t.oriented


def count_ok(results):
    """(closed, closed+manifold, closed+manifold+oriented) counts over shells."""
    return tuple(int(sum(r[i] for r in results)) for i in range(3))


# ---------------------------------------------------------------------------------------------
# tools
# ---------------------------------------------------------------------------------------------
def ours(arr, affine):
    from anatomesh.core.extract.multilabel import label_surfaces

    return lambda: label_surfaces(arr, affine=affine)


def vtk_image(arr, spacing):
    """The map as vtkImageData, padded with one voxel of background on every side (as 3D Slicer
    does before meshing), so labels touching the grid border can close in VTK's output too."""
    import vtk
    from vtk.util import numpy_support as ns

    arr = np.pad(arr, 1)
    img = vtk.vtkImageData()
    img.SetDimensions(*arr.shape)
    img.SetSpacing(*spacing)
    flat = np.ascontiguousarray(arr.ravel(order="F"))
    img.GetPointData().SetScalars(ns.numpy_to_vtk(flat, deep=True))
    return img


def surface_nets(img, labels, smoothing):
    import vtk

    def run():
        sn = vtk.vtkSurfaceNets3D()
        sn.SetInputData(img)
        for i, v in enumerate(labels):
            sn.SetValue(i, int(v))
        sn.SetSmoothing(smoothing)
        sn.Update()
        return sn.GetOutput()
    return run


def surface_nets_shells(poly, labels):
    from vtk.util import numpy_support as ns

    pts = ns.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float32)
    polys = poly.GetPolys()
    offsets = ns.vtk_to_numpy(polys.GetOffsetsArray())
    conn = ns.vtk_to_numpy(polys.GetConnectivityArray())
    sizes = np.diff(offsets)
    bl = ns.vtk_to_numpy(poly.GetCellData().GetArray("BoundaryLabels")).reshape(-1, 2)
    tris = []
    tri_cell = []
    for n in np.unique(sizes):  # fan-triangulate polygons of each size
        cells = np.flatnonzero(sizes == n)
        corners = conn[offsets[cells][:, None] + np.arange(n)]
        for k in range(1, n - 1):
            tris.append(corners[:, [0, k, k + 1]])
            tri_cell.append(cells)
    tris = np.concatenate(tris)
    tri_cell = np.concatenate(tri_cell)
    out = []
    for v in labels:  # faces naming v second are turned around, so each shell can be oriented
        first = bl[tri_cell, 0] == v
        second = bl[tri_cell, 1] == v
        out.append(shell_ok(pts, np.concatenate([tris[first], tris[second][:, ::-1]])))
    return out


def flying_edges(img, labels):
    import vtk

    def run():
        out = []
        for v in labels:
            fe = vtk.vtkDiscreteFlyingEdges3D()
            fe.SetInputData(img)
            fe.SetValue(0, float(v))
            fe.ComputeNormalsOff()
            fe.ComputeGradientsOff()
            fe.ComputeScalarsOff()
            fe.Update()
            out.append(fe.GetOutput())
        return out
    return run


def polydata_tris(poly):
    from vtk.util import numpy_support as ns

    pts = ns.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float32)
    conn = ns.vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    return pts, conn


def slicer_rule(img, labels):
    """3D Slicer's surface from a segment: discrete flying edges per label, windowed sinc 20
    iterations with pass band 10^(-4 * 0.5) = 0.01, then normals."""
    import vtk

    def run():
        out = []
        for v in labels:
            fe = vtk.vtkDiscreteFlyingEdges3D()
            fe.SetInputData(img)
            fe.SetValue(0, float(v))
            fe.ComputeNormalsOff()
            fe.ComputeGradientsOff()
            fe.ComputeScalarsOff()
            sm = vtk.vtkWindowedSincPolyDataFilter()
            sm.SetInputConnection(fe.GetOutputPort())
            sm.SetNumberOfIterations(20)
            sm.SetPassBand(0.01)
            sm.BoundarySmoothingOff()
            sm.FeatureEdgeSmoothingOff()
            sm.NonManifoldSmoothingOn()
            sm.NormalizeCoordinatesOn()
            nm = vtk.vtkPolyDataNormals()
            nm.SetInputConnection(sm.GetOutputPort())
            nm.SplittingOff()
            nm.Update()
            out.append(nm.GetOutput())
        return out
    return run


def ours_smoothed(arr, affine, measure=True, distances=True):
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.smooth.driver import smooth_surfaces

    return lambda: smooth_surfaces(label_surfaces(arr, affine=affine), measure=measure,
                                   distances=distances)


def interleaved(fns, repeat):
    """Best wall time and its process CPU time (all threads) of each callable, run in turns
    after one warm-up each."""
    for fn in fns.values():
        fn()
    best = {k: (np.inf, np.inf) for k in fns}
    for _ in range(repeat):
        for k, fn in fns.items():
            t, c = time.perf_counter(), time.process_time()
            fn()
            best[k] = min(best[k], (time.perf_counter() - t, time.process_time() - c))
    return best


def bench_smoothing(arr, A, labels, repeat):
    """Extract + smooth, ours against VTK's surface nets and Slicer's rule, interleaved."""
    spacing = np.linalg.norm(A[:3, :3], axis=0)
    img = vtk_image(arr, spacing)
    fns = {"anatomesh extract + organ default + report": ours_smoothed(arr, A),
           "  the same, report without distances": ours_smoothed(arr, A, distances=False),
           "  the same, no report": ours_smoothed(arr, A, measure=False),
           "vtkSurfaceNets3D smoothing on": surface_nets(img, labels, True),
           "Slicer: flying edges + windowed sinc + normals": slicer_rule(img, labels)}
    best = interleaved(fns, repeat)
    sn = best["vtkSurfaceNets3D smoothing on"]
    slicer = best["Slicer: flying edges + windowed sinc + normals"]
    print(f"{'':46s} {'wall s':>7s} {'x SN':>6s} {'x Slicer':>8s}   {'cpu s':>7s} {'x SN':>6s}")
    for name, (t, c) in best.items():
        print(f"{name:46s} {t:7.3f} {t / sn[0]:6.2f} {t / slicer[0]:8.2f}   {c:7.3f} "
              f"{c / sn[1]:6.2f}")


# ---------------------------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------------------------
def maps(quick):
    import nibabel as nib

    out = []
    for name, label in [("example_seg_fast_force_split.nii.gz", "61-label map"),
                        ("example_seg.nii.gz", "41-label map")]:
        img = nib.load(str(DATA / "totalsegmentator" / name))
        out.append((label, np.asarray(img.dataobj), img.affine))
    if not quick:
        arr, A = out[0][1], out[0][2]
        big = arr.repeat(3, 0).repeat(3, 1).repeat(3, 2)
        A3 = A.copy()
        A3[:3, :3] = A[:3, :3] / 3.0
        A3[:3, 3] = A[:3, 3] + A[:3, :3] @ np.full(3, -1.0 / 3.0)  # centres of the sub-voxels
        out.append((f"large: 61-label map upsampled 3x, nearest ({'x'.join(map(str, big.shape))})",
                    big, A3))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small maps only, fewer repeats")
    ap.add_argument("--repeat", type=int, default=None, help="timed runs per tool (default 5, "
                    "quick 3)")
    ap.add_argument("--no-check", action="store_true", help="skip the closed-shell counts")
    ap.add_argument("--smooth", action="store_true", help="only the extract + smooth rows")
    args = ap.parse_args(argv)
    repeat = args.repeat or (3 if args.quick else 5)

    import numba
    import vtk

    numba.set_num_threads(THREADS)
    vtk.vtkSMPTools.SetBackend("STDThread")
    vtk.vtkSMPTools.Initialize(THREADS)
    print(f"threads: numba {numba.get_num_threads()}, "
          f"VTK {vtk.vtkSMPTools.GetEstimatedNumberOfThreads()} ({vtk.vtkSMPTools.GetBackend()}); "
          f"VTK {vtk.vtkVersion.GetVTKVersion()}; "
          f"load average {os.getloadavg()[0]:.2f}")
    for label, arr, A in maps(args.quick):
        labels = [int(v) for v in np.unique(arr) if v != 0]
        spacing = np.linalg.norm(A[:3, :3], axis=0)
        print(f"\n== {label}: shape {arr.shape}, {len(labels)} labels, "
              f"spacing {np.round(spacing, 3).tolist()} mm ==")
        if "41-label" not in label:
            bench_smoothing(arr, A, labels, repeat)
        if args.smooth:
            continue
        rows = []
        *t_ours, s = timed(ours(arr, A), repeat)
        *t_sh, shells = timed(s.shells, max(1, repeat // 2))
        note = f"{s.n_faces:,} triangles, {len(s.splits)} split rows"
        ok = count_ok([shell_ok(m.vertices, m.faces) for m in shells]) if not args.no_check \
            else None
        rows.append(("anatomesh label_surfaces", t_ours, ok, note))
        rows.append(("  then shells() (all labels)", t_sh, None, "per-label Mesh views"))
        img = vtk_image(arr, spacing)
        for smoothing in (False, True):
            *t, poly = timed(surface_nets(img, labels, smoothing), repeat)
            ok = count_ok(surface_nets_shells(poly, labels)) if not args.no_check else None
            rows.append((f"vtkSurfaceNets3D smoothing {'on' if smoothing else 'off'}", t, ok,
                         f"{poly.GetNumberOfCells():,} cells"))
        *t, polys = timed(flying_edges(img, labels), max(1, repeat // 2))
        ok = count_ok([shell_ok(*polydata_tris(p)) for p in polys]) if not args.no_check \
            else None
        rows.append(("vtkDiscreteFlyingEdges3D per label", t, ok,
                     f"{sum(p.GetNumberOfCells() for p in polys):,} triangles"))
        base = rows[2][1]
        print(f"{'tool':36s} {'best s':>7s} {'median':>7s} {'cpu s':>7s} {'x SN-off':>8s}  "
              f"{'closed/manifold/oriented':>24s}  notes")
        for name, (best, med, cpu), ok, note in rows:
            okt = "" if ok is None else f"{ok[0]}/{ok[1]}/{ok[2]} of {len(labels)}"
            print(f"{name:36s} {best:7.4f} {med:7.4f} {cpu:7.4f} {best / base[0]:8.2f}  "
                  f"{okt:>24s}  {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
