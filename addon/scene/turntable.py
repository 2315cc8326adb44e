"""A turntable: an orthographic camera circling the anatomy about the patient's long (superior) axis,
one full turn over N frames, rendered frame by frame into PNGs and, when Blender has FFmpeg, into
an MP4 video.

The camera hangs on an empty (the pivot) at the anatomy's centre; a driver turns the pivot by
``360° (frame − 1) / N`` (a simple expression: it runs without Python scripts enabled), so frame
N + 1 would repeat frame 1 and the video loops seamlessly. The frame's size fits the anatomy at
every angle of the turn (:data:`~anatomesh.addon.scene.camera.FILL` of the widest one).
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterator, List, Optional, Sequence

import bpy
import numpy as np

from . import camera as cams

PIVOT_NAME, CAMERA_NAME = "Anatomesh Turntable Pivot", "Anatomesh Turntable"
#: frames per second of the video
FPS = 12


def add_turntable(scene: bpy.types.Scene, objects: Sequence[bpy.types.Object], space: str, frames: int,
                  elevation: float = 10.0, fill: float = cams.FILL) -> bpy.types.Object:
    """The turntable camera (made or re-made) circling the visible ``objects`` in ``frames`` frames,
    starting from the patient's front raised ``elevation`` degrees; sets the scene's frame range
    to 1..frames (the scene's camera is left as it was). Returns the camera."""
    from mathutils import Matrix

    objs = cams.visible(objects)
    pts = cams.world_points(objs)
    lo, hi = pts.min(0), pts.max(0)
    centre = (lo + hi) / 2
    pivot = bpy.data.objects.get(PIVOT_NAME) or bpy.data.objects.new(PIVOT_NAME, None)
    if not pivot.users_collection:
        scene.collection.objects.link(pivot)
    pivot.empty_display_size = float(np.linalg.norm(hi - lo)) / 4
    pivot.location = tuple(centre)
    cam = cams.camera_object(scene, CAMERA_NAME)
    to_cam, up = cams.view_axes("anterior", space, elevation)
    forward = -to_cam
    right = np.cross(forward, up)
    rel = pts - centre
    angles = 2 * np.pi * np.arange(frames) / frames
    xs, ys = [], []
    for a in angles:  # the pivot turns the camera by a: the anatomy turns by -a in its view
        c, s = np.cos(a), np.sin(a)
        turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        xs.append(np.abs(rel @ (turn @ right)).max())
        y = rel @ (turn @ up)
        ys.append((y.min(), y.max()))
    ys = np.array(ys)
    y_lo, y_hi = ys[:, 0].min(), ys[:, 1].max()
    cam.data.ortho_scale = cams.scale_for(scene, 2 * max(xs) / fill, (y_hi - y_lo) / fill)
    reach = float(np.linalg.norm(hi - lo))
    m = np.eye(4)
    m[:3, :3] = np.column_stack([right, up, -forward])
    m[:3, 3] = up * (y_lo + y_hi) / 2 + to_cam * (reach + 10.0)
    cam.parent = pivot
    cam.matrix_parent_inverse = Matrix.Identity(4)
    cam.matrix_basis = Matrix(m.tolist())
    cam.data.clip_start, cam.data.clip_end = 1.0, 2 * reach + 20.0
    cam["anatomesh_view"] = "turntable"
    _spin(pivot, frames)
    scene.frame_start, scene.frame_end = 1, int(frames)
    scene.render.fps = FPS
    return cam


def _spin(pivot: bpy.types.Object, frames: int) -> None:
    """Drive the pivot's turn about z: a full turn over ``frames`` frames, frame 1 at 0°."""
    pivot.driver_remove("rotation_euler", 2)
    fc = pivot.driver_add("rotation_euler", 2)
    fc.driver.type = "SCRIPTED"
    fc.driver.expression = f"(frame - 1) * 2 * pi / {int(frames)}"


def frame_paths(folder, frames: int) -> List[Path]:
    """The PNG of each frame: ``folder/frame_0001.png`` ..."""
    return [Path(folder) / f"frame_{i:04d}.png" for i in range(1, int(frames) + 1)]


def render_frames(scene: bpy.types.Scene, cam: bpy.types.Object, folder) -> Iterator[Path]:
    """Render the scene's frames 1..frame_end through ``cam`` into :func:`frame_paths` (the render
    settings as they are), yielding each PNG once written (so a caller can show progress or stop)."""
    old_cam, old_frame = scene.camera, scene.frame_current
    scene.camera = cam
    Path(folder).mkdir(parents=True, exist_ok=True)
    try:
        for i, path in enumerate(frame_paths(folder, scene.frame_end), start=1):
            scene.frame_set(i)
            scene.render.image_settings.file_format = "PNG"
            scene.render.filepath = str(path)
            bpy.ops.render.render(write_still=True, scene=scene.name)
            yield path
    finally:
        scene.camera = old_cam
        scene.frame_set(old_frame)


def can_encode_video() -> bool:
    """True when this Blender was built with FFmpeg (MP4 output)."""
    return bool(getattr(bpy.app.build_options, "codec_ffmpeg", False))


def encode_video(frames: Sequence[Path], path, fps: int = FPS) -> Optional[Path]:
    """An H.264 MP4 at ``path`` of the PNG ``frames`` (in order), through Blender's sequencer in a
    scene of its own (removed afterwards); None when Blender has no FFmpeg."""
    if not can_encode_video() or not frames:
        return None
    path = Path(path).resolve()
    first = Path(frames[0])
    vid = bpy.data.scenes.new("Anatomesh Turntable Video")
    try:
        seq = vid.sequence_editor_create()
        strip = seq.strips.new_image("frames", str(first), 1, 1)
        for f in frames[1:]:
            strip.elements.append(Path(f).name)
        r = vid.render
        r.resolution_x, r.resolution_y = _image_size(first)
        r.resolution_percentage, r.fps = 100, int(fps)
        vid.frame_start, vid.frame_end = 1, len(frames)
        r.image_settings.media_type = "VIDEO"
        r.image_settings.file_format = "FFMPEG"
        r.ffmpeg.format, r.ffmpeg.codec = "MPEG4", "H264"
        r.ffmpeg.constant_rate_factor = "HIGH"
        r.use_file_extension = False
        r.filepath = str(path)
        bpy.ops.render.render(animation=True, scene=vid.name)
    finally:
        bpy.data.scenes.remove(vid)
    return path if path.exists() else None


def _image_size(png: Path):
    import struct

    data = Path(png).read_bytes()[16:24]
    w, h = struct.unpack(">II", data)
    return int(w) - int(w) % 2, int(h) - int(h) % 2  # H.264 wants even sizes
