"""One study of a batch, as a worker runs it: the recipe through :func:`anatomesh.app.flow.run.run`
into a fresh folder, a thumbnail, the batch entry (hashes) added to the report, then the folder
renamed to ``OUT/<id>``. Any failure comes back as a one-line reason; nothing half-written stays.

:func:`run_study` is what the process pool and Dask workers call: it takes and returns plain,
picklable values.
"""
from __future__ import annotations

import dataclasses
import json
import platform
import shutil
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from ...core.export.snapshot import render, write_png
from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh
from ...core.model.volume import space_flip
from ...core.model.progress import Progress
from ..flow.recipe import Recipe
from ..flow.report import json_default
from ..flow.run import run
from . import state

#: thumbnail size in pixels (width, height)
THUMBNAIL_SIZE = (256, 256)


@dataclass(frozen=True)
class StudyTask:
    """Everything a worker needs for one study (picklable): the study, the batch recipe, its
    hash, the batch folder and the study's estimated peak memory in bytes."""

    id: str
    path: str
    labels: Optional[Union[str, Tuple]]
    recipe: Recipe
    recipe_sha256: str
    out: str
    memory: int = 0

    def study_recipe(self, out_dir: Path) -> Recipe:
        """The batch recipe with this study's input, output folder and labels."""
        labels = self.recipe.labels if self.labels is None else (
            self.labels if isinstance(self.labels, str) else list(self.labels))
        return dataclasses.replace(self.recipe, input=self.path, out_dir=str(out_dir), labels=labels,
                                   report=None, overwrite=False)


def run_study(task: StudyTask, progress: Optional[Progress] = None) -> Dict:
    """Run one study; returns ``{"id", "status": "done"|"failed", "seconds", "error",
    "report"}`` (``report`` of a done study, ``error`` a one-line reason of a failed one).
    Never raises for a problem of the study itself."""
    t0 = time.perf_counter()
    out = Path(task.out)
    partial = None
    try:
        inputs = state.fingerprint(task.path)
        if inputs is None:
            raise AnatomeshError("no such file or folder; check the path", task.path)
        partial = state.new_partial(out, task.id)
        t_run = time.perf_counter()
        result = run(task.study_recipe(partial), progress, keep_voxels=False)  # memory: one shot
        t_run = time.perf_counter() - t_run
        write_png(thumbnail(result.surfaces), partial / state.THUMBNAIL)
        report = stamp_report(result.report, partial, task, inputs, (time.perf_counter() - t0, t_run))
        state.publish(partial, out, task.id)
        return {"id": task.id, "status": "done", "seconds": report["batch"]["seconds"],
                "error": "", "report": report}
    except BaseException as exc:  # noqa: BLE001 - every failure of one study is reported, not raised
        if partial is not None:
            shutil.rmtree(partial, ignore_errors=True)
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        return {"id": task.id, "status": "failed", "seconds": round(time.perf_counter() - t0, 3),
                "error": one_line(exc), "report": None,
                "inputs": state.fingerprint(task.path, hashes=False)}


def thumbnail(surfaces: List[Mesh], size=THUMBNAIL_SIZE) -> np.ndarray:
    """An (H, W, 3) uint8 picture of the study's surfaces: seen from the front, or from above
    when that shows more of them (a thin slab of slices). One render at the final size, a small
    part of a study's time (the summary page shows it a little smaller, smoothing edges)."""
    extent = np.zeros(3)
    if any(m.n_faces for m in surfaces):
        v = np.concatenate([np.asarray(m.vertices, np.float64) @ space_flip(m.space, "RAS")[:3, :3].T
                            for m in surfaces if m.n_faces])
        extent = v.max(0) - v.min(0)
    view = "superior" if extent[0] * extent[1] > extent[0] * extent[2] else "anterior"
    return render(surfaces, size=size, view=view)


def stamp_report(report: Dict, folder: Path, task: StudyTask, inputs, seconds: Tuple[float, float]) -> Dict:
    """Add the batch entry to the study's report and rewrite it: study id, input, its files'
    hashes, recipe hash, version, host, ``seconds`` (the whole study) and ``run_seconds`` (of
    it, :func:`~anatomesh.app.flow.run.run`), ``worker_peak_mb`` (the worker process's peak resident
    memory so far). The recipe's output folder becomes the study's final folder."""
    report = dict(report)
    report["recipe"] = dict(report.get("recipe", {}), out_dir=str(Path(task.out, task.id).resolve()))
    report["files"] = dict(report.get("files", {}), thumbnail=state.THUMBNAIL)
    report["batch"] = {"study": task.id, "input": str(Path(task.path).resolve()), "inputs": inputs,
                       "recipe_sha256": task.recipe_sha256, "anatomesh": _version(),
                       "host": platform.node(), "seconds": round(seconds[0], 3),
                       "run_seconds": round(seconds[1], 3), "worker_peak_mb": peak_memory_mb()}
    (folder / state.REPORT).write_text(json.dumps(report, indent=2, default=json_default))
    return report


def peak_memory_mb() -> Optional[float]:
    """Peak resident memory of this process in MiB (None where the system does not tell)."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (2**20 if sys.platform == "darwin" else 1024), 1)  # bytes on macOS, KiB on Linux


def one_line(exc: BaseException) -> str:
    """The one-line reason of a failure: the message of our errors, else ``Type: message``
    and the place it came from."""
    if isinstance(exc, AnatomeshError):
        return str(exc).splitlines()[0] if str(exc) else "AnatomeshError"
    if isinstance(exc, MemoryError):
        return "out of memory (MemoryError); run fewer studies at once (--workers) or on a larger machine"
    text = (str(exc).strip().splitlines() or [""])[0]
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" (at {Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}: {text}{where}" if text else f"{type(exc).__name__}{where}"


def _version() -> str:
    """The installed Anatomesh version (pip's metadata), "unknown" for a bare checkout."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("anatomesh")
    except PackageNotFoundError:
        return "unknown"
