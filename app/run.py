"""The one place the stages are chained:
read → (fix) → extract → smooth → decimate → shells → write → (Blender scene) → (print check) → report.

Every door — the ``anatomesh`` command, recipe files, batch runs, ``blender -b`` and Python — fills
a :class:`~anatomesh.app.recipe.Recipe` and calls :func:`run`; the Blender panels call the same
stage functions (:mod:`anatomesh.app.stages`). Every setting is checked first and every output
path before anything is written (existing files are refused unless ``overwrite``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional

from ..core.io import load
from ..core.model.mesh import Mesh
from ..core.model.progress import Progress, report, sub
from ..core.model.surfaceset import SurfaceSet
from ..core.model.volume import Volume
from . import outputs, stages
from . import report as reports
from .recipe import BLENDER_FORMATS, Recipe, check_recipe


@dataclass
class Result:
    """What :func:`run` made: the volume read, the final surfaces (one closed :class:`Mesh` per
    label or level, mm), the final :class:`SurfaceSet`, the report dict and where files went.
    The other fields are what each stage reported (see :mod:`anatomesh.app.report`)."""

    volume: Volume
    recipe: Recipe
    surface_set: Optional[SurfaceSet] = None
    surfaces: List[Mesh] = field(default_factory=list)
    report: Dict = field(default_factory=dict)
    plan: Optional[outputs.Plan] = None
    timings: Dict[str, float] = field(default_factory=dict)
    smoothing: Optional[Dict] = None
    decimation: Optional[Dict] = None
    cleaning: List[Dict] = field(default_factory=list)
    fixes: List[Dict] = field(default_factory=list)
    lod: List[Dict] = field(default_factory=list)
    print_check: Optional[Dict] = None
    warnings: List[str] = field(default_factory=list)

    @property
    def report_path(self):
        return self.plan.report if self.plan else None

    @property
    def files(self):
        """The whole-scene files (combined 3MF, GLB, blend, PNG) by format."""
        return self.plan.scene if self.plan else {}


def run(recipe: Recipe, progress: Optional[Progress] = None) -> Result:
    """Execute ``recipe`` and return the :class:`Result`; the report is also written to
    ``recipe.report`` (default ``out_dir/report.json``) with ``recipe.toml`` beside it."""
    check_recipe(recipe)
    blender = outputs.blender_writer() if any(f in BLENDER_FORMATS for f in recipe.formats) else None
    clock = _Clock(progress)
    clock.start("read", 0.0, "reading")
    volume = load(recipe.input, series=recipe.series, volume_index=recipe.volume_index,
                  labels=recipe.label_table, space=recipe.space, progress=clock.sub(0.2))
    volume, fixes = stages.prepare_volume(volume, recipe)
    res = Result(volume, recipe, fixes=fixes)
    clock.start("extract", 0.2, "extracting surfaces")
    raw = stages.extract(volume, recipe, clock.sub(0.4))
    clock.start("smooth", 0.4, f"smoothing ({recipe.smooth})")
    smoothed, res.smoothing = stages.smooth(raw, recipe, clock.sub(0.55))
    clock.start("decimate", 0.55, "decimating")
    res.surface_set, res.decimation = stages.decimate(smoothed, recipe, float(max(volume.spacing)),
                                                      clock.sub(0.7))
    res.surfaces, res.cleaning, fix = stages.shells(res.surface_set, recipe)
    res.fixes += [fix] if fix else []
    clock.start("write", 0.7, "writing")
    res.plan = outputs.plan(res.surfaces, volume, recipe)
    outputs.write_surfaces(res.surfaces, res.plan, res.plan.stem, clock.sub(0.8))
    res.lod = outputs.write_lods(res.surface_set, recipe, res.plan, clock.sub(0.85))
    if blender is not None:
        clock.start("blender", 0.85, "building the Blender scene")
        blender(res, res.plan.scene.get("blend"), render_png=res.plan.scene.get("png"),
                samples=recipe.render_samples, size=tuple(recipe.render_size))
    if recipe.check:
        from ..core.printing.checks import check_parts  # speed: loaded only when asked for

        clock.start("check", 0.9, "print checks")
        res.print_check = check_parts(res.surfaces, profile=recipe.profile, min_wall=recipe.min_wall,
                                      min_gap=recipe.min_gap, progress=clock.sub(0.99))
    res.timings = clock.stop()
    res.warnings = reports.warnings_of(volume.warnings, raw.warnings, res.smoothing, res.decimation)
    t_report = time.perf_counter()  # speed: the report's own facts, timed apart from total_s
    res.report = reports.build_report(res)
    res.report["timings"]["report_s"] = round(time.perf_counter() - t_report, 4)
    reports.save(res.report, recipe, res.plan.report, res.plan.recipe)
    report(progress, 1.0, "done")
    return res


class _Clock:
    """Seconds per stage (``<stage>_s`` and ``total_s``) and the progress of the current one."""

    def __init__(self, progress: Optional[Progress]):
        self.progress, self.t0 = progress, time.perf_counter()
        self.timings: Dict[str, float] = {}
        self.current, self.since, self.at = None, self.t0, 0.0

    def start(self, name: str, at: float, text: str) -> None:
        self._close()
        self.current, self.since, self.at = name, time.perf_counter(), at
        report(self.progress, at, text)

    def sub(self, until: float) -> Optional[Progress]:
        return sub(self.progress, self.at, until)

    def _close(self) -> None:
        if self.current is not None:
            key = f"{self.current}_s"
            self.timings[key] = self.timings.get(key, 0.0) + time.perf_counter() - self.since

    def stop(self) -> Dict[str, float]:
        self._close()
        self.current = None
        self.timings["total_s"] = time.perf_counter() - self.t0
        return self.timings
