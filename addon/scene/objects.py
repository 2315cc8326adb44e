"""Surfaces into the Blender scene: units, one collection per scan, objects, materials.

* Units: metric, millimetres, unit scale 0.001 — one Blender unit is one millimetre and the
  viewport, the N panel and the 3D-Print Toolbox show real sizes.
* A scan becomes a collection named after the file (a second import of the same scan becomes
  ``name.001``; nothing the user already has is renamed, replaced or deleted).
* Each label or isosurface is one object named after it, carrying custom properties that say
  where it came from (:data:`OBJECT_PROPS`).
* Each object gets its own material: the node group of its tissue class (:mod:`.materials`: one
  shared group per class, ``anatomesh_tissue``) with the label's colour; opacity is read from
  the object's ``anatomesh_alpha`` property by an Attribute node, so it can be changed per object,
  keyed or driven without touching the material. An optional view-dependent ("oriented")
  transparency makes surfaces more opaque toward their silhouettes, so nested organs stay readable
  (transparency modulated by orientation, Stalling et al. 1999 (Zuse Institute Berlin); a
  variation of Kay & Greenberg 1979, "Transparency for computer synthesized images"): the Layer Weight node's *Facing* output (0 facing the viewer, 1 at grazing
  angles) mixes from the object's opacity up to the edge opacity.
* Faces where the scan's field of view cut the structure get a second, cut-surface material
  (:func:`mark_cut_faces`).
"""
from __future__ import annotations

from typing import Dict, Iterable, Optional, Sequence

import bpy
import numpy as np

from ...core.model.labels import srgb_to_linear
from . import bridge, materials
from .materials import ORIENTED_GROUP, oriented_alpha_group  # noqa: F401 (the add-on's names)

#: custom properties set on every surface object
OBJECT_PROPS = (
    "anatomesh_value",      # label value or isovalue
    "anatomesh_name",       # label name / level name
    "anatomesh_source",     # path of the scan
    "anatomesh_series_uid",  # DICOM SeriesInstanceUID ("" otherwise)
    "anatomesh_space",      # "RAS" or "LPS": the space of the vertex coordinates
    "anatomesh_affine",     # voxel index → mm, 16 floats row by row
    "anatomesh_shape",      # the scan's size in voxels (i, j, k): its field of view, for cut faces
    "anatomesh_units",      # "mm"
    "anatomesh_alpha",      # opacity 0..1 read by the material
    "anatomesh_oriented",   # 0/1: view-dependent transparency on
    "anatomesh_tissue",     # tissue class (materials.TISSUE_PRESETS): its node group draws it
)

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
                rest: Optional[np.ndarray] = None, tissue: str = "other") -> bpy.types.Object:
    """Create one surface object in ``collection``.

    ``vertices`` (N, 3) mm, ``faces`` (M, 3); ``props`` are written as custom properties (see
    :data:`OBJECT_PROPS`); the unsmoothed positions (``rest``, default ``vertices``: for a shell,
    its set's positions, before its pinch points are moved apart) are kept as the
    ``anatomesh_rest`` attribute and, when given, each vertex's index in the shared surface set
    as ``anatomesh_vid``.
    ``vertex_colors`` (N, 3|4) sRGB, optional: the colour attribute :data:`COLOR_ATTRIBUTE`
    (active, shown when the viewport colours by attribute). ``tissue``: the material's tissue
    class (:data:`materials.TISSUE_PRESETS`).
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
    for key, default in (("anatomesh_alpha", 1.0), ("anatomesh_oriented", 0.0),
                         (materials.TISSUE_PROPERTY, tissue)):
        if key not in obj:
            obj[key] = default
    _property_ui(obj)
    obj.color = linear_rgba(color)  # the Solid viewport's "Object" colour
    me.materials.append(surface_material(name, color, render_method, obj[materials.TISSUE_PROPERTY]))
    viewport_alpha(obj)
    collection.objects.link(obj)
    return obj


def viewport_alpha(obj: bpy.types.Object) -> None:
    """The Solid view's colours (object and materials) take the object's opacity
    (``anatomesh_alpha``), so see-through structures are see-through there too."""
    alpha = float(obj.get("anatomesh_alpha", 1.0))
    obj.color[3] = alpha
    for mat in getattr(obj.data, "materials", []):
        if mat is not None:
            mat.diffuse_color[3] = alpha


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
        viewport_alpha(o)
        o.update_tag()
        if o.data is not None:
            o.data.update_tag()


def set_render_method(objects: Iterable[bpy.types.Object], method: str) -> None:
    """EEVEE transparency: "DITHERED" (depth-correct, nested surfaces) or "BLENDED" (sorted per object)."""
    for o in objects:
        for mat in getattr(o.data, "materials", []):
            if mat is not None:
                materials.render_settings(mat, method)


# ---------------------------------------------------------------------------------------------
# materials
# ---------------------------------------------------------------------------------------------
def linear_rgba(color: Sequence[float]) -> tuple:
    """A label colour (sRGB-encoded 0..1, as label tables and ``Mesh.color`` give it) as the
    linear RGBA Blender's colour properties and shader sockets hold (the glTF/3MF writers convert
    the same way, so every output shows the same colour)."""
    return (*[float(c) for c in srgb_to_linear(np.asarray(color[:3], float))], 1.0)


def surface_material(name: str, color: Sequence[float], render_method: str = "DITHERED",
                     tissue: str = "other") -> bpy.types.Material:
    """A new material: the node group of tissue class ``tissue`` (:mod:`.materials`) with base
    colour ``color`` (sRGB), opacity from the object.

    Alpha = mix(object ``anatomesh_alpha``, oriented alpha, object ``anatomesh_oriented``).
    """
    return materials.organ_material(name, linear_rgba(color), tissue, render_method)


def mark_cut_faces(obj: bpy.types.Object, cut: Optional[np.ndarray] = None) -> int:
    """Give the structure's cut faces its cut-surface material (:func:`materials.cut_material` in
    the colour of its first material, a slot added when needed; the other faces slot 0).

    ``cut`` (M,) bool per face; default: the faces on its scan's field-of-view boundary
    (:func:`~anatomesh.core.geometry.cut_faces.cut_faces` from the object's ``anatomesh_affine``
    and ``anatomesh_shape``), so it can be called again after the faces changed (decimation, the
    print tools). Returns how many faces are marked.
    """
    me = obj.data
    if cut is None:
        cut = _faces_on_scan_boundary(obj)
    cut = np.asarray(cut, bool)
    if len(cut) != len(me.polygons) or not len(me.materials) or me.materials[0] is None:
        return 0
    slot = next((i for i, m in enumerate(me.materials) if m is not None and m.node_tree is not None
                 and materials.CUT_NODE in m.node_tree.nodes), None)
    if slot is None and cut.any():
        first = me.materials[0]
        affine, shape = obj.get("anatomesh_affine"), obj.get("anatomesh_shape")
        spacing = materials.HATCH_MM if affine is None or shape is None else \
            materials.hatch_spacing(np.reshape(list(affine), (4, 4)), list(shape))
        me.materials.append(materials.cut_material(f"{obj.name} cut", materials.base_color(first),
                                                   getattr(first, "surface_render_method", "DITHERED"),
                                                   spacing))
        slot = len(me.materials) - 1
    if slot is not None:
        me.polygons.foreach_set("material_index", np.where(cut, slot, 0).astype(np.int32))
        me.update()
        viewport_alpha(obj)
    return int(cut.sum())


def _faces_on_scan_boundary(obj: bpy.types.Object) -> np.ndarray:
    """(M,) bool: the object's faces on its scan's field-of-view boundary (none without the
    scan's affine and shape)."""
    from ...core.geometry.cut_faces import cut_faces

    affine, shape = obj.get("anatomesh_affine"), obj.get("anatomesh_shape")
    vertices, faces = bridge.arrays(obj.data)
    if affine is None or shape is None or len(faces) != len(obj.data.polygons):
        return np.zeros(len(obj.data.polygons), bool)
    return cut_faces(vertices, faces, np.reshape(list(affine), (4, 4)), tuple(int(n) for n in shape))


# ---------------------------------------------------------------------------------------------
# bounds (framing the viewports; the camera views are in camera.py)
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
