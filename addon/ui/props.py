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

from ...app.flow.recipe import Recipe, setting_help
from ..scene import objects as scene
from ..operators.common import active_scan
from ..operators.recipe import NOT_IN_BLENDER, PANEL_FIELDS
from ..operators.setting_props import settings_group
from ..operators.properties import (EXPORT_FORMAT_ITEMS, EXPORT_SELECTION_ITEMS, RENDER_METHOD_ITEMS,
                                     SPACE_ITEMS, TARGET_ITEMS, smoothing_properties)
from ..operators.decimate import PREVIEW_MODIFIER, set_preview, uniform_ratios

def _live_update(self, context):
    from ..operators import smooth as live

    live.on_scan_settings_changed(self, context)


def _look_update(self, context):
    from ..operators import smooth as live

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
                             description="NIfTI, NRRD file, DICOM folder (or one file in it: image, SEG, "
                                         "RTSTRUCT) or a folder of binary masks")
    series: StringProperty(name="Series", description="DICOM SeriesInstanceUID or 1-based number "
                                                      "when the folder holds several")
    label_table: StringProperty(name="Label table", subtype="FILE_PATH",
                                description="Label names/colours (TotalSegmentator JSON, Slicer "
                                            "colour table, ITK-SNAP); a sidecar is found automatically")
    space: EnumProperty(name="Space", items=SPACE_ITEMS, default="RAS",
                        description="Patient coordinate system of the vertex coordinates")
    # segmentations: mask folders, DICOM SEG, RTSTRUCT
    grid: StringProperty(name="Grid", description="Mask folders: the grid to mesh on (a mask name or "
                                                  "'image'; empty: the finest). DICOM SEG/RTSTRUCT: "
                                                  "'image' or 'native'")
    kind: EnumProperty(name="Kind", items=(("NONE", "Nothing loaded", ""), ("LABELS", "Label map", ""),
                                           ("LEVELS", "Scalar scan", "")), default="NONE")
    modality: StringProperty(name="Modality")
    info: StringProperty(name="Info", description="Shape, spacing and orientation of the loaded scan")
    labels: CollectionProperty(type=ANATOMESH_PG_label)
    label_index: IntProperty(default=0)
    levels: CollectionProperty(type=ANATOMESH_PG_level)
    level_index: IntProperty(default=0)

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
    live: BoolProperty(name="Live", default=True,
                       description="Re-smooth while the values change (turn off for huge scans)")
    alpha: FloatProperty(name="Opacity", default=1.0, min=0.0, max=1.0, subtype="FACTOR",
                         update=_look_update, description="Opacity of all surfaces of this scan")
    oriented: BoolProperty(name="Oriented transparency", default=False, update=_look_update,
                           description="More opaque toward silhouettes (Stalling et al. 1999)")
    render_method: EnumProperty(name="Transparency", items=RENDER_METHOD_ITEMS, default="DITHERED",
                                update=_look_update)


# the smoothing settings: the scene's defaults for the next extraction, and each scan's own (live)
ANATOMESH_PG_settings.__annotations__.update(smoothing_properties())
ANATOMESH_PG_scan.__annotations__.update(smoothing_properties(_live_update))


def _preview_update(self, context):
    """A target value changed: refresh a preview that is on (ratio and face count only; a max
    error needs a core run: press Preview again)."""
    if self.target == "ERROR":
        return
    coll = active_scan(context)
    if coll is None:
        return
    objs = [o for o in scene.surface_objects(coll) if PREVIEW_MODIFIER in o.modifiers]
    if objs:
        try:
            set_preview(objs, uniform_ratios(objs, self.target, self.ratio, self.faces))
        except Exception as exc:  # an update callback must never raise into the UI
            print(f"Anatomesh: decimate preview failed: {exc}")


class ANATOMESH_PG_decimate(PropertyGroup):
    """Decimation settings of the scene (``Scene.anatomesh_decimate``)."""

    target: EnumProperty(name="Target", items=TARGET_ITEMS, default="RATIO", update=_preview_update)
    ratio: FloatProperty(name="Ratio", default=0.1, min=0.001, max=1.0, subtype="FACTOR",
                         update=_preview_update, description=setting_help("decimate"))
    faces: IntProperty(name="Faces", default=50000, min=4, update=_preview_update,
                       description=setting_help("target_faces"))
    max_error: FloatProperty(name="Max error", default=1.0, min=0.0, soft_max=5.0, unit="LENGTH",
                             description=setting_help("max_error"))


def _profile_changed(self, context):
    from ...core.printing.profiles import PROFILES

    prof = PROFILES[self.profile.lower()]
    self.min_wall, self.min_gap = prof["min_wall"], prof["min_gap"]


class ANATOMESH_PG_print_problem(PropertyGroup):
    part: StringProperty(name="Part", description="Object the problem is on")
    other: StringProperty(name="Other Part", description="The other object of a gap or crossing")
    kind: StringProperty(name="Problem")
    value: FloatProperty(name="Value", description="Thinnest wall, gap (mm) or count")
    unit: StringProperty(name="Unit", default="mm")
    location: FloatVectorProperty(name="Location", size=3, subtype="XYZ", unit="LENGTH")


class ANATOMESH_PG_print(PropertyGroup):
    profile: EnumProperty(name="Printer", items=[
        ("FDM", "FDM (0.4 mm nozzle)", "Filament printer: min wall 0.8 mm, min gap 0.5 mm"),
        ("RESIN", "Resin", "Resin printer: min wall 0.4 mm, min gap 0.2 mm"),
    ], default="FDM", update=_profile_changed)
    min_wall: FloatProperty(name="Min Wall", default=0.8, min=0.01, soft_max=5.0, unit="LENGTH",
                            description=setting_help("min_wall"))
    min_gap: FloatProperty(name="Min Gap", default=0.5, min=0.0, soft_max=5.0, unit="LENGTH",
                           description=setting_help("min_gap"))
    selected_only: BoolProperty(name="Selected Only", default=False,
                                description="Check the selected objects instead of all Anatomesh objects")
    problems: CollectionProperty(type=ANATOMESH_PG_print_problem)
    problem_index: IntProperty(name="Problem", default=0)
    checked: BoolProperty(default=False)
    passed: BoolProperty(default=False)
    summary: StringProperty(name="Summary")


#: property groups, in registration order (a group before the groups that point to it)
CLASSES = (ANATOMESH_PG_label, ANATOMESH_PG_level, ANATOMESH_PG_settings, ANATOMESH_PG_scan,
           ANATOMESH_PG_decimate, ANATOMESH_PG_print_problem, ANATOMESH_PG_print)
#: where the settings live: (owner type, attribute, property group)
_POINTERS = (("Scene", "anatomesh", ANATOMESH_PG_settings), ("Collection", "anatomesh", ANATOMESH_PG_scan),
             ("Scene", "anatomesh_decimate", ANATOMESH_PG_decimate), ("Scene", "anatomesh_print", ANATOMESH_PG_print))


def register_properties() -> None:
    for owner, attr, group in _POINTERS:
        setattr(getattr(bpy.types, owner), attr, PointerProperty(type=group))


def unregister_properties() -> None:
    for owner, attr, _ in _POINTERS:
        if hasattr(getattr(bpy.types, owner), attr):
            delattr(getattr(bpy.types, owner), attr)


# ---------------------------------------------------------------------------------------------
# preprocessing before and around extraction: Scene.anatomesh_preprocess
# ---------------------------------------------------------------------------------------------
def _live_level_update(self, context):
    from ..operators import isovalue as live_iso

    live_iso.on_level_changed(self, context)


class ANATOMESH_PG_preprocess(PropertyGroup):
    """The Preprocess panel: the recipe's ``[preprocess]`` settings and the live isovalue."""

    resample: FloatProperty(name="Resample", default=0.0, min=0.0, soft_max=5.0, unit="LENGTH",
                            description="Scalar scans: new isotropic voxel size, mm (0: keep)")
    resample_method: EnumProperty(name="Method", default="LINEAR", items=(
        ("LINEAR", "Linear", "Trilinear interpolation"),
        ("CUBIC", "Cubic B-spline", "Cubic B-spline interpolation (smoothest surfaces)"),
        ("LANCZOS", "Lanczos", "Lanczos-3 windowed sinc (sharp, low-passes when downsampling)")))
    roi: StringProperty(name="ROI", description="Box x0,y0,z0,x1,y1,z1 in mm (the scene's space) to "
                                                "cut the scan to; empty: the whole scan")
    smooth_volume: EnumProperty(name="Smooth volume", default="NONE", items=(
        ("NONE", "None", "No volume smoothing"),
        ("GAUSSIAN", "Gaussian", "Gaussian, sigma in mm"),
        ("MEDIAN", "Median", "Median over a box, width in mm"),
        ("DIFFUSION", "Diffusion", "Edge-preserving anisotropic diffusion (Perona-Malik), iterations")))
    smooth_value: FloatProperty(name="Amount", default=1.0, min=0.0, soft_max=30.0,
                                description="Gaussian sigma (mm), median width (mm) or diffusion iterations")
    interpolate: BoolProperty(name="Interpolate slices", default=False,
                              description="Label maps: shape-based interpolation to isotropic voxels")
    fuzzy_boundary: BoolProperty(name="Fuzzy boundary", default=False,
                                 description="Label maps: smooth each label at the voxel level "
                                             "(stays within one voxel)")
    fill_cavities: BoolProperty(name="Fill cavities", default=False,
                                description="Label maps: fill background pockets enclosed by a label")
    close_handles: FloatProperty(name="Close handles", default=0.0, min=0.0, soft_max=20.0, unit="LENGTH",
                                 description="Label maps: plug tunnels up to this size, mm (0: off)")
    fuzzy: BoolProperty(name="Fuzzy isosurface", default=False,
                        description="Scalar scans: nested shells over an interval, the middle one opaque")
    fuzzy_low: FloatProperty(name="From", default=200.0)
    fuzzy_high: FloatProperty(name="To", default=400.0)
    fuzzy_count: IntProperty(name="Shells", default=5, min=2, max=32)
    precise: BoolProperty(name="Precise", default=False,
                          description="Scalar scans: refine triangles onto the trilinear interpolant")
    difference_colors: BoolProperty(name="Difference colours", default=False,
                                    description="Colour the surfaces by their distance to the "
                                                "surfaces without preprocessing")
    live_level: FloatProperty(name="Live isovalue", default=300.0, update=_live_level_update,
                              description="Drag: the live isosurface is re-extracted and redrawn")
    live_object: StringProperty(name="Live object")


CLASSES = CLASSES + (ANATOMESH_PG_preprocess,)
_POINTERS = _POINTERS + (("Scene", "anatomesh_preprocess", ANATOMESH_PG_preprocess),)


# ---------------------------------------------------------------------------------------------
# cut to fit: Scene.anatomesh_fit (the Print panel's Cut to Fit settings)
# ---------------------------------------------------------------------------------------------
class ANATOMESH_PG_fit(PropertyGroup):
    """The printer's build volume and whether pins go across the cuts."""
    size: FloatVectorProperty(name="Build Volume", size=3, default=(180.0, 180.0, 180.0), min=1.0,
                              soft_max=1000.0, unit="LENGTH", description="The printer's build volume X, Y, Z (mm)")
    connectors: BoolProperty(name="Pins Across Cuts", default=False,
                             description="Pins on one piece and pockets in the other across each cut")


CLASSES = CLASSES + (ANATOMESH_PG_fit,)
_POINTERS = _POINTERS + (("Scene", "anatomesh_fit", ANATOMESH_PG_fit),)


# ---------------------------------------------------------------------------------------------
# print tools / edit-mode tools: Scene.anatomesh_print_tools
# ---------------------------------------------------------------------------------------------
from ..operators.edit_tools import PROBLEM_ITEMS  # noqa: E402


class ANATOMESH_PG_print_tools(PropertyGroup):
    """The Print panel's tools and the Edit Mode tools' values."""

    clearance: FloatProperty(name="Clearance", default=0.2, min=0.001, soft_max=2.0, unit="LENGTH",
                             description=setting_help("clearance"))
    hollow_wall: FloatProperty(name="Wall", default=2.0, min=0.1, soft_max=10.0, unit="LENGTH",
                               description=setting_help("hollow"))
    drain_holes: IntProperty(name="Drain Holes", default=2, min=0, max=16,
                             description=setting_help("drain_holes"))
    drain_diameter: FloatProperty(name="Drain Diameter", default=0.0, min=0.0, soft_max=10.0, unit="LENGTH",
                                  description=setting_help("drain_diameter", "0: the printer profile's"))
    problem: EnumProperty(name="Problem", default="NON_MANIFOLD", items=PROBLEM_ITEMS)
    hole_edges: IntProperty(name="Max Edges", default=30, min=3, soft_max=500,
                            description="Fill Holes: largest hole, in edges around it")
    tiny_volume: FloatProperty(name="Min Volume", default=1.0, min=0.0, soft_max=1000.0,
                               description="Remove Tiny Shells: loose parts enclosing less, mm³")
    relax_deviation: FloatProperty(name="Max Deviation", default=0.5, min=0.0, soft_max=5.0, unit="LENGTH",
                                   description="Relax: no vertex moves farther than this, mm")
    relax_iterations: IntProperty(name="Iterations", default=10, min=1, soft_max=100)


CLASSES = CLASSES + (ANATOMESH_PG_print_tools,)
_POINTERS = _POINTERS + (("Scene", "anatomesh_print_tools", ANATOMESH_PG_print_tools),)


# ---------------------------------------------------------------------------------------------
# every other recipe setting, made from its definition: Scene.anatomesh_recipe (the Settings panel)
# ---------------------------------------------------------------------------------------------
ANATOMESH_PG_recipe = settings_group(Recipe, PANEL_FIELDS + NOT_IN_BLENDER)
CLASSES = CLASSES + (ANATOMESH_PG_recipe,)
_POINTERS = _POINTERS + (("Scene", "anatomesh_recipe", ANATOMESH_PG_recipe),)
