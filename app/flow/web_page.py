"""The web page of a run (format "web"): its final surfaces with coarser levels of detail from
the run's surface set, shown as the files show them (the same shells and cleaning), written by
:func:`anatomesh.app.web.page.write_page` into ``<out>/web``."""
from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Optional

from ...core.decimate.progressive import progressive
from ...core.geometry.margins import color_by_distance, find_target
from ...core.model.mesh import Mesh
from ...core.model.progress import Progress, sub
from ...core.model.surfaceset import SurfaceSet
from ..web.models import level_ratios
from ..web.page import WebModel, write_page
from ..web.views import read_views
from .outputs import relative, web_dir
from .recipe import WEB_FORMAT
from .stages import clean, output_shells, voxel_volume


def set_levels(surfaces: SurfaceSet, final: List[Mesh], n_levels: int, clean=None,
               progress: Optional[Progress] = None) -> List[List[Mesh]]:
    """Levels of a run's surface set, coarsest first; the last level is ``final`` (the run's
    surfaces as written). ``clean(mesh)`` is applied to each coarse shell (the run's cleaning)."""
    ratios = level_ratios(n_levels)
    if not ratios:
        return [final]
    pm = progressive(surfaces, face_ratios=ratios, progress=progress)
    levels = []
    for k in range(pm.n_levels - 1):
        shells, _ = output_shells(pm.level(k))
        for m in shells:
            if clean is not None:
                clean(m)
        levels.append(shells)
    while len(levels) < n_levels - 1:  # the run stopped early: repeat its coarsest level
        levels.insert(0, levels[0] if levels else final)
    return levels + [final]


def model_of_run(result, progress: Optional[Progress] = None) -> WebModel:
    """The page model of a finished run: its final surfaces (with their distance colours) and
    coarser levels from its surface set."""
    recipe = result.recipe
    levels = set_levels(result.surface_set, result.surfaces, recipe.web_levels,
                        clean=lambda m: clean(m, recipe, voxel_volume(result.surface_set)),
                        progress=progress)
    d = result.distance
    if d:  # the final surfaces are coloured already (stages.distance_colors)
        surface = result.surfaces[find_target(result.surfaces, d["target"])]
        for level in levels[:-1]:
            color_by_distance(level, d["target"], d["margins_mm"], target_surface=surface)
    return WebModel(result.plan.stem, levels, result.distance)


def write_web(result, progress: Optional[Progress] = None) -> Optional[Dict]:
    """The page of a run (format "web", :func:`anatomesh.app.web.page.write_page`) with its levels of
    detail; returns its summary for the report (``page`` relative to the report), else None."""
    recipe = result.recipe
    if WEB_FORMAT not in recipe.formats or not result.surfaces:
        return None
    views = read_views(recipe.web_views) if recipe.web_views else []
    model = model_of_run(result, sub(progress, 0.0, 0.6))
    summary = write_page([model], web_dir(recipe), title=result.plan.stem, overwrite=True,  # plan() checked
                         views=views, progress=sub(progress, 0.6, 1.0))
    summary["page"] = relative(Path(summary["page"]), result.plan.report.parent.resolve())
    return summary
