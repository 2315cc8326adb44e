"""Benchmark: the whole ``anatomesh mesh`` process against file read + 3D Slicer's rule, per case.

Usage::

    python benchmarks/bench_command.py                 # all cases, best of 3
    python benchmarks/bench_command.py --repeat 5 --cases ct,labels61
    python benchmarks/bench_command.py --no-peer       # ours only

Cases (the inputs are real scans from ../shared/data):

* ``ct``: the chest CT DICOM series (``itkelastix_chest_ct``, 512x512x141) ``--level 300``;
* ``labels61``: the 61-label TotalSegmentator map (122x101x112);
* ``big``: an 834x512x512 two-label map built here from the chest CT: label 1 the body (voxels
  above -500 HU, holes filled slice by slice, largest component), label 2 the bone inside it
  (above 300 HU), resampled with nearest neighbour from 141 to 834 slices (0.34 mm) — the shape
  of a thin-slice CT's body and bone masks. Written as ``.nii.gz`` into a temporary folder.

Each run is a fresh process (``python -m anatomesh.app.cli mesh ... --overwrite``, STL out), with
a warm numba cache (one untimed run first); runs of ours and of the peer are interleaved and the
best of ``--repeat`` is kept. For every case ours runs twice: with today's default smoothing and
with ``--smooth none``. The stage breakdown comes from the report's ``timings`` (read, facts, extract,
smooth, decimate, write, report); ``start+exit`` is the rest of the process's wall time (Python,
imports, kernel loading, exit).

The peer, also one fresh process per run: read the file (nibabel; pydicom for the DICOM series,
slices sorted along the normal, rescaled), the volume as vtkImageData padded with one voxel (as
3D Slicer pads it), then Slicer's rule per label — vtkDiscreteFlyingEdges3D, or
vtkFlyingEdges3D at the CT's level — vtkWindowedSincPolyDataFilter (20 iterations, pass band
0.01, non-manifold smoothing and normalised coordinates on) and vtkPolyDataNormals; it writes
nothing. VTK runs with 2 threads (STDThread). The ratio is ours / peer (target <= 1.5).

Peak memory is each process's maximum resident set (``wait4``); the budget is the input volume
plus 4x the output meshes (12 bytes per vertex and per face), above the ``floor``: the peak of the
same command (the same smoothing setting) on the bundled 122x101x30 sample — Python, numpy, numba
and the code of the kernels that setting loads (~0.8 MiB each; the default smoothing's make its
floor ~23 MiB higher than ``--smooth none``'s), none of which grows with the input.
Timings are noisy when other jobs share the 2 cores: the load average is printed, and the CPU
time (user + system, all threads) of the best run beside its wall time.
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

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", REPO.parent / "shared" / "data"))
CT = DATA / "itkelastix_chest_ct"
LABELS61 = DATA / "totalsegmentator" / "example_seg_fast_force_split.nii.gz"
SAMPLE = REPO / "data" / "sample" / "example_seg.nii.gz"
TARGETS = {"ct": 3.0, "labels61": 1.5, "big": 4.0}


def run_process(cmd, env=None):
    """(wall s, CPU s of the process and its threads, peak RSS MiB, stdout) of one process."""
    import threading

    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    streams = {}
    readers = [threading.Thread(target=lambda k=k, f=f: streams.__setitem__(k, f.read()))
               for k, f in (("out", p.stdout), ("err", p.stderr))]
    for r in readers:
        r.start()
    _, status, usage = os.wait4(p.pid, 0)  # this child's own CPU time and peak memory
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    for r in readers:
        r.join()
    if p.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(map(str, cmd[:6]))} failed ({p.returncode}):\n"
                           f"{streams.get('err', '')[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0, streams.get("out", "")


def ours_cmd(case, path, out_dir, smooth):
    cmd = [sys.executable, "-m", "anatomesh.app.cli", "mesh", str(path), "--out", str(out_dir),
           "--overwrite"]
    if case == "ct":
        cmd += ["--level", "300"]
    if smooth == "none":
        cmd += ["--smooth", "none"]
    return cmd


def peer_cmd(case, path):
    env = dict(os.environ, VTK_SMP_BACKEND_IN_USE="STDThread", VTK_SMP_MAX_THREADS="2")
    return [sys.executable, "-c", PEER, case, str(path)], env


PEER = r'''
import json, sys, time
t0 = time.perf_counter()
import numpy as np
import vtk
from vtk.util import numpy_support as ns
case, path = sys.argv[1], sys.argv[2]
t_import = time.perf_counter()
if case == "ct":
    import pydicom
    from pathlib import Path
    dss = [pydicom.dcmread(str(f)) for f in sorted(Path(path).iterdir()) if f.is_file()]
    o = np.array(dss[0].ImageOrientationPatient, float)
    n = np.cross(o[:3], o[3:])
    dss.sort(key=lambda d: float(np.dot(n, np.array(d.ImagePositionPatient, float))))
    arr = np.stack([d.pixel_array.astype(np.float32) * float(d.RescaleSlope) + float(d.RescaleIntercept)
                    for d in dss], axis=2).transpose(1, 0, 2)  # (cols, rows, slices)
    z = [float(np.dot(n, np.array(d.ImagePositionPatient, float))) for d in dss]
    spacing = [float(dss[0].PixelSpacing[1]), float(dss[0].PixelSpacing[0]), float(np.median(np.diff(z)))]
    labels = None
else:
    import nibabel as nib
    img = nib.load(path)
    arr = np.asarray(img.dataobj)
    spacing = [float(s) for s in img.header.get_zooms()[:3]]
    labels = [int(v) for v in np.unique(arr) if v != 0]
t_read = time.perf_counter()
arr = np.pad(arr, 1, constant_values=arr.min())
im = vtk.vtkImageData()
im.SetDimensions(*arr.shape)
im.SetSpacing(*spacing)
im.GetPointData().SetScalars(ns.numpy_to_vtk(np.ascontiguousarray(arr.ravel(order="F")), deep=True))
def slicer_rule(source):
    sm = vtk.vtkWindowedSincPolyDataFilter()
    sm.SetInputConnection(source.GetOutputPort())
    sm.SetNumberOfIterations(20)
    sm.SetPassBand(0.01)
    sm.BoundarySmoothingOff(); sm.FeatureEdgeSmoothingOff(); sm.SetFeatureAngle(120.0)
    sm.NonManifoldSmoothingOn(); sm.NormalizeCoordinatesOn()
    nm = vtk.vtkPolyDataNormals()
    nm.SetInputConnection(sm.GetOutputPort())
    nm.ComputePointNormalsOn(); nm.SplittingOff(); nm.ConsistencyOn()
    nm.Update()
    return nm.GetOutput()
faces = points = 0
for value in (labels if labels is not None else [300.0]):
    fe = vtk.vtkDiscreteFlyingEdges3D() if labels is not None else vtk.vtkFlyingEdges3D()
    fe.SetInputData(im)
    fe.SetValue(0, value)
    out = slicer_rule(fe)
    faces += out.GetNumberOfPolys()
    points += out.GetNumberOfPoints()
t_end = time.perf_counter()
print(json.dumps({"import_s": t_import - t0, "read_s": t_read - t_import,
                  "surfaces_s": t_end - t_read, "faces": faces, "vertices": points}))
'''


def build_big(folder: Path) -> Path:
    """The 834x512x512 body + bone map (see the module docstring), as .nii.gz."""
    import nibabel as nib
    from scipy import ndimage

    from anatomesh.core.io import load

    vol = load(CT, space="RAS")
    hu = vol.data
    body = hu > -500
    for k in range(body.shape[2]):
        body[:, :, k] = ndimage.binary_fill_holes(body[:, :, k])
    parts, _ = ndimage.label(body)
    sizes = np.bincount(parts.ravel())
    sizes[0] = 0
    body = parts == np.argmax(sizes)
    lab = np.zeros(hu.shape, np.uint8)
    lab[body] = 1
    lab[body & (hu > 300)] = 2
    n = 834
    idx = np.minimum((np.arange(n) * hu.shape[2] / n).astype(int), hu.shape[2] - 1)
    big = np.ascontiguousarray(lab[:, :, idx])
    affine = vol.affine.copy()
    affine[:3, 2] *= hu.shape[2] / n
    img = nib.Nifti1Image(big, affine)
    img.header.set_xyzt_units("mm")
    path = folder / "chest_body_bone_834.nii.gz"
    nib.save(img, str(path))
    return path


def report_of(out_dir: Path) -> dict:
    return json.loads((out_dir / "report.json").read_text())


def budget_mib(rep: dict) -> float:
    """Input volume + 4x the output meshes (float32 vertices, int32 faces), MiB."""
    facts = rep["input"]
    vol = float(np.prod(facts["shape"])) * np.dtype(facts["dtype"]).itemsize
    meshes = sum(12.0 * (s["vertices"] + s["faces"]) for s in rep["surfaces"])
    return (vol + 4.0 * meshes) / 2**20


def bench_case(case, path, work: Path, repeat: int, peer: bool, floor: dict) -> dict:
    runs = {"default": [], "none": [], "peer": []}
    reports = {}
    for smooth in ("default", "none"):  # warm-up: numba cache loaded (or compiled), files cached
        run_process(ours_cmd(case, path, work / f"{case}_{smooth}", smooth))
    if peer:
        run_process(*peer_cmd(case, path))
    for _ in range(repeat):
        for smooth in ("default", "none"):
            out_dir = work / f"{case}_{smooth}"
            wall, cpu, rss, _ = run_process(ours_cmd(case, path, out_dir, smooth))
            rep = report_of(out_dir)
            runs[smooth].append((wall, cpu, rss, rep["timings"]))
            reports[smooth] = rep
        if peer:
            cmd, env = peer_cmd(case, path)
            wall, cpu, rss, out = run_process(cmd, env)
            runs["peer"].append((wall, cpu, rss, json.loads(out.strip().splitlines()[-1])))
    return {"runs": runs, "reports": reports, "floor": floor}


def show(case, res, peer: bool) -> None:
    print(f"\n== {case}: {CASE_TEXT[case]}")
    rep = res["reports"]["default"]
    n_faces = sum(s["faces"] for s in rep["surfaces"])
    n_verts = sum(s["vertices"] for s in rep["surfaces"])
    print(f"   {len(rep['surfaces'])} surfaces, {n_verts:,} vertices, {n_faces:,} faces; input "
          f"{' x '.join(map(str, rep['input']['shape']))} {rep['input']['dtype']}")
    best_peer = min(res["runs"]["peer"], key=lambda r: r[0]) if peer else None
    for smooth in ("default", "none"):
        wall, cpu, rss, t = min(res["runs"][smooth], key=lambda r: r[0])
        stages = ["read", "facts", "extract", "smooth", "decimate", "shells", "write", "report"]
        parts = {s: t.get(f"{s}_s", 0.0) for s in stages}
        rest = wall - t.get("total_s", 0.0) - t.get("report_s", 0.0)
        label = "ours, default smoothing" if smooth == "default" else "ours, --smooth none     "
        ratio = f"  ratio {wall / best_peer[0]:.2f}x" if best_peer else ""
        target = f" (target <= {TARGETS[case]:g} s)" if smooth == "default" else ""
        print(f"   {label}: best {wall:6.2f} s{target}, CPU {cpu:6.2f} s, peak {rss:7.0f} MiB{ratio}")
        print("      stages: " + ", ".join(f"{k} {v:.2f}" for k, v in parts.items())
              + f", start+exit {rest:.2f} s")
        budget = budget_mib(res["reports"][smooth])
        above = rss - res["floor"][smooth]
        print(f"      memory: peak - floor = {above:.0f} MiB; budget (input + 4x meshes) "
              f"{budget:.0f} MiB -> {'within' if above <= budget else 'OVER'}")
    if best_peer:
        wall, cpu, rss, t = best_peer
        print(f"   peer (read + Slicer's rule, 1 process): best {wall:6.2f} s, CPU {cpu:6.2f} s, "
              f"peak {rss:7.0f} MiB: import {t['import_s']:.2f}, read {t['read_s']:.2f}, "
              f"surfaces {t['surfaces_s']:.2f} s ({t['faces']:,} faces)")


CASE_TEXT = {"ct": "chest CT DICOM (512x512x141) --level 300",
             "labels61": "61-label TotalSegmentator map (122x101x112)",
             "big": "834x512x512 two-label map (chest CT body + bone, resampled to 834 slices)"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cases", default="ct,labels61,big")
    ap.add_argument("--no-peer", dest="peer", action="store_false")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; best of {args.repeat}")
    work = Path(tempfile.mkdtemp(prefix="anatomesh_bench_command_"))
    try:
        floor = {}
        for smooth in ("default", "none"):
            floor_cmd = ours_cmd("labels61", SAMPLE, work / f"floor_{smooth}", smooth)
            run_process(floor_cmd)
            floor[smooth] = min(run_process(floor_cmd)[2] for _ in range(2))
        print(f"floor (the same command on the 122x101x30 sample): peak {floor['default']:.0f} "
              f"MiB with the default smoothing (its kernels loaded), {floor['none']:.0f} MiB "
              "with --smooth none")
        inputs = {"ct": CT, "labels61": LABELS61}
        for case in [c.strip() for c in args.cases.split(",") if c.strip()]:
            if case == "big" and "big" not in inputs:
                t = time.perf_counter()
                inputs["big"] = build_big(work)
                print(f"built {inputs['big'].name} in {time.perf_counter() - t:.1f} s")
            show(case, bench_case(case, inputs[case], work, args.repeat, args.peer, floor), args.peer)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
