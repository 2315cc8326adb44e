"""Settings as Blender properties.

* ``Scene.anatomesh`` (:class:`ANATOMESH_PG_settings`): what to read and extract next — the input,
  the label list (name, colour, include) or the isovalue list, the smoothing defaults and the
  export settings. These are the fields of core's ``Recipe``; the operators copy them over.
* ``Collection.anatomesh`` (:class:`ANATOMESH_PG_scan`): one per extracted scan — its live
  smoothing (changing a value re-smooths that scan's objects from their unsmoothed copy) and its
  look (opacity, oriented transparency, EEVEE blend method).
"""

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, PointerProperty, StringProperty)
from bpy.types import PropertyGroup

SPACE_ITEMS = (
    ("RAS", "RAS", "x toward the patient's right, y anterior, z superior (NIfTI, most Blender scenes)"),
    ("LPS", "LPS", "x toward the patient's left, y posterior, z superior (DICOM, ITK, 3D Slicer files); "
                   "Blender's Front view then looks at the patient's face"),
)

#: smoothing methods offered in the UI; the identifiers are core's method names in upper case
SMOOTH_ITEMS = (
    ("NONE", "None", "No smoothing: the surfaces as extracted"),
    ("TAUBIN", "Taubin", "Taubin λ|μ low-pass filter: removes the voxel staircase and barely shrinks "
                         "(Taubin 1995); the organ default"),
    ("LAPLACIAN", "Laplacian", "Laplacian (umbrella) smoothing: strongest, but shrinks thin parts"),
    ("HC", "HC Laplacian", "Laplacian with the HC correction against shrinkage (Vollmer et al. 1999)"),
    ("MEAN_CURVATURE", "Mean curvature flow", "Cotangent weights (Desbrun et al. 1999): moves "
                                             "along the normal only, keeps the triangles' layout"),
)

RENDER_METHOD_ITEMS = (
    ("DITHERED", "Dithered", "Depth-correct transparency for surfaces nested inside each other "
                             "(EEVEE deferred; needs a few samples to look smooth)"),
    ("BLENDED", "Blended", "Smooth blending sorted per object: best for one transparent shell "
                           "around opaque organs"),
)

EXPORT_FORMAT_ITEMS = (
    ("STL", "STL (binary)", "One binary STL per object, in mm, SPACE= in the header"),
    ("PLY", "PLY", "One binary PLY per object, in mm"),
    ("OBJ", "OBJ", "One OBJ per object, in mm"),
    ("3MF", "3MF (print)", "One .3mf with every object as a part, colours, unit millimetre"),
    ("GLB", "glTF binary (.glb)", "One .glb with all objects and colours (glTF is in metres)"),
    ("GLTF", "glTF (.gltf)", "One .gltf + .bin with all objects (glTF is in metres)"),
)

EXPORT_SELECTION_ITEMS = (
    ("SELECTED", "Selected", "The selected surface objects"),
    ("COLLECTION", "Scan", "All surfaces of the active scan collection"),
)


def _live_update(self, context):
    from . import live

    live.on_scan_settings_changed(self, context)


def _look_update(self, context):
    from . import live

    live.on_look_changed(self, context)


class ANATOMESH_PG_label(PropertyGroup):
    """One row of the label list (``name`` is the label's name)."""

    value: IntProperty(name="Value", description="Label value in the map")
    color: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, min=0.0, max=1.0,
                               default=(0.8, 0.8, 0.8))
    include: BoolProperty(name="Include", default=True, description="Extract this label")
    voxels: IntProperty(name="Voxels", description="Voxels with this value")
    volume_mm3: FloatProperty(name="Volume", unit="VOLUME", description="Voxel volume in mm³")


class ANATOMESH_PG_level(PropertyGroup):
    """One isovalue for a scalar scan (``name`` says what it shows)."""

    value: FloatProperty(name="Isovalue", description="Isovalue in the scan's units (HU for CT)")
    color: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, min=0.0, max=1.0,
                               default=(0.9, 0.85, 0.75))
    include: BoolProperty(name="Include", default=True)


class ANATOMESH_PG_settings(PropertyGroup):
    """Scene settings: the next import / extraction / export."""

    filepath: StringProperty(name="Scan", subtype="FILE_PATH",
                             description="NIfTI, NRRD file or DICOM folder (or one file in it)")
    series: StringProperty(name="Series", description="DICOM SeriesInstanceUID or 1-based number "
                                                      "when the folder holds several")
    label_table: StringProperty(name="Label table", subtype="FILE_PATH",
                                description="Label names/colours (TotalSegmentator JSON, Slicer "
                                            "colour table, ITK-SNAP); a sidecar is found automatically")
    space: EnumProperty(name="Space", items=SPACE_ITEMS, default="RAS",
                        description="Patient coordinate system of the vertex coordinates")
    kind: EnumProperty(name="Kind", items=(("NONE", "Nothing loaded", ""), ("LABELS", "Label map", ""),
                                           ("LEVELS", "Scalar scan", "")), default="NONE")
    modality: StringProperty(name="Modality")
    info: StringProperty(name="Info", description="Shape, spacing and orientation of the loaded scan")
    labels: CollectionProperty(type=ANATOMESH_PG_label)
    label_index: IntProperty(default=0)
    levels: CollectionProperty(type=ANATOMESH_PG_level)
    level_index: IntProperty(default=0)

    smooth_method: EnumProperty(name="Method", items=SMOOTH_ITEMS, default="TAUBIN")
    smooth_iterations: IntProperty(name="Iterations", default=0, min=0, soft_max=100, max=1000)
    smooth_strength: FloatProperty(name="Strength", default=0.5, min=0.0, max=1.0)
    smooth_max_deviation: FloatProperty(name="Max deviation", default=0.0, min=0.0, soft_max=5.0,
                                        unit="LENGTH", description="Cap on how far smoothing moves "
                                        "a vertex, mm (0: no cap)")
    keep_in_cell: BoolProperty(name="Stay in voxel", default=True,
                               description="Keep every vertex inside its voxel cell (Gibson 1998): "
                                           "smooth, yet never farther than half a voxel per axis")
    render_method: EnumProperty(name="Transparency", items=RENDER_METHOD_ITEMS, default="DITHERED")

    export_dir: StringProperty(name="Folder", subtype="DIR_PATH", default="//anatomesh_export/")
    export_format: EnumProperty(name="Format", items=EXPORT_FORMAT_ITEMS, default="STL")
    export_selection: EnumProperty(name="What", items=EXPORT_SELECTION_ITEMS, default="COLLECTION")
    last_collection: StringProperty(name="Last scan", description="Collection made by the last extraction")


class ANATOMESH_PG_scan(PropertyGroup):
    """Per-scan settings on its collection: live smoothing and look."""

    is_scan: BoolProperty(default=False)
    source: StringProperty(name="Source", subtype="FILE_PATH")
    space: StringProperty(name="Space", default="RAS")
    smooth_method: EnumProperty(name="Method", items=SMOOTH_ITEMS, default="TAUBIN", update=_live_update)
    smooth_iterations: IntProperty(name="Iterations", default=0, min=0, soft_max=100, max=1000,
                                   update=_live_update,
                                   description="Smoothing passes (0: as extracted); changes apply live")
    smooth_strength: FloatProperty(name="Strength", default=0.5, min=0.0, max=1.0, update=_live_update,
                                   description="Step size of each pass (λ)")
    smooth_max_deviation: FloatProperty(name="Max deviation", default=0.0, min=0.0, soft_max=5.0,
                                        unit="LENGTH", update=_live_update,
                                        description="No vertex moves farther than this from its "
                                                    "extracted position, mm (0: no cap)")
    keep_in_cell: BoolProperty(name="Stay in voxel", default=True, update=_live_update,
                               description="Keep every vertex inside its voxel cell (Gibson 1998): "
                                           "smooth, yet never farther than half a voxel per axis")
    live: BoolProperty(name="Live", default=True,
                       description="Re-smooth while the values change (turn off for huge scans)")
    alpha: FloatProperty(name="Opacity", default=1.0, min=0.0, max=1.0, subtype="FACTOR",
                         update=_look_update, description="Opacity of all surfaces of this scan")
    oriented: BoolProperty(name="Oriented transparency", default=False, update=_look_update,
                           description="More opaque toward silhouettes (Stalling et al. 1999)")
    render_method: EnumProperty(name="Transparency", items=RENDER_METHOD_ITEMS, default="DITHERED",
                                update=_look_update)


CLASSES = (ANATOMESH_PG_label, ANATOMESH_PG_level, ANATOMESH_PG_settings, ANATOMESH_PG_scan)


def register_properties() -> None:
    bpy.types.Scene.anatomesh = PointerProperty(type=ANATOMESH_PG_settings)
    bpy.types.Collection.anatomesh = PointerProperty(type=ANATOMESH_PG_scan)


def unregister_properties() -> None:
    for owner in (bpy.types.Scene, bpy.types.Collection):
        if hasattr(owner, "anatomesh"):
            del owner.anatomesh
