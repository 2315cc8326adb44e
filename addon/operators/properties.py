"""Blender properties the operators and the panels' property groups share: the choices (enum
items) and the smoothing settings, described by the recipe's own settings definitions
(:func:`anatomesh.app.flow.recipe.setting_help`)."""
from bpy.props import EnumProperty, FloatProperty, IntProperty

from ...app.flow.recipe import setting_help

SPACE_ITEMS = (
    ("RAS", "RAS", "x toward the patient's right, y anterior, z superior (NIfTI, most Blender scenes)"),
    ("LPS", "LPS", "x toward the patient's left, y posterior, z superior (DICOM, ITK, 3D Slicer files); "
                   "Blender's Front view then looks at the patient's face"),
)

#: smoothing presets and filters: the recipe's ``[smoothing] method`` (and ``--smooth``) in upper
#: case, so the same choice gives the same surfaces in every door
SMOOTH_ITEMS = (
    ("ORGAN", "Organ (default)", "Taubin λ|μ, every vertex kept in its voxel cell (Gibson 1998), "
                                 "volumes restored, no folds, nothing crossing: the command line's default"),
    ("LIGHT", "Light", "As Organ, fewer iterations: removes the staircase's shading only"),
    ("STRONG", "Strong", "As Organ, more iterations: flat or large structures, thick slices"),
    ("TAUBIN", "Taubin (unbounded)", "Classic Taubin without the voxel-cell bound (Taubin 1995)"),
    ("LAPLACIAN", "Laplacian", "Laplacian (umbrella) smoothing, in the voxel cell: shrinks thin parts"),
    ("HC", "HC Laplacian", "Laplacian with the HC correction against shrinkage (Vollmer et al. 1999)"),
    ("MEAN_CURVATURE", "Mean curvature flow", "Cotangent weights (Desbrun et al. 1999): moves along "
                                             "the normal only"),
    ("NORMAL_MEAN", "Normal filter (mean)", "Mean filtering of face normals (Yagou et al. 2002)"),
    ("NORMAL_MEDIAN", "Normal filter (median)", "Median filtering of face normals: keeps edges"),
    ("NONE", "As extracted", "No smoothing: the surfaces as extracted (voxel faces, exact volumes)"),
)
STAIRCASE_ITEMS = (("AUTO", "Auto", "Extra slice-axis passes when slices are >= 1.5x the in-plane spacing"),
                   ("ON", "On", "Extra slice-axis passes"), ("OFF", "Off", "No slice-axis passes"))


def smoothing_properties(update=None) -> dict:
    """The smoothing settings (the recipe's ``[smoothing]`` section) as Blender properties, for the
    scene's defaults and each scan collection (``update``: re-smooth live)."""
    kw = {"update": update} if update is not None else {}
    return dict(
        smooth_method=EnumProperty(name="Method", items=SMOOTH_ITEMS, default="ORGAN", **kw),
        smooth_iterations=IntProperty(name="Iterations", default=0, min=0, soft_max=100, max=1000,
                                      description=setting_help("iterations", "0: the method's own"), **kw),
        smooth_strength=FloatProperty(name="Strength λ", default=0.0, min=0.0, max=1.0,
                                      description=setting_help("lam", "0: the method's own"), **kw),
        smooth_mu=FloatProperty(name="Taubin μ", default=0.0, min=-1.0, max=0.0,
                                description=setting_help("mu", "0: the method's own"), **kw),
        smooth_max_deviation=FloatProperty(name="Max deviation", default=0.0, min=0.0, soft_max=5.0,
                                           unit="LENGTH", description=setting_help("max_deviation", "0: no cap"),
                                           **kw),
        smooth_damping=FloatProperty(name="Damping distance", default=0.0, min=0.0, soft_max=10.0,
                                     unit="LENGTH", description=setting_help("damping_distance", "0: off"), **kw),
        smooth_staircase=EnumProperty(name="Staircase", items=STAIRCASE_ITEMS, default="AUTO",
                                      description=setting_help("staircase"), **kw))

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


TARGET_ITEMS = (
    ("RATIO", "Ratio", "Keep this fraction of the faces"),
    ("FACES", "Face count", "Keep about this many faces, all surfaces of the scan together"),
    ("ERROR", "Max error", "Remove as many faces as possible while no point moves farther than "
                           "this from the surface, mm (measured: symmetric Hausdorff distance)"),
)
