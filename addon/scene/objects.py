"""Surfaces into the Blender scene: units, one collection per scan, objects, materials.

* Units: metric, millimetres, unit scale 0.001 — one Blender unit is one millimetre and the
  viewport, the N panel and the 3D-Print Toolbox show real sizes.
* A scan becomes a collection named after the file (a second import of the same scan becomes
  ``name.001``; nothing the user already has is renamed, replaced or deleted).
* Each label or isosurface is one object named after it, carrying custom properties that say
  where it came from (:data:`OBJECT_PROPS`).
* Each object gets its own material: Principled BSDF in the label's colour; opacity is read from
  the object's ``anatomesh_alpha`` property by an Attribute node, so it can be changed per object,
  keyed or driven without touching the material. An optional view-dependent ("oriented")
  transparency makes surfaces more opaque toward their silhouettes, so nested organs stay readable
  (transparency modulated by orientation, Stalling et al. 1999 (Zuse Institute Berlin); a
  variation of Kay & Greenberg 1979, "Transparency for computer synthesized images"): the Layer Weight node's *Facing* output (0 facing the viewer, 1 at grazing
  angles) mixes from the object's opacity up to the edge opacity.
"""
from __future__ import annotations

from typing import Dict, Iterable, Optional, Sequence

import bpy
import numpy as np

from ...core.model.labels import srgb_to_linear
from . import bridge

#: custom properties set on every surface object
OBJECT_PROPS = (
    "anatomesh_value",      # label value or isovalue
    "anatomesh_name",       # label name / level name
    "anatomesh_source",     # path of the scan
    "anatomesh_series_uid",  # DICOM SeriesInstanceUID ("" otherwise)
    "anatomesh_space",      # "RAS" or "LPS": the space of the vertex coordinates
    "anatomesh_affine",     # voxel index → mm, 16 floats row by row
    "anatomesh_units",      # "mm"
    "anatomesh_alpha",      # opacity 0..1 read by the material
    "anatomesh_oriented",   # 0/1: view-dependent transparency on
)

ORIENTED_GROUP = "Anatomesh Oriented Alpha"
#: the colour attribute of per-vertex colours that came with a surface (distance, difference maps)
COLOR_ATTRIBUTE = "anatomesh_color"


# ---------------------------------------------------------------------------------------------
# units and collections
# ---------------------------------------------------------------------------------------------
def setup_units(scene: bpy.types.Scene) -> None:
    """Metric, millimetres, unit scale 0.001: 1 Blender unit is shown as 1 mm."""
    us = scene.unit_settings
    us.system = "METRIC"
    us.scale_length = 0.001
    us.length_unit = "MILLIMETERS"


def new_collection(name: str, parent: Optional[bpy.types.Collection] = None) -> bpy.types.Collection:
    """A new collection linked under ``parent`` (default: the scene's master collection).

    If ``name`` is taken (by any collection in the file), Blender's own suffix is used
    (``scan.001``), so earlier imports are never replaced.
    """
    coll = bpy.data.collections.new(name)
    (parent or bpy.context.scene.collection).children.link(coll)
    return coll


def scan_name(path) -> str:
    """A readable collection name from a scan path (``example_seg.nii.gz`` → ``example_seg``)."""
    import os

    base = os.path.basename(os.path.normpath(str(path))) or "scan"
    for suffix in (".nii.gz", ".nii", ".seg.nrrd", ".nrrd", ".nhdr", ".dcm"):
        if base.lower().endswith(suffix):
            return base[: -len(suffix)] or "scan"
    return base


# ---------------------------------------------------------------------------------------------
# objects
# ---------------------------------------------------------------------------------------------
def add_surface(collection: bpy.types.Collection, name: str, vertices: np.ndarray, faces: np.ndarray,
                props: Dict, color: Sequence[float] = (0.8, 0.8, 0.8), render_method: str = "DITHERED",
                shared_index: Optional[np.ndarray] = None,
                vertex_colors: Optional[np.ndarray] = None,
                rest: Optional[np.ndarray] = None) -> bpy.types.Object:
    """Create one surface object in ``collection``.

    ``vertices`` (N, 3) mm, ``faces`` (M, 3); ``props`` are written as custom properties (see
    :data:`OBJECT_PROPS`); the unsmoothed positions (``rest``, default ``vertices``: for a shell,
    its set's positions, before its pinch points are moved apart) are kept as the
    ``anatomesh_rest`` attribute and, when given, each vertex's index in the shared surface set
    as ``anatomesh_vid``.
    ``vertex_colors`` (N, 3|4) sRGB, optional: the colour attribute :data:`COLOR_ATTRIBUTE`
    (active, shown when the viewport colours by attribute).
    """
    me = bridge.new_mesh(name, vertices, faces)
    bridge.set_point_attribute(me, bridge.REST_ATTRIBUTE, vertices if rest is None else rest, "vector")
    if shared_index is not None:
        bridge.set_point_attribute(me, bridge.SHARED_INDEX_ATTRIBUTE, shared_index, "int")
    if vertex_colors is not None:
        set_vertex_colors(me, vertex_colors)
    obj = bpy.data.objects.new(name, me)
    for key, val in props.items():
        obj[key] = val
    for key, default in (("anatomesh_alpha", 1.0), ("anatomesh_oriented", 0.0)):
        if key not in obj:
            obj[key] = default
    _property_ui(obj)
    obj.color = linear_rgba(color)  # the Solid viewport's "Object" colour
    me.materials.append(surface_material(name, color, render_method))
    collection.objects.link(obj)
    return obj


def set_vertex_colors(me: bpy.types.Mesh, colors: np.ndarray, name: str = "") -> None:
    """Per-vertex colours (N, 3|4) sRGB in [0, 1] as a linear FLOAT_COLOR point attribute
    (``name``, default :data:`COLOR_ATTRIBUTE`), made the active and render colour attribute."""
    name = name or COLOR_ATTRIBUTE
    c = np.asarray(colors, np.float32)
    rgba = np.ones((len(c), 4), np.float32)
    rgba[:, :3] = srgb_to_linear(c[:, :3])
    if c.shape[1] == 4:
        rgba[:, 3] = c[:, 3]
    attr = me.color_attributes.get(name)
    if attr is not None:
        me.color_attributes.remove(attr)
    attr = me.color_attributes.new(name, "FLOAT_COLOR", "POINT")
    attr.data.foreach_set("color", rgba.ravel())
    me.color_attributes.active_color = attr
    me.color_attributes.default_color_name = name


def _property_ui(obj: bpy.types.Object) -> None:
    """Slider ranges and tooltips for the properties users touch."""
    try:
        ui = obj.id_properties_ui("anatomesh_alpha")
        ui.update(min=0.0, max=1.0, soft_min=0.0, soft_max=1.0, description="Opacity of this surface")
        ui = obj.id_properties_ui("anatomesh_oriented")
        ui.update(min=0.0, max=1.0, description="1: more opaque toward the silhouette (oriented transparency)")
    except (TypeError, AttributeError):  # pragma: no cover - older Blender
        pass


def surface_objects(collection: bpy.types.Collection) -> list:
    """The Anatomesh surface objects of a collection (meshes with an ``anatomesh_value``)."""
    return [o for o in collection.all_objects if o.type == "MESH" and "anatomesh_value" in o]


def set_alpha(objects: Iterable[bpy.types.Object], alpha: float, oriented: Optional[bool] = None) -> None:
    """Set the opacity (and optionally the oriented transparency) of surface objects."""
    for o in objects:
        o["anatomesh_alpha"] = float(alpha)
        if oriented is not None:
            o["anatomesh_oriented"] = 1.0 if oriented else 0.0
        o.update_tag()
        if o.data is not None:
            o.data.update_tag()


def set_render_method(objects: Iterable[bpy.types.Object], method: str) -> None:
    """EEVEE transparency: "DITHERED" (depth-correct, nested surfaces) or "BLENDED" (sorted per object)."""
    for o in objects:
        for mat in getattr(o.data, "materials", []):
            if mat is not None:
                _render_settings(mat, method)


# ---------------------------------------------------------------------------------------------
# materials
# ---------------------------------------------------------------------------------------------
def linear_rgba(color: Sequence[float]) -> tuple:
    """A label colour (sRGB-encoded 0..1, as label tables and ``Mesh.color`` give it) as the
    linear RGBA Blender's colour properties and shader sockets hold (the glTF/3MF writers convert
    the same way, so every output shows the same colour)."""
    return (*[float(c) for c in srgb_to_linear(np.asarray(color[:3], float))], 1.0)


def surface_material(name: str, color: Sequence[float], render_method: str = "DITHERED") -> bpy.types.Material:
    """A new material: Principled BSDF base colour ``color``, opacity from the object.

    Alpha = mix(object ``anatomesh_alpha``, oriented alpha, object ``anatomesh_oriented``).
    """
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    rgba = linear_rgba(color)
    mat.diffuse_color = rgba  # viewport Solid mode "Material" colour
    nt = mat.node_tree
    nodes, links = nt.nodes, nt.links
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None) or nodes.new("ShaderNodeBsdfPrincipled")
    out = next((n for n in nodes if n.type == "OUTPUT_MATERIAL"), None) or nodes.new("ShaderNodeOutputMaterial")
    if not out.inputs["Surface"].is_linked:
        links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    bsdf.inputs["Base Color"].default_value = rgba
    bsdf.inputs["Roughness"].default_value = 0.45
    if "Coat Weight" in bsdf.inputs:  # a thin wet coat reads as tissue
        bsdf.inputs["Coat Weight"].default_value = 0.15

    alpha = _object_attribute(nodes, "anatomesh_alpha", (-700, -200))
    oriented_on = _object_attribute(nodes, "anatomesh_oriented", (-700, -420))
    group = nodes.new("ShaderNodeGroup")
    group.node_tree = oriented_alpha_group()
    group.location = (-480, -260)
    links.new(alpha.outputs["Fac"], group.inputs["Alpha"])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "FLOAT"
    mix.location = (-260, -300)
    links.new(oriented_on.outputs["Fac"], mix.inputs["Factor"])
    links.new(alpha.outputs["Fac"], mix.inputs["A"])
    links.new(group.outputs["Alpha"], mix.inputs["B"])
    links.new(mix.outputs["Result"], bsdf.inputs["Alpha"])
    _render_settings(mat, render_method)
    return mat


def _object_attribute(nodes, name: str, location) -> bpy.types.Node:
    node = nodes.new("ShaderNodeAttribute")
    node.attribute_type = "OBJECT"
    node.attribute_name = name
    node.label = name
    node.location = location
    return node


def _render_settings(mat: bpy.types.Material, method: str) -> None:
    """Transparency that works for surfaces nested inside each other (EEVEE 4.2+; Cycles needs none)."""
    if hasattr(mat, "surface_render_method"):  # Blender 4.2+
        mat.surface_render_method = method if method in ("DITHERED", "BLENDED") else "DITHERED"
        # BLENDED: show the back faces too and sort them within the object
        mat.use_transparency_overlap = True
    else:  # pragma: no cover - Blender < 4.2
        mat.blend_method = "BLEND" if method == "BLENDED" else "HASHED"
        mat.show_transparent_back = True
    mat.use_backface_culling = False
    if hasattr(mat, "use_transparent_shadow"):
        mat.use_transparent_shadow = True


def oriented_alpha_group() -> bpy.types.ShaderNodeTree:
    """The shared node group: ``Alpha out = mix(Alpha, Edge Alpha, Facing)``.

    Inputs: *Alpha* (opacity facing the viewer), *Edge Alpha* (opacity at the silhouette, default
    1), *Blend* (Layer Weight blend, 0..1: larger = wider opaque rim). Created once per file; an
    existing group of that name (perhaps edited by the user) is reused as is.
    """
    ng = bpy.data.node_groups.get(ORIENTED_GROUP)
    if ng is not None and ng.bl_idname == "ShaderNodeTree":
        return ng
    ng = bpy.data.node_groups.new(ORIENTED_GROUP, "ShaderNodeTree")
    iface = ng.interface
    s = iface.new_socket("Alpha", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 0.3, 0.0, 1.0
    s = iface.new_socket("Edge Alpha", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 1.0, 0.0, 1.0
    s = iface.new_socket("Blend", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 0.35, 0.0, 1.0
    iface.new_socket("Alpha", in_out="OUTPUT", socket_type="NodeSocketFloat")
    nodes, links = ng.nodes, ng.links
    gin = nodes.new("NodeGroupInput")
    gin.location = (-500, 0)
    gout = nodes.new("NodeGroupOutput")
    gout.location = (300, 0)
    lw = nodes.new("ShaderNodeLayerWeight")
    lw.location = (-250, -150)
    links.new(gin.outputs["Blend"], lw.inputs["Blend"])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "FLOAT"
    mix.clamp_factor = True
    mix.location = (50, 0)
    links.new(lw.outputs["Facing"], mix.inputs["Factor"])
    links.new(gin.outputs["Alpha"], mix.inputs["A"])
    links.new(gin.outputs["Edge Alpha"], mix.inputs["B"])
    links.new(mix.outputs["Result"], gout.inputs["Alpha"])
    return ng


# ---------------------------------------------------------------------------------------------
# camera framing (examples, "Frame scan" button in background mode)
# ---------------------------------------------------------------------------------------------
def bounds(objects: Iterable[bpy.types.Object]) -> Optional[np.ndarray]:
    """World-space bounding box (2, 3) mm of the objects' vertices, or None when empty."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for o in objects:
        if o.type != "MESH" or not len(o.data.vertices):
            continue
        m = np.array(o.matrix_world)
        corners = np.array([m @ np.r_[c[:], 1.0] for c in o.bound_box])[:, :3]
        lo, hi = np.minimum(lo, corners.min(0)), np.maximum(hi, corners.max(0))
    return None if not np.all(np.isfinite(lo)) else np.stack([lo, hi])


def frame_camera(scene: bpy.types.Scene, objects, space: str = "RAS", view: str = "ANTERIOR",
                 elevation: float = 0.0, azimuth: float = 0.0, lens: float = 50.0,
                 margin: float = 1.05) -> bpy.types.Object:
    """Point the scene camera (made if missing) at the objects from the patient's front or back.

    ``view`` "ANTERIOR" puts the camera in front of the patient (+y in RAS, −y in LPS),
    "POSTERIOR" behind; ``elevation`` (degrees) raises it toward the head, ``azimuth`` turns it
    around the patient's long (z) axis. The distance is the smallest at which all eight corners of
    the bounding box fit in the frame (times ``margin``).
    """
    box = bounds(objects)
    if box is None:
        raise ValueError("nothing to frame")
    centre = box.mean(0)
    front = 1.0 if space == "RAS" else -1.0
    if view == "POSTERIOR":
        front = -front
    el, az = np.radians(elevation), np.radians(azimuth)
    # unit vector from the centre toward the camera
    to_cam = np.array([np.sin(az) * np.cos(el), front * np.cos(az) * np.cos(el), np.sin(el)])
    forward = -to_cam / np.linalg.norm(to_cam)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    cam = scene.camera
    if cam is None:
        cam = bpy.data.objects.new("Anatomesh Camera", bpy.data.cameras.new("Anatomesh Camera"))
        scene.collection.objects.link(cam)
        scene.camera = cam
    cam.data.lens = lens
    cam.data.sensor_fit = "AUTO"
    aspect = (scene.render.resolution_x * scene.render.pixel_aspect_x) / max(
        1.0, scene.render.resolution_y * scene.render.pixel_aspect_y)
    tan_big = 0.5 * cam.data.sensor_width / lens
    tan_w, tan_h = (tan_big, tan_big / aspect) if aspect >= 1 else (tan_big * aspect, tan_big)
    corners = np.array([[x, y, z] for x in box[:, 0] for y in box[:, 1] for z in box[:, 2]]) - centre
    cx, cy, cz = corners @ right, corners @ up, corners @ forward
    dist = float(max(np.max(np.abs(cx) * margin / tan_w - cz), np.max(np.abs(cy) * margin / tan_h - cz)))
    location = centre - forward * dist
    cam.location = tuple(location)
    from mathutils import Vector

    cam.rotation_euler = Vector(tuple(forward)).to_track_quat("-Z", "Y").to_euler()
    size = float(np.linalg.norm(box[1] - box[0]))
    cam.data.clip_start = max(0.1, (dist - size) * 0.5)
    cam.data.clip_end = dist + 2.0 * size
    return cam
