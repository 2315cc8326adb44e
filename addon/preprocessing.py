"""Preprocessing in Blender (issue 15): the Preprocess panel's settings as recipe fields, an
extraction with them through the same app functions as ``anatomesh mesh``, and the isovalue
gallery shown in the Import panel.

The settings live in ``Scene.anatomesh_preprocess`` (:class:`ui.props.ANATOMESH_PG_preprocess`);
:func:`to_recipe` / :func:`from_recipe` copy them to and from a core ``Recipe`` (so the Recipe
panel saves and loads them as the ``[preprocess]`` section). :func:`extract_preprocessed` runs
:func:`anatomesh.app.preprocess.prepare` and :func:`~anatomesh.app.preprocess.extract` and adds
the surfaces like the Extract button does (collection, objects, materials — fuzzy shells get their
opacity — live smoothing); what each step did, with its measured effect, is kept on the
collection (``anatomesh_preprocess``, JSON) and shown in the panel.
"""
from __future__ import annotations

import json
from typing import List

import bpy
import numpy as np

from . import scan

#: UI smoothing filter → recipe filter name
SMOOTH_FILTERS = {"GAUSSIAN": "gaussian", "MEDIAN": "median", "DIFFUSION": "diffusion"}
GALLERY_IMAGE = "Anatomesh Gallery"


def to_recipe(p, recipe) -> None:
    """Copy the panel's settings ``p`` into ``recipe`` (in place)."""
    recipe.resample = [float(p.resample)] if p.resample > 0 else None
    recipe.resample_method = p.resample_method.lower()
    recipe.roi = [float(x) for x in p.roi.replace(";", ",").split(",") if x.strip()] if p.roi.strip() else None
    if p.smooth_volume in SMOOTH_FILTERS:
        value = int(round(p.smooth_value)) if p.smooth_volume == "DIFFUSION" else float(p.smooth_value)
        recipe.smooth_volume = f"{SMOOTH_FILTERS[p.smooth_volume]}:{value:g}"
    else:
        recipe.smooth_volume = None
    for name in ("interpolate", "fuzzy_boundary", "fill_cavities", "precise", "difference_colors"):
        setattr(recipe, name, bool(getattr(p, name)))
    recipe.close_handles = float(p.close_handles) if p.close_handles > 0 else None
    recipe.fuzzy = [float(p.fuzzy_low), float(p.fuzzy_high), float(p.fuzzy_count)] if p.fuzzy else None
    if recipe.fuzzy is not None:
        recipe.levels = []


def from_recipe(p, recipe) -> None:
    """Put a recipe's ``[preprocess]`` settings into the panel ``p``."""
    p.resample = float(recipe.resample[0]) if recipe.resample else 0.0
    p.resample_method = str(recipe.resample_method).upper()
    p.roi = ",".join(f"{x:g}" for x in recipe.roi) if recipe.roi else ""
    p.smooth_volume, p.smooth_value = "NONE", p.smooth_value
    if recipe.smooth_volume:
        name, _, arg = str(recipe.smooth_volume).partition(":")
        p.smooth_volume = {v: k for k, v in SMOOTH_FILTERS.items()}.get(name.lower(), "NONE")
        p.smooth_value = float(arg.split(",")[0]) if arg else p.smooth_value
    for name in ("interpolate", "fuzzy_boundary", "fill_cavities", "precise", "difference_colors"):
        setattr(p, name, bool(getattr(recipe, name)))
    p.close_handles = float(recipe.close_handles or 0.0)
    p.fuzzy = recipe.fuzzy is not None
    if recipe.fuzzy:
        p.fuzzy_low, p.fuzzy_high = recipe.fuzzy[:2]
        p.fuzzy_count = int(recipe.fuzzy[2]) if len(recipe.fuzzy) == 3 else 5


def extract_preprocessed(context, volume, recipe, progress=None) -> bpy.types.Collection:
    """Preprocess ``volume`` as ``recipe`` says, extract, and add the surfaces to the scene
    (as extracted; the operator then smooths them like the Extract button). Returns the new
    collection."""
    from ..app import preprocess, stages
    from ..app.difference import color_differences
    from ..app.recipe import check_recipe

    check_recipe(recipe)
    prepared, pre = preprocess.prepare(volume, recipe, progress)
    sset = preprocess.extract(prepared, recipe, pre, progress)
    sset = sset if sset is not None else stages.extract(prepared, recipe, progress)
    meshes = [m for m in sset.shells() if m.n_faces]
    if pre is not None and recipe.difference_colors:
        pre.difference = color_differences(meshes, preprocess.raw_surfaces(pre.base, recipe).shells())
    coll = scan.scan_to_scene(context, prepared, [(m, 0) for m in meshes], [sset], list(sset.warnings))
    summary = pre.summary() if pre is not None else {"steps": []}
    coll["anatomesh_preprocess"] = json.dumps(summary, default=_plain)
    return coll


def summary_lines(collection) -> List[str]:
    """What each preprocessing step of a scan collection did, one short line each."""
    raw = collection.get("anatomesh_preprocess") if collection is not None else None
    if not raw:
        return []
    out = []
    for step in json.loads(raw).get("steps", []):
        effect = step.get("effect") or {}
        line = step["step"].replace("_", " ")
        if "mean_mm" in effect:
            line += f": mean {effect['mean_mm']:.2f} mm, max {effect['max_mm']:.2f} mm"
        if "within_one_voxel" in effect:
            line += " (within a voxel)" if effect["within_one_voxel"] else " (MORE than a voxel)"
        out.append(line)
    return out


def show_gallery(volume, levels=None, tile: int = 192) -> bpy.types.Image:
    """Render the isovalue gallery of ``volume`` (:func:`anatomesh.app.gallery.gallery`) into
    the image datablock :data:`GALLERY_IMAGE` (made or resized) and return it."""
    from ..app.gallery import gallery

    sheet, info = gallery(volume, levels, tile=tile)
    h, w, _ = sheet.shape
    img = bpy.data.images.get(GALLERY_IMAGE)
    if img is not None and tuple(img.size) != (w, h):
        bpy.data.images.remove(img)
        img = None
    if img is None:
        img = bpy.data.images.new(GALLERY_IMAGE, w, h, alpha=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = sheet[::-1].astype(np.float32) / 255.0  # Blender's rows run bottom-up
    img.pixels.foreach_set(rgba.ravel())
    img.update()
    img["anatomesh_levels"] = json.dumps(info)
    if not bpy.app.background:
        img.preview_ensure()
    return img


def _plain(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
