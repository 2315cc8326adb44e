"""View presets and framing: an orthographic camera looking at the anatomy from a side of the patient,
its frame filled by the visible surfaces.

Views are named by the side of the patient the camera stands at (the anatomical views of
atlases): ``anterior`` (the patient's front; their right on the image's left, head up),
``posterior``, ``lateral_left`` / ``lateral_right`` (the patient's left / right side),
``superior`` / ``inferior`` (from the head / the feet, anterior up) and ``oblique`` (anterior-left,
45° around the long axis and raised 20° toward the head). The directions come from the patient
axes of the collection's space (:func:`patient_axes`), so an LPS scene is seen from the same
anatomical side as an RAS one.

The camera is orthographic: the frame's size (``ortho_scale``, mm) is set from the extent of the
surfaces' vertices projected onto the image plane, so the anatomy fills exactly ``fill`` of the
frame's width or height (whichever is limiting) and is centred.
"""
from __future__ import annotations

from typing import Iterable, Optional, Sequence, Tuple

import bpy
import numpy as np

from ...app.flow.recipe import VIEWS  # the view presets, the default first

#: the part of the frame's width or height the anatomy fills
FILL = 0.9
#: the oblique view: degrees around the long axis from anterior toward the patient's left, and up
OBLIQUE_TURN, OBLIQUE_RAISE = 45.0, 20.0
CAMERA_NAME = "Anatomesh Camera"


def patient_axes(space: str) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (3,) toward the patient's anterior, left and superior in ``space`` coordinates.

    RAS: +x right, +y anterior, +z superior; LPS: +x left, +y posterior, +z superior (DICOM).
    """
    sign = 1.0 if str(space).upper() == "RAS" else -1.0
    return (np.array([0.0, sign, 0.0]), np.array([-sign, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))


def view_axes(view: str, space: str = "RAS", elevation: float = 0.0,
              azimuth: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """``(to_camera, up)``: unit vectors (3,) from the anatomy toward the camera and the image's up.

    ``elevation`` (degrees) then raises the camera toward the head (about the image's horizontal),
    ``azimuth`` turns it about the patient's long axis (positive: toward the patient's left).
    """
    front, left, head = patient_axes(space)
    if view == "oblique":
        elevation, azimuth = elevation + OBLIQUE_RAISE, azimuth + OBLIQUE_TURN
    table = {"anterior": (front, head), "posterior": (-front, head), "lateral_left": (left, head),
             "lateral_right": (-left, head), "superior": (head, front), "inferior": (-head, front),
             "oblique": (front, head)}
    if view not in table:
        from ...core.model.errors import AnatomeshError

        raise AnatomeshError(f"unknown view {view!r}; use one of {', '.join(VIEWS)}")
    to_cam, up = table[view]
    side = np.cross(to_cam, up)  # the image's left: turning about it raises the camera
    to_cam, up = _turn(to_cam, side, elevation), _turn(up, side, elevation)
    return _turn(to_cam, head, azimuth), _turn(up, head, azimuth)


def _turn(v: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """``v`` rotated about the unit ``axis`` by ``degrees`` (right hand; Rodrigues' formula)."""
    a = np.radians(degrees)
    return v * np.cos(a) + np.cross(axis, v) * np.sin(a) + axis * np.dot(axis, v) * (1 - np.cos(a))


def visible(objects: Iterable[bpy.types.Object]) -> list:
    """The mesh objects of ``objects`` that render (not hidden from renders, with vertices)."""
    return [o for o in objects if o.type == "MESH" and not o.hide_render and len(o.data.vertices)]


def world_points(objects: Iterable[bpy.types.Object]) -> np.ndarray:
    """Every vertex of the objects in world coordinates, (N, 3) float64 mm."""
    chunks = []
    for o in objects:
        n = len(o.data.vertices)
        co = np.empty(n * 3, np.float32)
        o.data.vertices.foreach_get("co", co)
        m = np.array(o.matrix_world, np.float64)
        chunks.append(co.reshape(n, 3) @ m[:3, :3].T + m[:3, 3])
    return np.concatenate(chunks) if chunks else np.zeros((0, 3))


def aspect(scene: bpy.types.Scene) -> float:
    """The render's width / height (pixel aspect included)."""
    r = scene.render
    return (r.resolution_x * r.pixel_aspect_x) / max(1e-9, r.resolution_y * r.pixel_aspect_y)


def frame_size(scene: bpy.types.Scene, ortho_scale: float) -> Tuple[float, float]:
    """The frame's (width, height) in mm of an orthographic camera (sensor fit AUTO)."""
    a = aspect(scene)
    return (ortho_scale, ortho_scale / a) if a >= 1 else (ortho_scale * a, ortho_scale)


def scale_for(scene: bpy.types.Scene, width: float, height: float) -> float:
    """The ``ortho_scale`` (mm) whose frame holds ``width`` x ``height`` mm."""
    a = aspect(scene)
    return max(width, height * a) if a >= 1 else max(width / a, height)


def camera_object(scene: bpy.types.Scene, name: str = CAMERA_NAME) -> bpy.types.Object:
    """The camera object ``name`` (made and linked to the scene if missing), orthographic."""
    cam = bpy.data.objects.get(name)
    if cam is None or cam.type != "CAMERA":
        cam = bpy.data.objects.new(name, bpy.data.cameras.new(name))
    if scene.collection not in cam.users_collection and not any(
            cam.name in c.objects for c in scene.collection.children_recursive):
        scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.sensor_fit = "AUTO"
    return cam


def aim(cam: bpy.types.Object, points: np.ndarray, to_cam: np.ndarray, up: np.ndarray,
        scene: bpy.types.Scene, fill: float = FILL, extra: Sequence[float] = (0.0, 0.0)) -> Tuple[float, float]:
    """Place the orthographic ``cam`` looking along ``-to_cam`` with ``up`` as the image's up, centred
    on ``points`` (N, 3) mm, its frame filled to ``fill`` by their projection.

    ``extra`` (left, right) mm: room kept beside the anatomy (label columns); the frame is centred
    on the anatomy plus that room. Returns the anatomy's filled fraction (width, height) of the frame.
    """
    from mathutils import Matrix

    forward = -to_cam / np.linalg.norm(to_cam)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    x, y, z = points @ right, points @ up, points @ forward
    lo_x, hi_x = x.min() - extra[0], x.max() + extra[1]
    w, h = (hi_x - lo_x), (y.max() - y.min())
    scale = scale_for(scene, max(w, 1e-3) / fill, max(h, 1e-3) / fill)
    depth = float(z.max() - z.min())
    back = depth + 0.5 * scale + 10.0  # mm in front of the nearest surface
    loc = right * (lo_x + hi_x) / 2 + up * (y.max() + y.min()) / 2 + forward * (z.min() - back)
    rot = np.column_stack([right, up, -forward])  # camera axes: x right, y up, looking down -z
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, loc
    cam.matrix_world = Matrix(m.tolist())
    cam.data.ortho_scale = float(scale)
    cam.data.clip_start = 1.0
    cam.data.clip_end = float(back + depth + 0.5 * scale + 10.0)
    fw, fh = frame_size(scene, scale)
    return float((x.max() - x.min()) / fw), float(h / fh)


def frame_view(scene: bpy.types.Scene, objects, space: str = "RAS", view: str = "anterior",
               elevation: float = 0.0, azimuth: float = 0.0, fill: float = FILL,
               name: str = CAMERA_NAME, extra: Sequence[float] = (0.0, 0.0),
               make_active: bool = True) -> bpy.types.Object:
    """Frame the rendered surfaces of ``objects`` from ``view`` (:data:`VIEWS`) with the camera
    ``name`` (made if missing; the scene's camera when ``make_active``); returns it.

    The camera keeps ``anatomesh_view`` and ``anatomesh_fill`` ([width, height] fractions)."""
    from ...core.model.errors import AnatomeshError

    objs = visible(objects)
    if not objs:
        raise AnatomeshError("nothing to frame: no visible surface in the scan")
    to_cam, up = view_axes(view, space, elevation, azimuth)
    cam = camera_object(scene, name)
    fill_wh = aim(cam, world_points(objs), to_cam, up, scene, fill, extra)
    cam["anatomesh_view"] = view
    cam["anatomesh_fill"] = [round(f, 4) for f in fill_wh]
    if make_active:
        scene.camera = cam
    return cam


def projected(scene: bpy.types.Scene, cam: bpy.types.Object, points: np.ndarray) -> np.ndarray:
    """``points`` (N, 3) world mm in the camera's normalised frame (N, 3): x, y in 0..1 across the
    image (0, 0 bottom left), z the distance in front of the camera (mm), as
    :func:`bpy_extras.object_utils.world_to_camera_view` gives them (orthographic camera)."""
    m = np.linalg.inv(np.array(cam.matrix_world, np.float64))
    local = points @ m[:3, :3].T + m[:3, 3]
    fw, fh = frame_size(scene, cam.data.ortho_scale)
    return np.column_stack([local[:, 0] / fw + 0.5, local[:, 1] / fh + 0.5, -local[:, 2]])


def filled(scene: bpy.types.Scene, cam: bpy.types.Object, objects) -> Optional[Tuple[float, float]]:
    """The fractions (width, height) of the frame the visible surfaces' projection spans."""
    pts = world_points(visible(objects))
    if not len(pts):
        return None
    p = projected(scene, cam, pts)
    return float(np.ptp(p[:, 0])), float(np.ptp(p[:, 1]))
