"""The one place the stages are chained:
read → (fix) → extract → drop specks → smooth → decimate → shells → write → (Blender scene) → (print check) → report.

Every door — the ``anatomesh`` command, recipe files, batch runs, ``blender -b`` and Python — fills
a :class:`~anatomesh.app.flow.recipe.Recipe` and calls :func:`run`; the Blender panels call the same
stage functions (:mod:`anatomesh.app.flow.stages`). Every setting is checked first and every output
path before anything is written (existing files are refused unless ``overwrite``).
"""
from __future__ import annotations

import copy

import time
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, List, Optional

from ...core.io.describe import describe
from ...core.model.progress import Progress, report, sub
from ...core.model.errors import AnatomeshError
from ...core.model.segmentation import as_layers, stack_surface_sets
from ...core.model.volume import Volume
from . import outputs, stages, web_page
from . import report as reports
from .preprocess_settings import active as preprocessing_asked
from .recipe import Recipe, check_recipe
from .result import Result


def run(recipe: Recipe, progress: Optional[Progress] = None, keep_voxels: bool = True) -> Result:
    """Execute ``recipe`` and return the :class:`Result`; the report is also written to
    ``recipe.report`` (default ``out_dir/report.json``) with ``recipe.toml`` beside it.
    ``keep_voxels=False`` (one-shot commands, memory): a scan or label map read as one
    :class:`Volume` lets go of its voxels once its surfaces are extracted
    (:meth:`~anatomesh.core.model.volume.Volume.release_voxels`) when nothing after extraction
    reads them (no preprocessing, no Blender scene): the smoothing's peak no longer holds the
    input."""
    recipe = copy.deepcopy(recipe)  # the run resolves its own copy: the caller's stays as asked
    check_recipe(recipe)
    outputs.refuse_existing(recipe)
    blender = outputs.blender_writer() if outputs.needs_blender(recipe) else None
    clock = _Clock(progress)
    clock.start("read", 0.0, "reading")
    volume = stages.read(recipe, clock.sub(0.1))
    clock.start("preprocess", 0.1, "preprocessing")
    volume, pre = _preprocessed(volume, recipe, clock.sub(0.2))
    res = Result(volume, recipe)
    clock.start("facts", 0.2, "describing the input")
    res.input_facts = describe(volume, want_histogram=False)
    release = not keep_voxels and pre is None and blender is None and isinstance(volume, Volume)
    raw_warnings = _layered_surfaces(volume, recipe, clock, res, pre, release)
    pre_warnings = _finish_surfaces(res, pre, clock)
    clock.start("write", 0.7, "writing")
    res.plan = outputs.plan(res.surfaces, volume, recipe)
    # speed: the report's sizes while the files are written; the writers launch no parallel
    # kernel, so one thread at a time does (safe with every numba threading layer)
    with ThreadPoolExecutor(1) as pool:
        sizes = pool.submit(reports.surface_sizes, res.surfaces)
        outputs.write_surfaces(res.surfaces, res.plan, res.plan.stem, clock.sub(0.8))
    res.surface_sizes = sizes.result()
    res.lod = outputs.write_lods(res.surface_set, recipe, res.plan, clock.sub(0.85))
    res.web = web_page.write_web(res, clock.sub(0.85))
    if blender is not None:
        clock.start("blender", 0.85, "building the Blender scene")
        res.render = blender(res, res.plan.scene.get("blend"), render_png=outputs.pictures(res.plan),
                             samples=recipe.render_samples, size=tuple(recipe.render_size),
                             labels_on=recipe.labels_on, turntable=recipe.turntable,
                             turntable_dir=res.plan.scene.get("turntable"), video=res.plan.scene.get("mp4"),
                             light=recipe.light)
        if "mp4" in res.plan.scene and not res.plan.scene["mp4"].exists():  # Blender without FFmpeg
            del res.plan.scene["mp4"]
    if recipe.check:
        from ...core.printing.checks import check_parts  # speed: loaded only when asked for

        clock.start("check", 0.9, "print checks")
        res.print_check = check_parts(res.surfaces, profile=recipe.profile, min_wall=recipe.min_wall,
                                      min_gap=recipe.min_gap, progress=clock.sub(0.99))
    res.timings = clock.stop()
    res.warnings = reports.warnings_of(volume.warnings, raw_warnings, res.smoothing, res.decimation)
    res.warnings += pre_warnings
    t_report = time.perf_counter()  # speed: the report's own facts, timed apart from total_s
    res.report = reports.build_report(res)
    res.report["timings"]["report_s"] = round(time.perf_counter() - t_report, 4)
    reports.save(res.report, recipe, res.plan.report, res.plan.recipe)
    report(progress, 1.0, "done")
    return res


def _finish_surfaces(res: Result, pre, clock: "_Clock") -> List[str]:
    """After the shells: the print tools (hollowing, connectors, cut to fit), the
    preprocessing's measured effects and difference colours, the distance colours — each only
    when the recipe asks.
    Fills ``res``; returns the preprocessing's warnings."""
    recipe = res.recipe
    if recipe.connectors or recipe.hollow is not None or recipe.fit:  # print tools, cut to fit
        from .fit import rows_for_pieces
        from .print_parts import apply_tools

        res.surfaces, tools = apply_tools(res.surfaces, recipe, clock.sub(0.7))
        res.fixes += tools
        res.cleaning = rows_for_pieces(res.cleaning, res.surfaces)
    warnings: List[str] = []
    if pre is not None or recipe.difference_colors:
        from .preprocess import finish

        res.preprocess, warnings = finish(res.surfaces, pre, recipe, clock.sub(0.7))
    res.distance = stages.distance_colors(res.surfaces, recipe)
    return warnings


def _preprocessed(volume, recipe: Recipe, progress):
    """``(volume, preprocessing or None)``: the recipe's preprocessing (:mod:`.preprocess`) of a
    scan or a one-layer label map."""
    if not preprocessing_asked(recipe):
        return volume, None
    from . import preprocess  # speed: scipy.ndimage and the preprocess room load when asked for

    layers = as_layers(volume)
    if len(layers) > 1:
        raise AnatomeshError(f"preprocessing works on one label map or scan; these structures overlap "
                             f"and lie in {len(layers)} layers: mesh them without the preprocessing "
                             "flags", volume.meta.get("source"))
    return preprocess.prepare(layers[0], recipe, progress)


def _pre_extract(layer, recipe: Recipe, pre, progress):
    """The preprocessing's own extraction of ``layer`` (fuzzy boundary, fuzzy shells, precise),
    or None: the usual one applies."""
    if pre is None:
        return None
    from .preprocess import extract

    return extract(layer, recipe, pre, progress)


def _layered_surfaces(volume, recipe: Recipe, clock: "_Clock", res: Result, pre=None,
                      release: bool = False) -> List[str]:
    """Fix → extract → smooth → decimate each label-map layer on its own (a Segmentation's layers
    share no vertex, so one layer's smoothing, untangling or decimation never moves another's
    surfaces), then one closed shell per structure; fills ``res`` and returns the extraction
    warnings. A plain Volume is one layer; ``pre`` (its preprocessing) may extract it its own way
    (fuzzy boundary, fuzzy shells, precise). ``release``: a one-layer volume lets go of its
    voxels once extracted (see :func:`run`)."""
    layers = stages.layers_of(volume, recipe)
    sets, smoothing, decimation, warnings = [], [], [], []
    for i, (layer, lrecipe) in enumerate(layers):
        def at(x: float) -> float:
            return 0.2 + 0.5 * (i + x) / len(layers)
        tag = f" (layer {i + 1}/{len(layers)})" if len(layers) > 1 else ""
        layer, fixes = stages.prepare_volume(layer, lrecipe)
        res.fixes += fixes
        clock.start("extract", at(0.0), "extracting surfaces" + tag)
        raw = _pre_extract(layer, lrecipe, pre, clock.sub(at(0.3)))  # None: the usual way
        raw = raw if raw is not None else stages.extract(layer, lrecipe, clock.sub(at(0.3)))
        if release and len(layers) == 1:  # memory: nothing after extraction reads the voxels
            volume.release_voxels()
            layer.release_voxels()  # a fused or thickened copy
        raw = stages.drop_specks(raw)
        warnings += [w for w in raw.warnings if w not in warnings]
        clock.start("smooth", at(0.3), f"smoothing ({recipe.smooth}){tag}")
        smoothed, rep = stages.smooth(raw, lrecipe, clock.sub(at(0.7)))
        smoothing.append(rep)
        clock.start("decimate", at(0.7), "decimating" + tag)
        done, rep = stages.decimate(smoothed, lrecipe, float(max(layer.spacing)), clock.sub(at(1.0)))
        sets.append(done)
        decimation.append(rep)
    clock.start("shells", 0.7, "splitting into shells")
    res.smoothing, res.decimation = stages.merge_reports(smoothing, decimation)
    res.surface_set = stack_surface_sets(sets)
    res.surfaces, res.cleaning, fix, res.pinch_points = stages.shells(res.surface_set, recipe)
    res.fixes += [fix] if fix else []
    return warnings


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
