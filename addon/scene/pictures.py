"""The pictures of a scan's scene: one framed camera per view (with its labels), which one renders,
and the turntable's frames and video — for the headless run and the add-on's buttons alike.

Each view has its own orthographic camera, ``Anatomesh Camera <view>``, framed by
:func:`~anatomesh.addon.scene.camera.frame_view`; its labels (:mod:`.labels`) sit in a collection
of their own that renders only while that camera is the scene's (:func:`show_view`).
"""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Dict, Optional, Sequence

import bpy

from . import camera as cams
from . import labels as labelling
from . import turntable as turning
from .objects import surface_objects


def camera_name(view: str) -> str:
    return f"{cams.CAMERA_NAME} {view}"


def add_view(sc: bpy.types.Scene, coll: bpy.types.Collection, view: str,
             labels_on: Sequence[str] = (), elevation: float = 0.0, azimuth: float = 0.0) -> bpy.types.Object:
    """The camera of ``view`` framing the scan ``coll`` (made or re-framed), with labels on the
    structures ``labels_on`` (none: its labels removed); it becomes the scene's camera."""
    objs = surface_objects(coll)
    cam = cams.frame_view(sc, objs, coll.anatomesh.space, view, elevation, azimuth, name=camera_name(view))
    show_view(sc, cam)  # other views' labels hidden: they must not stop this view's rays
    if labels_on:
        labelling.add_labels(sc, cam, objs, labels_on)
        cam["anatomesh_fill"] = [round(f, 4) for f in cams.filled(sc, cam, objs)]
    else:
        labelling.remove_labels(cam)
    show_view(sc, cam)
    return cam


def show_view(sc: bpy.types.Scene, cam: bpy.types.Object) -> None:
    """Make ``cam`` the scene's camera; only its labels render and show."""
    sc.camera = cam
    for coll in bpy.data.collections:
        owner = coll.get("anatomesh_camera")
        if owner is not None:
            coll.hide_render = coll.hide_viewport = owner != cam.name


def configure(sc: bpy.types.Scene, samples: int = 32, size=(960, 540)) -> None:
    """Cycles on the CPU, ``samples`` (adaptive, denoised), ``size`` pixels, PNG with the
    background: the settings the saved .blend keeps, so it renders the same picture again."""
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
    sc.render.image_settings.media_type = "IMAGE"
    sc.render.image_settings.file_format = "PNG"


@contextlib.contextmanager
def quick_frames(sc: bpy.types.Scene):
    """Settings for many frames of one scene, restored afterwards: the scene's render data kept
    between frames (only the camera moves) and the denoiser's quick prefilter."""
    old = sc.render.use_persistent_data, sc.cycles.denoising_prefilter
    sc.render.use_persistent_data, sc.cycles.denoising_prefilter = True, "FAST"
    try:
        yield sc
    finally:
        sc.render.use_persistent_data, sc.cycles.denoising_prefilter = old


def render_still(sc: bpy.types.Scene, path) -> Path:
    """Render the scene's camera into the PNG ``path`` (folders made)."""
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True, scene=sc.name)
    return path


def shoot(sc: bpy.types.Scene, coll: bpy.types.Collection, stills: Dict[str, Path],
          frames: Optional[Path] = None, video: Optional[Path] = None) -> Dict:
    """Render the view cameras made by :func:`add_view` into ``stills`` (view → PNG) and, when the
    scene has a turntable camera, its frames into the folder ``frames`` and the video ``video``
    (where Blender has FFmpeg). Returns what was made: per view the filled fractions of the frame
    (width, height) and the labelled structures, the turntable's frame count and video."""
    out: Dict = {"views": {}}
    for view, png in stills.items():
        cam = bpy.data.objects[camera_name(view)]
        show_view(sc, cam)
        render_still(sc, png)
        labelled = [c for c in bpy.data.collections if c.get("anatomesh_camera") == cam.name]
        out["views"][view] = {"fill": list(cam.get("anatomesh_fill", [])),
                              "labels": sorted(o["anatomesh_label"] for c in labelled for o in c.objects
                                               if o.type == "FONT"),
                              "hidden": list(labelled[0].get("anatomesh_hidden", [])) if labelled else []}
    turn = bpy.data.objects.get(turning.CAMERA_NAME)
    if frames is not None and turn is not None:
        show_view(sc, turn)  # no labels on the turn
        with quick_frames(sc):
            written = list(turning.render_frames(sc, turn, frames))
        made = turning.encode_video(written, video) if video is not None else None
        out["turntable"] = {"frames": len(written), "video": made is not None,
                            "note": "" if turning.can_encode_video() else "this Blender has no FFmpeg: no video"}
    if stills:
        show_view(sc, bpy.data.objects[camera_name(next(iter(stills)))])
    return out
