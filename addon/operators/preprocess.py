"""Preprocessing in Blender: the Preprocess panel's settings as recipe fields, an
extraction with them through the same app functions as ``anatomesh mesh``, and the isovalue
gallery shown in the Import panel.

The settings live in ``Scene.anatomesh_preprocess`` (:class:`ui.props.ANATOMESH_PG_preprocess`);
:func:`anatomesh.addon.operators.recipe.preprocess_to_recipe` / ``preprocess_from_recipe`` copy them to and
from a core ``Recipe`` (the Recipe panel saves and loads them as the ``[preprocess]`` section).
:func:`extract_preprocessed` runs :func:`anatomesh.app.flow.preprocess.prepare` and
:func:`~anatomesh.app.flow.preprocess.extract` and adds the surfaces like the Extract button does
(collection, objects, materials — fuzzy shells get their opacity — live smoothing); what each step did, with its measured effect, is kept on the
collection (``anatomesh_preprocess``, JSON) and shown in the panel.
"""
from __future__ import annotations

import json
from typing import List

import bpy
import numpy as np

from . import scan

GALLERY_IMAGE = "Anatomesh Gallery"


def extract_preprocessed(context, volume, recipe, progress=None) -> bpy.types.Collection:
    """Preprocess ``volume`` as ``recipe`` says, extract, and add the surfaces to the scene
    (as extracted; the operator then smooths them like the Extract button). Returns the new
    collection."""
    from ...app.flow import preprocess, stages
    from ...app.flow.difference import color_differences
    from ...app.flow.recipe import check_recipe

    check_recipe(recipe)
    prepared, pre = preprocess.prepare(volume, recipe, progress)
    sset = preprocess.extract(prepared, recipe, pre, progress)
    sset = stages.drop_specks(sset if sset is not None else stages.extract(prepared, recipe, progress))
    meshes = [m for m in stages.output_shells(sset)[0] if m.n_faces]
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
    """Render the isovalue gallery of ``volume`` (:func:`anatomesh.app.pictures.gallery.gallery`) into
    the image datablock :data:`GALLERY_IMAGE` (made or resized) and return it."""
    from ...app.pictures.gallery import gallery

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
