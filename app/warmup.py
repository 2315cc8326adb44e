"""The warm-up: compile Anatomesh's numba kernels once (first run), or load them from numba's cache.

numba compiles a kernel the first time a process calls it — 2.5-4 min for all of Anatomesh's on
a fresh install with 2 cores — and caches the machine code next to the sources
(``__pycache__``), where later processes load it in milliseconds. :func:`warm_up` runs the stages on tiny made-up inputs, in
the order a first session needs them (reading, extraction, smoothing, report and files first;
decimation, print checks and fixes, scene files after), so that every kernel and every argument
type the default flow uses is compiled and cached before the user's first real run.

Who runs it:

* the command line: ``python -m anatomesh.app.warmup`` compiles everything ahead of time; and
  every ``anatomesh`` command announces, in one line on stderr, when a run compiles
  (:func:`announce_compiling`);
* the Blender add-on: after the extension is enabled, a background process of Blender's own
  Python runs this module under the add-on's own package name (numba's cache remembers the module
  name a kernel was compiled under), while the UI shows its progress (``addon/warmup.py``).

Run as a script it prints one line per step, ``warmup <i>/<n> <step> <seconds>``, then
``warmup done <seconds>`` (the add-on reads them for its progress bar).
"""
from __future__ import annotations

import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Dict, List, Optional

import numpy as np

#: what a first session needs first — reading, extraction of label maps and of scans (the
#: add-on's first extraction waits for these), the default smoothing, the run's report and files
#: — then the rest
DEFAULT_STEPS = ("reading", "label surfaces", "isosurfaces", "smoothing", "files and report")
EXTRA_STEPS = ("more data types", "decimation and levels of detail", "print checks and fixes")

#: a one-line note for runs that compile (the CLI prints it on stderr once)
FIRST_RUN_NOTE = ("first run: compiling Anatomesh's kernels once (1-2 min; `python -m anatomesh.app.warmup` "
                  "does it ahead), later runs are fast")


def warm_up(steps: Optional[List[str]] = None,
            progress: Optional[Callable[[float, str], None]] = None) -> Dict[str, float]:
    """Run the warm-up steps (default: all, in :data:`DEFAULT_STEPS` then :data:`EXTRA_STEPS`
    order); returns the seconds each took. ``progress(fraction, text)`` is called before each
    step and at the end (``"done"``)."""
    names = list(steps) if steps is not None else list(DEFAULT_STEPS + EXTRA_STEPS)
    unknown = [n for n in names if n not in _STEPS]
    if unknown:
        raise ValueError(f"unknown warm-up step(s) {unknown}; known: {list(_STEPS)}")
    seconds: Dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="anatomesh_warmup_") as tmp:
        for i, name in enumerate(names):
            if progress is not None:
                progress(i / len(names), name)
            t0 = time.perf_counter()
            _STEPS[name](Path(tmp) / f"step{i}")
            seconds[name] = time.perf_counter() - t0
    if progress is not None:
        progress(1.0, "done")
    return seconds


@contextmanager
def announce_compiling(stream=None, note: str = FIRST_RUN_NOTE):
    """Within the block, say ``note`` once on ``stream`` (default stderr) when numba starts
    compiling an Anatomesh kernel, i.e. when the cache is cold (a cache hit says nothing)."""
    def say(func) -> None:
        out = stream or sys.stderr
        out.write(f"\n{note}\n" if getattr(out, "isatty", lambda: False)() else f"{note}\n")
        out.flush()

    with _on_compile(say, once=True):
        yield


@contextmanager
def counting_compiles():
    """Within the block, count the Anatomesh kernels numba compiles (cache misses): yields a
    list that receives each compiled function's qualified name."""
    names: List[str] = []
    with _on_compile(lambda func: names.append(f"{func.__module__}.{func.__qualname__}")):
        yield names


@contextmanager
def _on_compile(callback: Callable, once: bool = False):
    """Call ``callback(python_function)`` when numba starts compiling one of our kernels."""
    from numba.core import event

    package = (__package__ or "anatomesh.app").rpartition(".")[0]  # run as __main__ too

    class _Listener(event.Listener):
        calls = 0

        def on_start(self, ev):
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            if func is None or not getattr(func, "__module__", "").startswith(package + "."):
                return
            if not (once and self.calls):
                callback(func)
            self.calls += 1

        def on_end(self, ev):
            pass

    listener = _Listener()
    event.register("numba:compile", listener)
    try:
        yield listener
    finally:
        event.unregister("numba:compile", listener)


# -- tiny inputs -----------------------------------------------------------------------------------
def _label_map(dtype, big: int = 0) -> np.ndarray:
    """12x11x9 map: a ball (label 1 or ``big``) beside a box (label 2) it touches."""
    i, j, k = np.ogrid[:12, :11, :9]
    data = np.zeros((12, 11, 9), dtype)
    data[(i - 5) ** 2 + (j - 5) ** 2 + (k - 4) ** 2 <= 10] = big or 1
    data[7:11, 3:8, 2:7] = 2
    return data


def _scan(dtype) -> np.ndarray:
    """12x12x10 CT-like scan: a dense ball (~1000 HU) with a softer shell in air (-1000)."""
    i, j, k = np.ogrid[:12, :12, :10]
    r2 = (i - 5.5) ** 2 + (j - 5.5) ** 2 + (k - 4.5) ** 2
    return np.where(r2 <= 9, 1000, np.where(r2 <= 16, 40, -1000)).astype(dtype)


def _save_nifti(data: np.ndarray, path: Path, spacing=(1.0, 1.0, 2.5)) -> str:
    import nibabel as nib

    path.parent.mkdir(parents=True, exist_ok=True)
    img = nib.Nifti1Image(data, np.diag(list(spacing) + [1.0]))
    img.header.set_xyzt_units("mm")
    nib.save(img, str(path))
    return str(path)


def _mesh(folder: Path, source: str, **settings) -> None:
    """One run of the whole flow (:func:`anatomesh.app.run.run`) with these settings."""
    from .recipe import Recipe
    from .run import run

    run(Recipe(input=source, out_dir=str(folder / "out"), overwrite=True, **settings))


# -- the steps -------------------------------------------------------------------------------------
def _reading(folder: Path) -> None:
    """Counting values (label detection, input facts) and the DICOM slice layout kernel."""
    from ..core.io.dicom_pixels import to_volume_layout
    from ..core.io.values import value_counts

    for dtype in (np.bool_, np.uint8, np.uint16, np.int16, np.int32):
        value_counts(_label_map(dtype))
    for stored in (np.uint16, np.int16):
        stack = np.arange(2 * 3 * 4, dtype=stored).reshape(2, 3, 4)
        to_volume_layout(stack, np.ones(2), np.full(2, -1024.0))  # integer rescale → int16
        to_volume_layout(stack, np.full(2, 0.5), np.zeros(2))      # fractional → float32


def _label_surfaces(folder: Path) -> None:
    """A uint8 label map read from NIfTI, its surfaces extracted and split into shells."""
    from ..core.extract.multilabel import label_surfaces
    from ..core.io import load

    label_surfaces(load(_save_nifti(_label_map(np.uint8), folder / "u8.nii.gz"))).shells()


def _isosurfaces(folder: Path) -> None:
    """An int16 scan read from NIfTI, its isosurface at one level."""
    from ..core.extract.isosurface import isosurfaces
    from ..core.io import load

    isosurfaces(load(_save_nifti(_scan(np.int16), folder / "i16.nii.gz")), [300.0], cap=True)


def _files_and_report(folder: Path) -> None:
    """The rest of a run without smoothing: the report's facts and the STL files."""
    _mesh(folder / "u8", _save_nifti(_label_map(np.uint8), folder / "u8.nii.gz"), smooth="none")
    _mesh(folder / "i16", _save_nifti(_scan(np.int16), folder / "i16.nii.gz"), levels=[300.0],
          smooth="none")


def _more_types(folder: Path) -> None:
    """Label maps with values above 255 (uint16) and float32 scans at two levels."""
    _mesh(folder / "u16", _save_nifti(_label_map(np.uint16, big=300), folder / "u16.nii.gz"))
    _mesh(folder / "f32", _save_nifti(_scan(np.float32) + 0.5, folder / "f32.nii.gz",
                                      spacing=(1.0, 1.0, 1.0)), levels=[300.0, -400.0])


def _smoothing(folder: Path) -> None:
    """The default smoothing (:func:`anatomesh.app.stages.smooth`) of label surfaces (thick
    slices: with the staircase pass; isotropic) and of an isosurface, and the cached session the
    live sliders run (:class:`anatomesh.core.smooth.session.SmoothingSession`)."""
    from ..core.extract.isosurface import isosurfaces
    from ..core.extract.multilabel import label_surfaces
    from ..core.model.surfaceset import SurfaceSet
    from ..core.smooth.session import SmoothingSession
    from . import stages
    from .recipe import Recipe

    for spacing in ((1.0, 1.0, 2.5), (1.0, 1.0, 1.0)):
        s = label_surfaces(_label_map(np.uint8), affine=np.diag(list(spacing) + [1.0]))
        stages.smooth(s, Recipe())
    iso = isosurfaces(_scan(np.int16), [300.0], cap=True)
    stages.smooth(SurfaceSet.from_meshes(iso, np.eye(4)), Recipe())
    method, settings = stages.smoothing(Recipe())
    SmoothingSession(s).run(method, **settings)


def _decimation(folder: Path) -> None:
    labels = _save_nifti(_label_map(np.uint8), folder / "u8.nii.gz")
    _mesh(folder / "lab", labels, decimate=0.5, lod=2, formats=["stl", "3mf", "glb"])
    _mesh(folder / "iso", _save_nifti(_scan(np.int16), folder / "i16.nii.gz"), levels=[300.0],
          target_faces=100, formats=["ply", "obj"])


def _printing(folder: Path) -> None:
    labels = _save_nifti(_label_map(np.uint8), folder / "u8.nii.gz")
    _mesh(folder / "check", labels, check=True)
    _mesh(folder / "fix", labels, thicken=True, clearance=0.2, fuse=[[1, 2]], check=True)


_STEPS: Dict[str, Callable[[Path], None]] = {
    "reading": _reading,
    "label surfaces": _label_surfaces,
    "isosurfaces": _isosurfaces,
    "smoothing": _smoothing,
    "files and report": _files_and_report,
    "more data types": _more_types,
    "decimation and levels of detail": _decimation,
    "print checks and fixes": _printing,
}


def main(argv: Optional[List[str]] = None) -> int:
    """``python -m anatomesh.app.warmup [--default-only | --steps A,B] [--quiet]``.

    Prints one line per step before it runs (``warmup <i>/<n> <step>``), after it
    ``  <seconds> s, <k> kernels compiled``, and at the end ``warmup done <seconds> s, <k>
    kernels compiled`` (0 when every kernel came from numba's cache)."""
    args = list(sys.argv[1:] if argv is None else argv)
    names = list(DEFAULT_STEPS) + ([] if "--default-only" in args else list(EXTRA_STEPS))
    if "--steps" in args:
        names = [n.strip() for n in args[args.index("--steps") + 1].split(",") if n.strip()]
    quiet = "--quiet" in args
    t0 = time.perf_counter()
    with counting_compiles() as compiled:
        for i, name in enumerate(names, 1):
            if not quiet:
                print(f"warmup {i}/{len(names)} {name}", flush=True)
            before = len(compiled)
            seconds = warm_up([name])[name]
            if not quiet:
                print(f"  {seconds:.1f} s, {len(compiled) - before} kernels compiled", flush=True)
    print(f"warmup done {time.perf_counter() - t0:.1f} s, {len(compiled)} kernels compiled", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
