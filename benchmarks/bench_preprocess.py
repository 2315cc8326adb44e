"""Benchmark: preprocessing on the real chest CT (512x512x141 int16, 0.977x0.977x2 mm).

* **Resampling** to 1 mm isotropic (512x512x141 → 500x500x282): ours (linear, cubic B-spline,
  Lanczos-3; 2 numba threads, slabs of 256 MB) against ``scipy.ndimage.zoom`` (order 1 and 3, one
  thread) and SimpleITK's ``ResampleImageFilter`` (linear, B-spline, Lanczos windowed sinc; 2
  threads) when SimpleITK is installed (``pip install SimpleITK``). The same output grid; the
  values are compared at the interior voxels (max |difference| in HU).
* **Anisotropic diffusion**, 5 iterations, the same conductance and time step: ours (Perona and
  Malik's rational conductance, float32, 2 threads) against one numpy/``scipy.ndimage`` step per
  iteration (``np.diff`` fluxes) and SimpleITK's ``GradientAnisotropicDiffusionImageFilter``
  (exponential conductance, its own scaling of K; 2 threads).
* **Memory**: a 512x512x1000 CT-sized volume (the chest CT tiled along z) resampled to 1.5 mm in a
  fresh process; the peak resident memory above the input (VmHWM) against the output's size:
  slabs keep it bounded.
* **Live isovalue** in Blender (the ``bpy`` module): one change = isosurface + writing the mesh,
  over a sweep of levels, full resolution and the coarse drag preview (every 2nd voxel); and the
  same mesh written with Blender's own edge derivation (``mesh.update(calc_edges=True)``).

Timings are best of N interleaved runs on a shared machine (the load average is printed).
Run: ``python benchmarks/bench_preprocess.py [--quick] [--repeat N]``.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from anatomesh.core import load
from anatomesh.core.preprocess import filters
from anatomesh.core.preprocess.resample import grid_positions, resample

DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def interleaved(fns, repeat):
    times = [[] for _ in fns]
    outs = [None] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            outs[i] = fn()
            times[i].append(time.perf_counter() - t0)
    return [min(t) for t in times], outs


def sitk_module():
    try:
        import SimpleITK as sitk
    except ImportError:
        return None
    sitk.ProcessObject.SetGlobalDefaultNumberOfThreads(2)
    return sitk


def sitk_image(sitk, vol, dtype=np.float32):
    """The volume as a SimpleITK image (index order reversed: numpy (k, j, i) ↔ ITK (i, j, k))."""
    img = sitk.GetImageFromArray(np.ascontiguousarray(np.asarray(vol.data, dtype).transpose(2, 1, 0)))
    img.SetSpacing([float(s) for s in vol.spacing])
    return img


def bench_resample(vol, repeat, sitk):
    new = 1.0
    zoom = [len(grid_positions(n, s, new)) / n for n, s in zip(vol.shape, vol.spacing)]
    data32 = np.asarray(vol.data, np.float32)
    rows = []
    for method, order, sitk_name in (("linear", 1, "sitkLinear"), ("cubic", 3, "sitkBSpline"),
                                     ("lanczos", None, "sitkLanczosWindowedSinc")):
        fns = [lambda m=method: resample(vol, new, m).data]
        names = [f"ours {method}"]
        if order is not None:
            fns.append(lambda o=order: ndimage.zoom(data32, zoom, order=o, mode="mirror", grid_mode=True))
            names.append(f"scipy zoom order {order}")
        if sitk is not None:
            fns.append(lambda n=sitk_name: _sitk_resample(sitk, vol, new, getattr(sitk, n)))
            names.append(f"SimpleITK {sitk_name}")
        best, outs = interleaved(fns, repeat)
        for name, t, out in zip(names, best, outs):
            inner = tuple(slice(4, -4) for _ in range(3))
            diff = float(np.abs(np.asarray(out, np.float32)[inner] - outs[0][inner]).max()) \
                if np.shape(out) == outs[0].shape else float("nan")
            rows.append((name, t, best[0] / t, diff))
    print(f"\nresampling {vol.shape} {tuple(round(s, 3) for s in vol.spacing)} mm -> {new} mm "
          f"{resample(vol, new).shape}")
    print(f"  {'':32s} {'best s':>8s} {'ours/peer':>10s} {'max |diff| HU (interior)':>26s}")
    for name, t, ratio, diff in rows:
        print(f"  {name:32s} {t:8.3f} {ratio:10.2f} {diff:26.2f}")


def _sitk_resample(sitk, vol, new, interpolator):
    img = sitk_image(sitk, vol)
    size = [len(grid_positions(n, s, new)) for n, s in zip(vol.shape, vol.spacing)]
    origin = [(n - 1) / 2 * s - (m - 1) / 2 * new for n, s, m in zip(vol.shape, vol.spacing, size)]
    out = sitk.Resample(img, size, sitk.Transform(), interpolator, origin, [new] * 3,
                        img.GetDirection(), 0.0, sitk.sitkFloat32)
    return sitk.GetArrayFromImage(out).transpose(2, 1, 0)


def numpy_diffusion(u, iterations, k, dt, h):
    """Perona-Malik (rational conductance) with numpy slices and ``np.diff``: the same scheme."""
    u = np.array(u, np.float32)
    for _ in range(iterations):
        acc = np.zeros_like(u)
        for axis in range(3):
            d = np.diff(u, axis=axis) / h[axis]
            flux = d / (1 + (d / k) ** 2) / h[axis]
            lo = [slice(None)] * 3
            hi = [slice(None)] * 3
            lo[axis], hi[axis] = slice(0, -1), slice(1, None)
            acc[tuple(lo)] += flux
            acc[tuple(hi)] -= flux
        u += dt * acc
    return u


def bench_diffusion(vol, repeat, sitk):
    ours = filters.diffusion(vol, 5)
    info = ours.meta["smoothed"]
    k, dt, h = info["conductance"], info["time_step_mm2"], np.asarray(vol.spacing)
    fns = [lambda: filters.diffusion(vol, 5).data, lambda: numpy_diffusion(vol.data, 5, k, dt, h)]
    names = ["ours (numba, 2 threads)", "numpy / np.diff (1 thread)"]
    if sitk is not None:
        img = sitk_image(sitk, vol)

        def itk():
            f = sitk.GradientAnisotropicDiffusionImageFilter()
            f.SetNumberOfIterations(5)
            f.SetTimeStep(0.06)  # ITK's own stable bound here: 0.0625 x the smallest spacing
            f.SetConductanceParameter(3.0)
            return sitk.GetArrayFromImage(f.Execute(img))
        fns.append(itk)
        names.append("SimpleITK gradient anisotropic (2 threads)")
    best, outs = interleaved(fns, repeat)
    print(f"\ndiffusion {vol.shape}, 5 iterations (K {k:g} HU/mm, dt {dt:g} mm^2)")
    for name, t in zip(names, best):
        print(f"  {name:44s} {t:8.3f} s   ours/peer {best[0] / t:5.2f}")
    print(f"  ours vs numpy max |diff|: {float(np.abs(outs[0] - outs[1]).max()):.4f} HU")


def bench_memory(quick):
    code = ("import numpy as np, sys; from anatomesh.core import load; "
            "from anatomesh.core.preprocess.resample import resample; "
            "from anatomesh.core.model.volume import Volume; "
            f"v = load({str(DATA / 'itkelastix_chest_ct')!r}); "
            f"n = {400 if quick else 1000}; d = np.concatenate([v.data, v.data[:, :, ::-1]] * 4, axis=2)[:, :, :n].copy(); "
            "a = v.affine.copy(); a[:3, 2] = [0, 0, 1.0]; big = Volume(d, a); "
            "hwm = lambda: int([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]) * 1024; "
            "open('/proc/self/clear_refs', 'w').write('5'); base = hwm(); "
            "out = resample(big, 1.5, 'cubic'); peak = hwm() - base; "
            "print(d.nbytes, out.data.nbytes, peak, 'x'.join(map(str, big.shape)), 'x'.join(map(str, out.shape)))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if res.returncode != 0:
        print("\nmemory: failed", res.stderr.strip().splitlines()[-1:])
        return
    inp, out, peak, shape_in, shape_out = res.stdout.split()
    mb = lambda x: int(x) / 2**20  # noqa: E731
    print(f"\nmemory, cubic resampling of {shape_in} int16 ({mb(inp):.0f} MB) to 1.5 mm ({shape_out}): "
          f"output {mb(out):.0f} MB, peak above the input {mb(peak):.0f} MB (output + slabs of 256 MB)")


def bench_live(vol, levels):
    try:
        import bpy  # noqa: F401
    except ImportError:
        print("\nlive isovalue: needs the bpy module")
        return
    from anatomesh.addon.scene import bridge
    from anatomesh.addon.operators import isovalue as live_iso

    me = bpy.data.meshes.new("live")
    obj = bpy.data.objects.new("live", me)
    bpy.context.scene.collection.objects.link(obj)
    live_iso.update(obj, vol, levels[0], stride=1)  # warm
    print(f"\nlive isovalue in Blender, {vol.shape}: seconds per change (isosurface + mesh written)")
    for stride, label in ((1, "full resolution"), (2, "drag preview (every 2nd voxel)")):
        times, faces = [], []
        for lv in levels:
            times.append(live_iso.update(obj, vol, lv, stride=stride))
            faces.append(len(me.polygons))
        print(f"  {label:34s} median {np.median(times):.3f}  max {max(times):.3f}  "
              f"({min(faces):,}-{max(faces):,} triangles)")
    times = []
    for lv in levels[:4]:
        t0 = time.perf_counter()
        m = live_iso.extract(vol, lv)
        bridge.set_geometry(me, m.vertices, m.faces)
        times.append(time.perf_counter() - t0)
    print(f"  {'with calc_edges (Blender derives)':34s} median {np.median(times):.3f}  max {max(times):.3f}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--only", choices=("resample", "diffusion", "memory", "live"),
                    help="run one part only")
    args = ap.parse_args()
    repeat = args.repeat or (2 if args.quick else 4)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    vol = load(str(DATA / "itkelastix_chest_ct"))
    sitk = sitk_module()
    print("SimpleITK:", sitk.Version.VersionString() if sitk else "not installed")
    parts = {"resample": lambda: bench_resample(vol, repeat, sitk),
             "diffusion": lambda: bench_diffusion(vol, repeat, sitk),
             "memory": lambda: bench_memory(args.quick),
             "live": lambda: bench_live(vol, [300, 310, 320, 200, 150, -500, -490, -480, 100, 40]
                                        if not args.quick else [300, 320, -500, 200])}
    for name, part in parts.items():
        if args.only in (None, name):
            part()
            sys.stdout.flush()


if __name__ == "__main__":
    main()
