"""Headless Blender: a pipeline result → the scene the UI would build → a .blend and a Cycles PNG.

``anatomesh mesh --format blend,png`` ends here (the only place the command line reaches
Blender): :func:`write_blend` starts an empty file, adds the surfaces through the very function
the Extract button uses (:func:`anatomesh.addon.operators.scan_ops.scan_to_scene`: one collection named
after the scan, one object per label or level named after it, its material and colour, the custom
properties, the live-smoothing cache), frames one camera per asked view (labels optional) and a
turntable, lights the scene and saves it; it renders the views with Cycles on the CPU (and the
turntable's frames and video).

The surfaces go in as the pipeline made them (smoothed, decimated): they are the objects' rest
shape, with the Smooth panel at 0 iterations, so nothing is smoothed twice.

Runs wherever ``bpy`` imports: ``python`` with the ``bpy`` module, or ``blender -b``. It replaces
the current file's contents, so it refuses to run in an interactive Blender session.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Dict, Sequence, Tuple

import bpy

from .operators import smooth as live, scan
from .scene import lights, objects as scene, pictures
from .scene import turntable as turning

def ensure_registered() -> None:
    """Register the add-on (this package) unless an Anatomesh add-on is registered already."""
    if hasattr(bpy.types, "ANATOMESH_OT_extract"):
        return
    import importlib

    root = importlib.import_module(__package__.rsplit(".", 1)[0])
    root.register()


def write_blend(result, path, *, render_png=None, samples: int = 32, size: Tuple[int, int] = (960, 540),
                labels_on: Sequence[str] = (), turntable: int = 0, turntable_dir=None, video=None,
                light: str = "studio") -> Dict:
    """Build the scene of a :class:`~anatomesh.app.flow.result.Result`, save it as ``path`` and
    render its pictures.

    Parameters
    ----------
    result : pipeline Result (``volume``, ``surfaces``, ``surface_set``, ``recipe``)
    path : str or Path, optional
        The .blend to write (None: build and render only).
    render_png : dict view → PNG path, or one PNG path (the anterior view), optional
        One framed camera per view (:mod:`.scene.camera`), each rendered with Cycles on the CPU.
    samples, size : Cycles samples and the image size in pixels (width, height).
    labels_on : structures (names) labelled in every view (:mod:`.scene.labels`).
    turntable, turntable_dir, video : N frames of a turn about the long axis rendered into the
        folder ``turntable_dir`` and, where Blender has FFmpeg, the MP4 ``video``.
    light : the light preset (:data:`.scene.lights.PRESETS`: ``studio``, ``atlas``).

    The .blend holds every view's camera (the first one active, its labels shown) and the
    turntable's, with the render settings, so it renders the first PNG again. Returns what was
    rendered (:func:`.scene.pictures.shoot`). Errors in Blender become :class:`AnatomeshError`.
    """
    from ..core.model.errors import AnatomeshError

    if not bpy.app.background:
        raise AnatomeshError("write_blend replaces the open file: run it headless "
                             "(blender -b, or Python with the bpy module)")
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    pictures.configure(sc, samples, size)
    coll = result_to_scene(bpy.context, result)
    stills = render_png if isinstance(render_png, dict) else (
        {"anterior": render_png} if render_png is not None else {})
    for view in reversed(list(stills) or ["anterior"]):  # the first view ends up the scene's camera
        pictures.add_view(sc, coll, view, labels_on)
    setup_look(sc, coll, light)
    if turntable:
        turning.add_turntable(sc, scene.surface_objects(coll), coll.anatomesh.space, turntable)
    try:
        if path is not None:
            out = Path(path).resolve()
            out.parent.mkdir(parents=True, exist_ok=True)
            bpy.context.preferences.filepaths.save_version = 0  # no .blend1 beside it
            bpy.ops.wm.save_as_mainfile(filepath=str(out), check_existing=False)
        return pictures.shoot(sc, coll, stills, Path(turntable_dir) if turntable and turntable_dir else None,
                              video)
    except RuntimeError as exc:  # bpy.ops errors (disk full, no permission, ...)
        raise AnatomeshError(f"Blender could not write it ({exc})", path or render_png) from None


def result_to_scene(context, result) -> bpy.types.Collection:
    """Add the result's surfaces as the Extract button would (the run smoothed them already:
    smoothing "As extracted"); returns the scan collection."""
    items = [(m, 0) for m in result.surfaces if m.n_faces]
    sset = result.surface_set
    if result.decimation is not None:  # decimated vertices left their voxel corners: box around them
        sset = dataclasses.replace(sset, lattice=None)
    warnings = list(result.volume.warnings) + list(sset.warnings or [])
    coll = scan.scan_to_scene(context, result.volume, items, [sset], warnings)
    scan.group_layers(coll, result.volume)  # overlapping structures: one child collection per layer
    live.set_scan_settings(coll, smooth_method="NONE")
    recipe = getattr(result, "recipe", None)
    if recipe is not None:
        from ..app.flow.recipe import dump_recipe

        coll["anatomesh_recipe"] = dump_recipe(recipe)
    return coll


def setup_look(sc: bpy.types.Scene, collection: bpy.types.Collection, light: str = "studio") -> None:
    """Light the scan with a preset of :mod:`.scene.lights` (``studio``: key, fill and rim area
    lights; ``atlas``: bright, even light on a light backdrop), placed relative to the scene
    camera (frame it first).

    The materials come with the objects (:func:`scan.scan_to_scene`: each structure's tissue
    class, its opacity from the style table, its cut faces marked), as the Extract button makes
    them.
    """
    lights.apply_lights(sc, scene.surface_objects(collection), light)


def render(sc: bpy.types.Scene, path: str, samples: int = 32, size: Tuple[int, int] = (960, 540)) -> None:
    """Render the scene camera's view with Cycles on the CPU (denoised) into a PNG at ``path``."""
    pictures.configure(sc, samples, size)
    pictures.render_still(sc, path)
