"""The camera side of the Look panel: view presets framing the scan, labels on the selected
structures, and the turntable rendered one frame at a time (so the operator shows progress and
can stop between frames). The same scene functions build the headless run's pictures
(:mod:`anatomesh.addon.scene.pictures`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import bpy

from ..scene import labels as labelling
from ..scene import pictures
from ..scene import turntable as turning
from ..scene.objects import surface_objects


def set_view(context, coll, view: str, elevation: float = 0.0, azimuth: float = 0.0) -> bpy.types.Object:
    """Frame the scan ``coll`` from ``view`` with its own camera, made the scene's camera (its
    labels, if any, are removed: add them again for the new framing)."""
    return pictures.add_view(context.scene, coll, view, (), elevation, azimuth)


def label_selected(context, coll) -> bpy.types.Collection:
    """Label the selected surfaces of ``coll`` in the scene camera's view (a view preset's camera);
    replaces that camera's labels."""
    from ...core.model.errors import AnatomeshError

    cam = context.scene.camera
    if cam is None or cam.get("anatomesh_view") in (None, "turntable"):
        raise AnatomeshError("the scene camera is not a view of the scan: set a view first (Frame Camera)")
    objs = surface_objects(coll)
    names = [str(o.get("anatomesh_name", o.name)) for o in objs if o.select_get()]
    if not names:
        raise AnatomeshError("select the structures to label (in the viewport or the outliner)")
    out = labelling.add_labels(context.scene, cam, objs, names)
    pictures.show_view(context.scene, cam)
    return out


def turntable_folder(directory: str) -> Path:
    """The frames' folder: ``turntable`` in ``directory`` (a ``//`` path is beside the .blend)."""
    from .common import abspath

    return Path(abspath(directory or "//")) / "turntable"


class TurntableJob:
    """One turntable render: :meth:`step` renders the next frame; :meth:`finish` writes the video."""

    def __init__(self, context, coll, frames: int, directory: str):
        sc = context.scene
        self.scene, self.frames, self.folder = sc, int(frames), turntable_folder(directory)
        cam = turning.add_turntable(sc, surface_objects(coll), coll.anatomesh.space, self.frames)
        self.old_camera = sc.camera
        pictures.show_view(sc, cam)
        self.quick = pictures.quick_frames(sc)
        self.quick.__enter__()
        self.todo = turning.render_frames(sc, cam, self.folder)
        self.written = []

    def step(self) -> bool:
        """Render the next frame; False when every frame is written."""
        path = next(self.todo, None)
        if path is None:
            return False
        self.written.append(path)
        return True

    def finish(self, cancelled: bool = False) -> Optional[Path]:
        """Close the render (settings and camera back); the MP4 unless ``cancelled``."""
        self.todo.close()
        self.quick.__exit__(None, None, None)
        if self.old_camera is not None:
            pictures.show_view(self.scene, self.old_camera)
        if cancelled or len(self.written) < self.frames:
            return None
        return turning.encode_video(self.written, self.folder.parent / "turntable.mp4")
