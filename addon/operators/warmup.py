"""First run in Blender: compile the numba kernels in a background process, with a status line.

numba compiles each kernel the first time it runs (~3 min in all on a fresh install, 2 cores) and would
freeze Blender meanwhile. So once the extension is enabled, :func:`start` launches Blender's own
Python (``sys.executable``) on :mod:`anatomesh.app.warmup.compile`, imported under the add-on's own
package name (``bl_ext.<repo>.anatomesh``): numba's cache, next to the sources in
``__pycache__``, remembers the module name a kernel was compiled under, so the add-on then loads
exactly what the background process compiled. That process shares the compiling with a second
one it starts (:data:`anatomesh.app.warmup.compile.LANES`, both at low priority), so label maps can be
extracted sooner. ``NUMBA_CACHE_DIR`` is never set here (the processes inherit
the environment as it is).

A timer reads the process's progress lines into :data:`STATE`; the Import panel draws it
(:func:`draw_status`). Operators that need kernels call :func:`defer` first: while the
surfaces' kernels are still compiling, the operator is re-run when they are ready instead of
compiling in Blender, and :func:`when_ready` runs later work (the first smoothing) once its step
is done. A stamp beside the cache records a finished warm-up for these sources, this Python and
this numba, so later sessions start no process at all.
"""
from __future__ import annotations

import hashlib
import math
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Callable, Dict, List, Optional

import bpy

from ...app.warmup.compile import DEFAULT_STEPS, EXTRA_STEPS, command_as

#: the add-on's root package (``bl_ext.<repo>.anatomesh`` in Blender) and its folder
PACKAGE = __package__.rsplit(".", 2)[0]  # the root package, from its addon.operators
ROOT = Path(__file__).parents[2]  # not resolved: the extension folder may be a link
#: the steps of :mod:`..app.warmup.compile`, in the order they run
STEPS = DEFAULT_STEPS + EXTRA_STEPS
#: the steps the decimation and export operators, and the print check and fixes, wait for
DECIMATION_STEP, FIXES_STEP = "decimation and levels of detail", "print checks and fixes"

#: what the panel shows: running, fraction done, current step, steps finished, error, seconds
STATE: Dict = {"running": False, "fraction": 0.0, "step": "", "done": [], "error": "",
               "seconds": 0.0}

_PROCESS: Optional[subprocess.Popen] = None
_LINES: List[str] = []
_WAITING: List[tuple] = []  # (step, callback) run once the step is done


def command(steps=None) -> List[str]:
    """The background process's command line: Blender's Python on the warm-up module."""
    return command_as(PACKAGE, str(ROOT.parent), ["--steps", ",".join(steps)] if steps else [])


def start(force: bool = False, steps=None) -> bool:
    """Start the background warm-up unless it runs already or a stamp says it is done for
    these sources (``force`` ignores the stamp). Returns True when a process was started."""
    global _PROCESS
    if STATE["running"] or (not force and stamp_path().exists()
                            and stamp_path().read_text() == _fingerprint()):
        return False
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if isinstance(p, str) and p)
    env.setdefault("PYTHONUNBUFFERED", "1")
    try:
        _PROCESS = subprocess.Popen(command(steps), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, env=env, text=True, **_low_priority())
    except OSError as exc:
        STATE.update(error=f"could not start the kernel compilation ({exc})")
        return False
    STATE.update(running=True, fraction=0.0, step="starting", done=[], error="", seconds=0.0)
    _LINES.clear()
    threading.Thread(target=_read_lines, args=(_PROCESS,), daemon=True).start()
    if not bpy.app.background and not bpy.app.timers.is_registered(_poll):
        bpy.app.timers.register(_poll, first_interval=0.2, persistent=True)
    print(f"Anatomesh: first run, compiling kernels in the background ({sys.executable})")
    return True


def stop() -> None:
    """End the background process (unregistering the add-on)."""
    global _PROCESS
    if _PROCESS is not None and _PROCESS.poll() is None:
        _PROCESS.terminate()
    _PROCESS = None
    STATE["running"] = False
    _WAITING.clear()
    if bpy.app.timers.is_registered(_poll):
        bpy.app.timers.unregister(_poll)


def wait(timeout: Optional[float] = None) -> bool:
    """Block until the background process ends (tests, ``blender -b``); True when it succeeded."""
    if _PROCESS is not None:
        try:
            _PROCESS.wait(timeout)
        except subprocess.TimeoutExpired:
            return False
    _poll()
    return not STATE["running"] and not STATE["error"]


def ready(step: str = "reading") -> bool:
    """True when ``step``'s kernels are compiled, or no warm-up runs (they load or compile on
    use as usual)."""
    return not STATE["running"] or step in STATE["done"]


def when_ready(step: str, callback: Callable[[], None]) -> None:
    """Run ``callback()`` once ``step`` is ready (now, when it already is)."""
    if ready(step):
        callback()
    else:
        _WAITING.append((step, callback))


def reading_step(path: str) -> str:
    """The warm-up step whose kernels reading ``path`` needs: "reading" for NIfTI/NRRD files and
    mask folders; DICOM's pixel layout kernels compile with the scans' ("isosurfaces")."""
    from ...core.io.load import NIFTI_SUFFIXES, NRRD_SUFFIXES
    from ...core.io.masks import mask_files

    path = bpy.path.abspath(path)
    name = os.path.basename(os.path.normpath(path)).lower()
    if not path or name.endswith(NIFTI_SUFFIXES + NRRD_SUFFIXES) or mask_files(path):
        return "reading"
    return "isosurfaces"


def extraction_step(volume) -> str:
    """The warm-up step whose kernels extracting ``volume``'s surfaces needs (large label maps
    run parallel passes of their own)."""
    from ...core.extract.multilabel import PARALLEL_MIN_VOXELS

    if not volume.is_label_map:
        return "isosurfaces"
    voxels = math.prod(volume.shape)  # a Volume or a Segmentation's grid
    return "large label maps" if voxels >= PARALLEL_MIN_VOXELS else "label surfaces"


def defer(op, step: str = "reading") -> bool:
    """For an operator's ``execute``: when ``step`` is still compiling in the background, run
    this operator again (same settings) once it is ready and return True — the caller returns
    ``{"FINISHED"}`` at once, so Blender never freezes; False: go on now."""
    if ready(step):
        return False
    settings = {k: getattr(op, k) for k in op.properties.keys() if op.properties.is_property_set(k)}
    idname = op.bl_idname  # "ANATOMESH_OT_import_scan" on an instance, "anatomesh.import_scan" in code
    family, name = idname.split(".") if "." in idname else idname.split("_OT_")
    family = family.lower()

    def rerun():
        getattr(getattr(bpy.ops, family), name)("EXEC_DEFAULT", **settings)

    _WAITING.append((step, rerun))
    op.report({"INFO"}, f"Anatomesh is compiling its kernels (first run, {int(100 * STATE['fraction'])}%): "
                        "this starts by itself when they are ready")
    return True


def status_text() -> str:
    """One line for the panel, '' when nothing is running or went wrong."""
    if STATE["running"]:
        return f"First run: compiling kernels ({STATE['step']})"
    return STATE["error"]


def draw_status(layout) -> None:
    """The status line and progress bar (drawn by the Import panel while compiling)."""
    text = status_text()
    if not text:
        return
    layout.label(text=text, icon="TIME" if STATE["running"] else "ERROR")
    if STATE["running"] and hasattr(layout, "progress"):
        layout.progress(factor=STATE["fraction"], type="BAR", text=f"{int(100 * STATE['fraction'])}%")


def stamp_path() -> Path:
    """Where a finished warm-up is recorded: beside numba's cache of these sources."""
    folder = os.environ.get("NUMBA_CACHE_DIR") or str(ROOT / "__pycache__")
    return Path(folder) / f"anatomesh-warmup-{hashlib.sha1(str(ROOT).encode()).hexdigest()[:10]}.stamp"


# -- internals -------------------------------------------------------------------------------------
def _fingerprint() -> str:
    """Sources (path, size, mtime: what numba's cache checks), package name, Python, numba."""
    from importlib import metadata

    h = hashlib.sha1(f"{PACKAGE}|{sys.version}|{_version('numba', metadata)}".encode())
    for f in sorted((ROOT / "core").rglob("*.py")) + sorted((ROOT / "app" / "warmup").rglob("*.py")):
        st = f.stat()
        h.update(f"{f.relative_to(ROOT)}|{st.st_size}|{st.st_mtime_ns}".encode())
    return h.hexdigest()


def _version(name, metadata) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "?"


def _low_priority() -> Dict:
    """Keep the user's Blender responsive: the compiling process runs at a lower priority."""
    if os.name == "nt":
        return {"creationflags": getattr(subprocess, "BELOW_NORMAL_PRIORITY_CLASS", 0)}
    return {"preexec_fn": lambda: os.nice(10)}


def _read_lines(process: subprocess.Popen) -> None:
    for line in process.stdout:
        _LINES.append(line.rstrip("\n"))


def _poll() -> Optional[float]:
    """Timer: fold the process's new lines into STATE, run what waited, redraw; stop at the end."""
    while _LINES:
        _take(_LINES.pop(0))
    if _PROCESS is not None and _PROCESS.poll() is not None and STATE["running"]:
        _finish(_PROCESS.wait())
    _run_waiting()
    _redraw()
    return 0.25 if STATE["running"] else None


def _take(line: str) -> None:
    """``warmup <i>/<n> <step>`` starts a step (the previous one is done); ``warmup done ...``."""
    parts = line.split(" ", 2)
    if len(parts) == 3 and parts[0] == "warmup" and "/" in parts[1]:
        i, n = (int(x) for x in parts[1].split("/"))
        if STATE["step"] in STEPS and STATE["step"] not in STATE["done"]:
            STATE["done"].append(STATE["step"])
        STATE.update(step=parts[2], fraction=(i - 1) / max(1, n))
    elif line.startswith("warmup done"):
        STATE["done"].append(STATE["step"])
        STATE.update(fraction=1.0, step="done")
    elif line.strip():
        print(f"Anatomesh warm-up: {line}")


def _finish(code: int) -> None:
    STATE["running"] = False
    if code == 0:
        try:
            stamp_path().parent.mkdir(parents=True, exist_ok=True)
            stamp_path().write_text(_fingerprint())
        except OSError:
            pass  # a read-only install: the next session checks the cache again
        print("Anatomesh: kernels compiled; extraction and smoothing start at full speed now")
    else:
        STATE["error"] = ("Kernel compilation stopped (see the system console); kernels compile "
                          "on first use instead")
        waiting = list(_WAITING)
        _WAITING.clear()
        for _, callback in waiting:  # run what waited: it compiles in Blender instead
            _safely(callback)


def _run_waiting() -> None:
    for item in [w for w in _WAITING if ready(w[0])]:
        _WAITING.remove(item)
        _safely(item[1])


def _safely(callback) -> None:
    try:
        callback()
    except Exception as exc:  # a deferred operator failing must not stop the timer
        print(f"Anatomesh: deferred action failed: {type(exc).__name__}: {exc}")


def _redraw() -> None:
    wm = getattr(bpy.context, "window_manager", None)
    for window in getattr(wm, "windows", []):
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
