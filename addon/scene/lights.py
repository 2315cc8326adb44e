"""Light presets for a scan's scene: ``studio`` (three-point) and ``atlas`` (bright and even).

:func:`apply_lights` removes the lights it made before and places new ones relative to the scene
camera and the anatomy's bounding box, so the look follows the framing:

* ``studio`` — the photographer's three-point rig (key, fill, back light; e.g. Millerson, *The
  Technique of Lighting for Television and Film*): a warm, large area key from the camera's
  upper left that models the organs' shapes with soft shadows; a cooler, weaker, larger fill from
  the right that opens the shadows (about 1:3); a back (rim) light from behind and above that
  traces the silhouettes, so thin vessels and bowel loops separate from what lies behind them.
  Dark grey-blue backdrop, low ambient light.
* ``atlas`` — the plate of an anatomy atlas: a light, near-white backdrop and bright, even light
  from the whole sky (its occlusion darkens creases and contacts the way ambient occlusion does),
  plus one very large, gentle key from the upper left for a soft sense of form.

The world separates what the camera sees (the backdrop, Light Path *Is Camera Ray*) from the
light it gives, so each preset sets both. Area lights' power falls off with distance (Blender
units are mm here), so each light's power is set from the irradiance it should give at the
anatomy: P = E * pi * d^2 (a small Lambertian emitter facing the target).
"""
from __future__ import annotations

import math
from typing import Dict, Iterable, Sequence

import bpy
import numpy as np

from ...app.flow.recipe import LIGHTS as PRESETS
from .objects import bounds

#: custom property marking the lights this module made
LIGHT_PROPERTY = "anatomesh_light"
WORLD_NAME = "Anatomesh World"

#: per preset: backdrop colour (linear RGB, seen by the camera), ambient colour and strength (the
#: world's light), and lights as (name, azimuth deg to the camera's right, elevation deg,
#: irradiance, size as a fraction of the box diagonal, colour); azimuth 180 is behind the anatomy
LOOKS: Dict[str, Dict] = {
    "studio": dict(backdrop=(0.045, 0.05, 0.06), ambient=(0.8, 0.85, 1.0), ambient_strength=0.2,
                   view="AgX", look="AgX - Punchy", exposure=0.3,
                   lights=(("Key", -40.0, 40.0, 4.5, 0.6, (1.0, 0.95, 0.88)),
                           ("Fill", 55.0, 10.0, 1.5, 1.0, (0.85, 0.9, 1.0)),
                           ("Rim", 160.0, 45.0, 6.0, 0.35, (0.95, 0.97, 1.0)))),
    "atlas": dict(backdrop=(0.85, 0.85, 0.84), ambient=(1.0, 1.0, 1.0), ambient_strength=0.7,
                  view="Khronos PBR Neutral", look="None", exposure=0.0,
                  lights=(("Key", -35.0, 50.0, 2.4, 1.0, (1.0, 0.98, 0.95)),)),
}
assert tuple(LOOKS) == PRESETS


def check_preset(preset: str) -> str:
    """``preset`` if it is one of :data:`PRESETS`, else :class:`AnatomeshError`."""
    if preset not in LOOKS:
        from ...core.model.errors import AnatomeshError

        raise AnatomeshError(f"light preset {preset!r} is not one of {', '.join(PRESETS)}")
    return preset


def apply_lights(scene: bpy.types.Scene, objects: Iterable[bpy.types.Object], preset: str = "studio") -> list:
    """Light ``objects`` (the scan's surfaces) with ``preset``; returns the light objects made.

    Lights made earlier by this function are removed first; positions follow the scene camera
    (the front of the patient when there is none) and the objects' bounding box.
    """
    look = LOOKS[check_preset(preset)]
    remove_lights(scene)
    box = bounds(objects)
    if box is None:
        box = np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
    centre = box.mean(0)
    diagonal = float(np.linalg.norm(box[1] - box[0])) or 1.0
    forward = _camera_forward(scene, centre)
    set_world(scene, look["backdrop"], look["ambient"], look["ambient_strength"])
    set_tone(scene, look["view"], look["look"], look["exposure"])
    made = []
    for name, azimuth, elevation, irradiance, size, colour in look["lights"]:
        direction = _direction(forward, azimuth, elevation)  # from the centre toward the light
        distance = 1.5 * diagonal
        light = bpy.data.lights.new(f"Anatomesh {name}", "AREA")
        light.shape = "DISK"
        light.size = size * diagonal
        light.color = colour
        light.energy = irradiance * math.pi * distance ** 2
        obj = bpy.data.objects.new(light.name, light)
        obj[LIGHT_PROPERTY] = preset
        obj.location = tuple(centre + direction * distance)
        from mathutils import Vector

        obj.rotation_euler = Vector(tuple(-direction)).to_track_quat("-Z", "Y").to_euler()
        scene.collection.objects.link(obj)
        made.append(obj)
    scene["anatomesh_light"] = preset
    return made


def remove_lights(scene: bpy.types.Scene) -> None:
    """Delete the lights :func:`apply_lights` made (and the two suns of older files)."""
    for obj in list(scene.objects):
        if obj.type == "LIGHT" and (LIGHT_PROPERTY in obj or obj.name.startswith(("Anatomesh Key",
                                                                                 "Anatomesh Fill"))):
            data = obj.data
            bpy.data.objects.remove(obj)
            if data.users == 0:
                bpy.data.lights.remove(data)


def _camera_forward(scene, centre: np.ndarray) -> np.ndarray:
    """Unit vector from the camera toward the anatomy (the patient's front view without one)."""
    cam = scene.camera
    if cam is None:
        return np.array([0.0, -1.0, 0.0])
    m = np.array(cam.matrix_world)
    forward = -m[:3, 2]  # a camera looks down its local -Z
    return forward / (np.linalg.norm(forward) or 1.0)


def _direction(forward: np.ndarray, azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector from the anatomy toward a light ``azimuth`` degrees to the camera's right of
    the camera direction (about the world's up axis) and ``elevation`` degrees above the horizon."""
    to_cam = -np.asarray(forward, float)
    flat = np.array([to_cam[0], to_cam[1], 0.0])
    if np.linalg.norm(flat) < 1e-6:  # looking straight down or up: any horizontal reference
        flat = np.array([0.0, 1.0, 0.0])
    flat /= np.linalg.norm(flat)
    right = np.cross(flat, [0.0, 0.0, 1.0])  # the camera's right seen from the anatomy is -right
    a, e = math.radians(azimuth), math.radians(elevation)
    horizontal = flat * math.cos(a) - right * math.sin(a)
    d = horizontal * math.cos(e) + np.array([0.0, 0.0, math.sin(e)])
    return d / np.linalg.norm(d)


def set_tone(scene: bpy.types.Scene, view: str, look: str, exposure: float) -> None:
    """Colour management: the view transform and its look, and the exposure (stops); a
    transform this Blender lacks leaves the current one."""
    vs = scene.view_settings
    try:
        vs.view_transform = view
        vs.look = look
    except TypeError:
        pass
    vs.exposure = float(exposure)


def set_world(scene: bpy.types.Scene, backdrop: Sequence[float], ambient: Sequence[float],
              strength: float) -> bpy.types.World:
    """The world: ``backdrop`` where the camera sees it, ``ambient`` x ``strength`` as light."""
    world = bpy.data.worlds.get(WORLD_NAME) or bpy.data.worlds.new(WORLD_NAME)
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputWorld")
    out.location = (400, 0)
    seen = nodes.new("ShaderNodeBackground")
    seen.name = seen.label = "Backdrop"
    seen.inputs["Color"].default_value = (*backdrop, 1.0)
    seen.inputs["Strength"].default_value = 1.0
    seen.location = (0, 100)
    light = nodes.new("ShaderNodeBackground")
    light.name = light.label = "Ambient"
    light.inputs["Color"].default_value = (*ambient, 1.0)
    light.inputs["Strength"].default_value = float(strength)
    light.location = (0, -100)
    path = nodes.new("ShaderNodeLightPath")
    path.location = (-250, 250)
    mix = nodes.new("ShaderNodeMixShader")
    mix.location = (200, 0)
    links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    links.new(light.outputs["Background"], mix.inputs[1])
    links.new(seen.outputs["Background"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    world.color = tuple(backdrop)  # the viewport's world colour
    return world
