"""Headless Blender: a pipeline result → the scene the UI would build → a .blend and a Cycles PNG.

``anatomesh mesh --format blend,png`` ends here (the only place the command line reaches
Blender): :func:`write_blend` starts an empty file, adds the surfaces through the very function
the Extract button uses (:func:`anatomesh.addon.operators.scan_ops.scan_to_scene`: one collection named
after the scan, one object per label or level named after it, its material and colour, the custom
properties, the live-smoothing cache), frames a camera from the patient's front, lights the scene
and saves it; with ``render_png`` it also renders the view with Cycles on the CPU.

The surfaces go in as the pipeline made them (smoothed, decimated): they are the objects' rest
shape, with the Smooth panel at 0 iterations, so nothing is smoothed twice.

Runs wherever ``bpy`` imports: ``python`` with the ``bpy`` module, or ``blender -b``. It replaces
the current file's contents, so it refuses to run in an interactive Blender session.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Optional, Sequence, Tuple

import bpy

from .operators import smooth as live, scan
from .scene import objects as scene

#: organs made see-through in the picture (name contains one of these), with their opacity
SEE_THROUGH = ("lung",)
SEE_THROUGH_ALPHA = 0.25


def ensure_registered() -> None:
    """Register the add-on (this package) unless an Anatomesh add-on is registered already."""
    if hasattr(bpy.types, "ANATOMESH_OT_extract"):
        return
    import importlib

    root = importlib.import_module(__package__.rsplit(".", 1)[0])
    root.register()


def write_blend(result, path, *, render_png=None, samples: int = 32, size: Tuple[int, int] = (960, 540),
                elevation: float = 30.0, azimuth: float = -25.0,
                see_through: Sequence[str] = SEE_THROUGH) -> Optional[Path]:
    """Build the scene of a :class:`~anatomesh.app.flow.result.Result` and save it as ``path``.

    Parameters
    ----------
    result : pipeline Result (``volume``, ``surfaces``, ``surface_set``, ``recipe``)
    path : str or Path, optional
        The .blend to write (None: build and render only).
    render_png : str or Path, optional
        Also render the camera view with Cycles on the CPU into this PNG.
    samples, size : Cycles samples and the image size in pixels (width, height).
    elevation, azimuth : camera degrees above the front view and around the body's long axis.
    see_through : organs (by name) drawn see-through (:data:`SEE_THROUGH_ALPHA`, oriented).

    Returns the .blend path (or None). Errors in Blender become :class:`AnatomeshError`.
    """
    from ..core.model.errors import AnatomeshError

    if not bpy.app.background:
        raise AnatomeshError("write_blend replaces the open file: run it headless "
                             "(blender -b, or Python with the bpy module)")
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = int(size[0]), int(size[1])
    coll = result_to_scene(bpy.context, result)
    scene.frame_camera(sc, scene.surface_objects(coll), coll.anatomesh.space, "ANTERIOR",
                       elevation, azimuth)
    setup_look(sc, coll, see_through)
    out = None
    try:
        if path is not None:
            out = Path(path).resolve()
            out.parent.mkdir(parents=True, exist_ok=True)
            bpy.context.preferences.filepaths.save_version = 0  # no .blend1 beside it
            bpy.ops.wm.save_as_mainfile(filepath=str(out), check_existing=False)
        if render_png is not None:
            png = Path(render_png).resolve()
            png.parent.mkdir(parents=True, exist_ok=True)
            render(sc, str(png), samples, size)
    except RuntimeError as exc:  # bpy.ops errors (disk full, no permission, ...)
        raise AnatomeshError(f"Blender could not write it ({exc})", path or render_png) from None
    return out


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


def setup_look(sc: bpy.types.Scene, collection: bpy.types.Collection,
               see_through: Sequence[str] = SEE_THROUGH, alpha: float = SEE_THROUGH_ALPHA) -> None:
    """See-through outer organs (oriented transparency), a neutral background, soft sun lights.

    The lights are placed relative to the scene camera (:func:`scene.frame_camera` first): a key
    from above-left and a weak fill from the right.
    """
    objs = scene.surface_objects(collection)
    for obj in objs:
        name = str(obj.get("anatomesh_name", obj.name)).lower()
        if any(word in name for word in see_through):
            obj["anatomesh_alpha"] = float(alpha)
            obj["anatomesh_oriented"] = 1.0
    world = sc.world or bpy.data.worlds.new("World")
    sc.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (0.09, 0.1, 0.12, 1.0)
        bg.inputs["Strength"].default_value = 0.5
    from mathutils import Matrix, Vector

    box = scene.bounds(objs)
    centre = Vector(tuple(box.mean(0))) if box is not None else Vector((0.0, 0.0, 0.0))
    cam = sc.camera
    to_cam = (cam.location - centre).normalized() if cam is not None else Vector((0.0, 1.0, 0.0))
    for name, energy, turn, raise_ in (("Key", 3.0, -35.0, 45.0), ("Fill", 1.0, 60.0, 5.0)):
        light = bpy.data.lights.new(f"Anatomesh {name}", "SUN")
        light.energy = energy
        light.angle = 0.15
        obj = bpy.data.objects.new(light.name, light)
        sc.collection.objects.link(obj)
        d = Matrix.Rotation(math.radians(turn), 3, "Z") @ to_cam
        horizontal = Vector((d.x, d.y, 0.0)).normalized()
        d = horizontal * math.cos(math.radians(raise_)) + Vector((0, 0, math.sin(math.radians(raise_))))
        obj.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()


def render(sc: bpy.types.Scene, path: str, samples: int = 32, size: Tuple[int, int] = (960, 540)) -> None:
    """Render the scene camera's view with Cycles on the CPU (denoised) into a PNG at ``path``."""
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = int(samples)
    sc.cycles.use_adaptive_sampling = True
    sc.cycles.transparent_max_bounces = 16
    try:
        sc.cycles.use_denoising = True
        sc.cycles.denoiser = "OPENIMAGEDENOISE"
    except (AttributeError, TypeError):
        pass
    sc.render.resolution_x, sc.render.resolution_y = int(size[0]), int(size[1])
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = "PNG"
    sc.render.filepath = path
    bpy.ops.render.render(write_still=True)
