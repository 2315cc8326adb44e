"""The recipe: every setting of a run, one dataclass that CLI flags, TOML files, the Blender panels
and batch runs all fill, checked in one place (:func:`check_recipe`).

In a TOML file the settings are grouped by step::

    [input]
    path = "example_seg.nii.gz"        # relative paths are relative to this file's folder
    labels = ["liver", "spleen", 3]    # or "all"
    space = "RAS"

    [smoothing]
    method = "organ"

    [decimation]
    ratio = 0.5                        # or target_faces = N, or max_error_mm = 0.3

    [check]
    enabled = true
    profile = "fdm"

    [output]
    dir = "out"
    formats = ["stl", "3mf", "glb"]

:func:`load_recipe` turns a file into a :class:`Recipe` (unknown keys and
wrongly typed values are one-line errors naming the key and what is allowed); :func:`dump_recipe`
writes one back (by hand: TOML writing needs no extra dependency). ``anatomesh mesh`` stores the
recipe of every run as ``recipe.toml`` next to its report, so ``anatomesh mesh --recipe
OUT/recipe.toml`` runs it again.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Dict, List, Optional, Union

from ...core.model.errors import AnatomeshError
from ...core.model.volume import SPACES
from ...core.printing.profiles import PROFILES as PRINTER_PROFILES
from .preprocess_settings import RESAMPLE_METHODS, check_preprocess
from .fit import check_fit  # cut to fit
from .settings import check_values, field_help, read_number_lists, fields_of, from_toml, sections, setting, to_toml

SMOOTH_NONE = "none"
SMOOTH_DEFAULT = "organ"  # the smoothing driver's default: Taubin in the voxel cell, volumes kept
#: per-surface formats, whole-scene formats, and the ones that need Blender (bpy)
SURFACE_FORMATS = ("stl", "ply", "obj", "3mf", "dicom")
SCENE_ONLY_FORMATS = ("glb", "blend", "png")
#: the web page: a folder (index.html + scripts), not one file
WEB_FORMAT = "web"
FORMATS = SURFACE_FORMATS + SCENE_ONLY_FORMATS + (WEB_FORMAT,)
BLENDER_FORMATS = ("blend", "png")
#: camera views of the png (the side of the patient the camera stands at), the default first
VIEWS = ("anterior", "posterior", "lateral_left", "lateral_right", "superior", "inferior", "oblique")
#: light presets of the .blend and png (studio: key, fill and rim; atlas: bright and even), the default first
LIGHTS = ("studio", "atlas")
STAIRCASE = ("auto", "on", "off")
PROFILES = tuple(PRINTER_PROFILES)
RECIPE_FILE = "recipe.toml"
# segmentations: DICOM write-back, RT contour methods
DICOM_FORMAT = "dicom"
CONTOURS_RASTER, CONTOURS_TILE = "raster", "tile"
CONTOURS = (CONTOURS_RASTER, CONTOURS_TILE)


#: a recipe file's sections in order, each with the comment written above it
SECTION_NOTES = {
    "input": "scan, label map, mask folder, DICOM SEG/RTSTRUCT; labels: \"all\" or values/names; levels: "
             "isovalues of a scalar scan; grid: a mask name, \"image\" or \"native\"; contours: raster or tile",
    "preprocess": "before extraction: resample (mm), resample_method (linear, cubic, lanczos), roi "
                  "(x0,y0,z0,x1,y1,z1 mm), smooth_volume (gaussian:SIGMA_MM, median:SIZE_MM, "
                  "diffusion:ITERATIONS), interpolate, fuzzy_boundary, fill_cavities, close_handles "
                  "(mm), fuzzy ([I1, I2, N]), precise, difference_colors",
    "surfaces": "isosurfaces capped at the volume's border; drop small components (mm3)",
    "smoothing": "method: organ, light, strong, taubin, laplacian, hc, mean_curvature, normal_mean, "
                 "normal_median, none",
    "decimation": "ratio of faces kept or target_faces, and/or max_error_mm (a cap with the others)",
    "check": "print checks: profile fdm or resin; min_wall_mm / min_gap_mm override it; fixes: fuse "
             "(groups of labels), thicken, clearance_mm; tools: hollow_mm (wall), drain_holes, "
             "drain_diameter_mm, connectors (label pairs), fit_mm (build volume [x, y, z]: cut parts to fit), "
             "fit_connectors (pins across the cuts)",
    "output": "formats: stl, ply, obj, 3mf, dicom, glb, blend, png, web; lod: GLB levels of detail (0: none); "
              "views: camera views of the png; turntable: frames of a turn around the body; labels_on: "
              "structures labelled in the png; style: a style table (TOML) over the default colours",
    "distance": "colour every surface by its distance (mm) to the structure `to` (name or value): "
                "within margins_mm red, yellow, green",
    "web": "the web page (format web): levels of detail, coarsest shown first",
}



@dataclass
class Recipe:
    """Everything a run needs. Paths may be strings; units are mm.

    ``labels``: "all", or a list of label values and/or names (label maps only).
    ``levels``: isovalues for scalar scans (required for them).
    ``space``: the space every written vertex is in ("RAS" or "LPS").
    ``formats``: any of :data:`FORMATS` ("stl", "ply", "obj", "3mf", "glb", "blend", "png").
    ``smooth``: a preset or filter of :mod:`anatomesh.core.smooth.driver` ("organ" by default, "none" keeps
    the raw surface); ``iterations``/``lam``/``mu`` override the preset, ``max_deviation`` (mm) caps
    every vertex's displacement, ``damping_distance`` (mm) enables distance-aware damping,
    ``staircase`` ("auto", "on", "off") the extra slice-axis passes for thick slices.
    ``decimate`` (ratio of faces kept, 0–1] or ``target_faces``, and/or ``max_error`` (mm):
    decimation after smoothing (:mod:`anatomesh.core.decimate.qem`; a label map's SurfaceSet as a
    whole, so seams stay shared). With a ratio or face count, ``max_error`` caps the error (default:
    one voxel, the largest spacing), so a target the shapes cannot reach stops short with a warning
    instead of ruining small organs. ``check``: run the print checks (:func:`~anatomesh.core.printing.checks.
    check_parts`) with ``profile`` ("fdm", "resin"), ``min_wall``/``min_gap`` (mm) overriding it.
    Print fixes (label maps; each reported under ``fixes``): ``fuse`` — groups of labels (values
    or names) merged into one solid each before extraction; ``thicken`` — grow parts thinner than
    the minimum wall (``min_wall`` or the profile's) in the label map before extraction;
    ``clearance`` (mm) — pull touching parts apart along their shared interfaces after decimation,
    so separately printed parts fit together (:mod:`anatomesh.core.printing.fixes`).
    ``hollow`` (mm) — hollow every part to a shell of this wall with ``drain_holes`` holes of
    ``drain_diameter`` mm (default: the profile's) at its lowest points (:mod:`anatomesh.core.printing.hollow`);
    ``connectors`` — pairs of touching labels (names/values) that get pins and pockets across
    their interface, clearance from the profile (:mod:`anatomesh.core.printing.connectors`).
    ``fit`` — the printer's build volume [x, y, z] mm: parts too big are cut into pieces that fit
    (``<part>_1``, ...), with pins across the cuts when ``fit_connectors`` (:mod:`anatomesh.app.flow.fit`).
    ``render_samples``/``render_size``: Cycles samples and pixel size of the "png" output; ``light``:
    the light preset of the .blend and png (:data:`LIGHTS`);
    ``views``: its camera views (:data:`VIEWS`; one PNG each, ``<scan>.png`` for the default alone,
    else ``<scan>_<view>.png``), ``turntable``: N frames of a full turn about the patient's long axis
    (``turntable/frame_0001.png`` .., and ``turntable.mp4`` where Blender has FFmpeg),
    ``labels_on``: structures (names) given leader-line labels in the views.
    ``grid``: the grid structures of a mask folder are meshed on (a mask name or "image"; default the
    finest), or for DICOM SEG/RTSTRUCT "image" (the referenced series) or "native" (the object's own
    planes). ``contours``: RTSTRUCT contours to surfaces by "raster" (even-odd rasterisation + shape-based
    interpolation, then the label-map flow) or "tile" (direct tiling between adjacent contours).
    Format "dicom": each surface as a DICOM Encapsulated STL object in the source's study and frame of
    reference (:mod:`anatomesh.core.export.dicom_stl`).
    ``lod``: number of levels of detail written as ``<scan>_lod0.glb`` (the final surfaces) ..
    ``<scan>_lod{n-1}.glb`` (each level half the faces of the one before, or the coarsest that keeps
    every shell's topology), all from one progressive decimation run (:mod:`anatomesh.core.decimate.progressive`,
    Hoppe 1996); 0 or 1: none.
    Distance colouring and the web page: ``distance_to`` — a label name or value: every other
    surface is coloured by its vertices' distance to that one's surface, within each of
    ``margins`` (mm, default 2, 5, 10) red, yellow, green (:mod:`anatomesh.core.geometry.margins`);
    ``web_levels`` — levels of detail of the "web" page (:mod:`anatomesh.app.web.page`), 1..4.
    ``web_views`` — a file of named views the page lists (:mod:`anatomesh.app.web.views`).
    """
    NOTES: ClassVar[Dict[str, str]] = SECTION_NOTES

    input: Union[str, List[str]] = setting("", "input", "path", "paths", "the scan, label map, mask folder or DICOM file/folder")
    out_dir: str = setting("out", "output", "dir", "path", "the output folder")
    series: Optional[str] = setting(None, "input", "series", "series", "a DICOM folder's series (number or UID)")
    volume_index: Optional[int] = setting(None, "input", "volume", "int", "the volume of a 4D file", low=0)
    label_table: Optional[str] = setting(None, "input", "label_table", "path", "label names (JSON, CSV or Slicer colour table)")
    labels: Union[str, List[Union[int, str]]] = setting("all", "input", "labels", "labels", "the labels to mesh")
    levels: List[float] = setting(None, "input", "levels", "floats", "isovalues of a scalar scan", factory=list)
    level_names: List[str] = setting(None, "input", "level_names", "strs",
                                     "names of the isosurfaces, one per level (default: isosurface VALUE)",
                                     factory=list)
    space: str = setting("RAS", "input", "space", "str", "coordinate space of the written vertices",
                         choices=SPACES, flag="--space")
    grid: Optional[str] = setting(None, "input", "grid", "str", "the grid masks or a segmentation are meshed on",
                                  allowed="a mask name, \"image\" or \"native\"")
    contours: str = setting(CONTOURS_RASTER, "input", "contours", "str",
                            "RTSTRUCT contours to surfaces: raster (even-odd rasterisation, shape-based "
                            "interpolation, conforming extraction) or tile (direct tiling between adjacent "
                            "contours)", choices=CONTOURS, flag="--contours")
    resample: Optional[List[float]] = setting(None, "preprocess", "resample", "number_or_floats",
                                              "scalar scans: resample to this voxel size (one number: isotropic)",
                                              unit="mm", allowed="a voxel size in mm or [x, y, z]", count=(1, 3),
                                              low=0, low_open=True, flag="--resample", metavar="MM|X,Y,Z")
    resample_method: str = setting("linear", "preprocess", "resample_method", "str",
                                   "interpolation of --resample: linear, cubic (B-spline) or lanczos",
                                   choices=RESAMPLE_METHODS, flag="--resample-method")
    roi: Optional[List[float]] = setting(None, "preprocess", "roi", "floats",
                                         "cut the scan to the box X0 Y0 Z0 X1 Y1 Z1 (in --space) before anything else",
                                         unit="mm", allowed="[x0, y0, z0, x1, y1, z1] in mm", count=(6,),
                                         flag="--roi", metavar="MM")
    smooth_volume: Optional[str] = setting(None, "preprocess", "smooth_volume", "str",
                                           "scalar scans: filter the volume first: gaussian:SIGMA_MM, median:SIZE_MM "
                                           "(one value or X,Y,Z) or diffusion:ITERATIONS (edge-preserving, Perona-Malik)",
                                           allowed="\"gaussian:SIGMA_MM\", \"median:SIZE_MM\" or \"diffusion:ITERATIONS\"",
                                           flag="--smooth-volume", metavar="SPEC")
    interpolate: bool = setting(False, "preprocess", "interpolate", "bool",
                                "label maps: shape-based interpolation to isotropic voxels at the finest spacing "
                                "(removes the staircase of thick slices)", flag="--interpolate")
    fuzzy_boundary: bool = setting(False, "preprocess", "fuzzy_boundary", "bool",
                                   "label maps: smooth each label at the voxel level (morphological fuzzy boundary); "
                                   "the surface stays within one voxel, measured", flag="--fuzzy-boundary")
    fill_cavities: bool = setting(False, "preprocess", "fill_cavities", "bool",
                                  "label maps: fill background pockets enclosed by a label", flag="--fill-cavities")
    close_handles: Optional[float] = setting(None, "preprocess", "close_handles", "float",
                                             "label maps: plug tunnels (handles) up to this size across; genus "
                                             "before/after reported", unit="mm", low=0, low_open=True,
                                             flag="--close-handles", metavar="MM")
    fuzzy: Optional[List[float]] = setting(None, "preprocess", "fuzzy", "floats",
                                           "scalar scans: I1 I2 [N], N (default 5) nested isosurfaces over [I1, I2], "
                                           "the middle one opaque, the others more transparent toward the ends",
                                           allowed="[I1, I2] or [I1, I2, N]", count=(2, 3), flag="--fuzzy",
                                           metavar="VALUE")
    precise: bool = setting(False, "preprocess", "precise", "bool",
                            "scalar scans: refine isosurface triangles onto the trilinear interpolant; reports how "
                            "far the surface moved", flag="--precise")
    difference_colors: bool = setting(False, "preprocess", "difference_colors", "bool",
                                      "colour surfaces by their distance to the surface without preprocessing "
                                      "(PLY/GLB vertex colours, a colour attribute in Blender)",
                                      flag="--difference-colors")
    cap: bool = setting(True, "surfaces", "cap", "bool",
                        "leave isosurfaces open where they leave the volume (default: capped, closed)",
                        flag="--no-cap")
    keep_largest: bool = setting(False, "surfaces", "keep_largest", "bool",
                                 "keep only the largest component per surface", flag="--keep-largest")
    min_component_mm3: float = setting(0.0, "surfaces", "min_component_mm3", "float",
                                       "drop components smaller than this volume", unit="mm³",
                                       flag="--min-component", metavar="MM3", low=0)
    smooth: str = setting(SMOOTH_DEFAULT, "smoothing", "method", "str",
                          "smoothing preset or filter: organ (Taubin kept inside each voxel cell, volumes "
                          "restored), light, strong, taubin, laplacian, hc, mean_curvature, normal_mean, "
                          "normal_median, none (raw surface)", allowed="a smoothing preset or method name",
                          flag="--smooth")
    iterations: Optional[int] = setting(None, "smoothing", "iterations", "int",
                                         "smoothing iterations (overrides the preset)", flag="--iterations", low=0)
    lam: Optional[float] = setting(None, "smoothing", "lambda", "float", "smoothing step λ (overrides the preset)",
                                  flag="--lambda", low=0, high=1, low_open=True)
    mu: Optional[float] = setting(None, "smoothing", "mu", "float", "Taubin's negative step μ (overrides the preset)",
                                 flag="--mu", low=-1, high=0)
    max_deviation: Optional[float] = setting(None, "smoothing", "max_deviation_mm", "float",
                                             "no vertex moves further than this from the unsmoothed surface",
                                             unit="mm", flag="--max-deviation", metavar="MM", low=0, low_open=True)
    damping_distance: Optional[float] = setting(None, "smoothing", "damping_distance_mm", "float",
                                                "smooth less where another structure is closer than this "
                                                "(Mönch et al. 2011)", unit="mm", flag="--damping-distance",
                                                metavar="MM", low=0, low_open=True)
    staircase: str = setting("auto", "smoothing", "staircase", "str",
                             "extra slice-axis smoothing for thick slices (auto: slice >= 1.5x in-plane)",
                             choices=STAIRCASE, flag="--staircase")
    decimate: Optional[float] = setting(None, "decimation", "ratio", "float",
                                        "after smoothing, keep this fraction of the faces (0.1 = 10 %); seams stay "
                                        "shared, shells closed; the error in mm is measured and reported",
                                        allowed="a number in (0, 1]", flag="--decimate", metavar="RATIO", low=0, high=1, low_open=True)
    target_faces: Optional[int] = setting(None, "decimation", "target_faces", "int", "decimate to N faces in all",
                                           flag="--target-faces", metavar="N", low=4)
    max_error: Optional[float] = setting(None, "decimation", "max_error_mm", "float",
                                         "decimate as far as the surface stays within this of the smoothed one; "
                                         "with --decimate/--target-faces a cap on their error (default: one voxel)",
                                         unit="mm", flag="--max-error", metavar="MM", low=0, low_open=True)
    check: bool = setting(False, "check", "enabled", "bool",
                          "run the 3D-print checks on the result (exit code 1 when one fails)", flag="--check")
    profile: str = setting("fdm", "check", "profile", "str", "printer profile of the print checks and tools",
                           choices=PROFILES, flag="--profile")
    min_wall: Optional[float] = setting(None, "check", "min_wall_mm", "float",
                                        "thinnest printable wall (overrides the profile)", unit="mm",
                                        flag="--min-wall", metavar="MM", low=0, low_open=True)
    min_gap: Optional[float] = setting(None, "check", "min_gap_mm", "float",
                                       "narrowest gap that stays open (overrides the profile)", unit="mm",
                                       flag="--min-gap", metavar="MM", low=0, low_open=True)
    fuse: List[List[Union[int, str]]] = setting(None, "check", "fuse", "label_groups", "label groups merged into one solid each",
                                                allowed="a list of label groups, e.g. [[\"liver\", \"spleen\"]]", factory=list)
    thicken: bool = setting(False, "check", "thicken", "bool",
                            "print fix: grow parts thinner than the minimum wall (--min-wall or the profile's) "
                            "in the label map before extraction", flag="--thicken")
    clearance: Optional[float] = setting(None, "check", "clearance_mm", "float",
                                         "print fix: pull touching parts apart by this along their shared "
                                         "interfaces, so separately printed parts fit together", unit="mm",
                                         flag="--clearance", metavar="MM", low=0, low_open=True)
    hollow: Optional[float] = setting(None, "check", "hollow_mm", "float",
                                      "print tool (resin/powder): hollow every part to a shell of this wall, with "
                                      "drain holes at its lowest points (+z of the patient is up)", unit="mm",
                                      flag="--hollow", metavar="WALL_MM", low=0, low_open=True)
    drain_holes: int = setting(2, "check", "drain_holes", "int", "drain holes per cavity",
                                flag="--drain-holes", metavar="N", low=0, high=16)
    drain_diameter: Optional[float] = setting(None, "check", "drain_diameter_mm", "float",
                                              "drain hole diameter (default: the profile's, fdm 4 mm, resin 3 mm)",
                                              unit="mm", flag="--drain-diameter", metavar="MM", low=0, low_open=True)
    connectors: List[List[Union[int, str]]] = setting(None, "check", "connectors", "label_pairs",
                                                      "pairs of touching labels joined by pins and pockets",
                                                      allowed="a list of label pairs, e.g. [[\"liver\", \"stomach\"]]", factory=list)
    fit: Optional[List[float]] = setting(None, "check", "fit_mm", "floats", "the printer's build volume: bigger parts are cut to fit",
                                         unit="mm", allowed="the build volume [x, y, z] in mm", count=(3,), low=0, low_open=True)
    fit_connectors: bool = setting(False, "check", "fit_connectors", "bool", "pins across the cuts")
    formats: List[str] = setting(None, "output", "formats", "strs", "output formats", allowed="a list of format names",
                                 factory=lambda: ["stl"])
    report: Optional[str] = setting(None, "output", "report", "path",
                                    "report path (default OUT/report.json; recipe.toml is written beside it)",
                                    flag="--report")
    overwrite: bool = setting(False, "output", "overwrite", "bool", "replace existing output files",
                              flag="--overwrite")
    style: Optional[str] = setting(None, "output", "style", "path",
                                   "style table (TOML): colour, material and opacity per structure "
                                   "over the default (docs/STYLES.md)", flag="--style")
    render_samples: int = setting(32, "output", "render_samples", "int", "Cycles samples of the png", low=1)
    render_size: List[int] = setting(None, "output", "render_size", "ints", "pixel size of the png",
                                     allowed="[width, height] in pixels", count=(2,),
                                     factory=lambda: [960, 540], low=16)
    light: str = setting("studio", "output", "light", "str",
                         "light of the .blend and png: studio (key, fill and rim lights, dark backdrop) or "
                         "atlas (bright even light, light backdrop)", choices=LIGHTS, flag="--light")
    views: List[str] = setting(None, "output", "views", "strs",
                               "camera views of the png, each framing the anatomy: anterior, posterior, "
                               "lateral_left, lateral_right, superior, inferior, oblique (one PNG each)",
                               allowed="a list of view names", factory=lambda: ["anterior"], flag="--view",
                               metavar="VIEW")
    turntable: int = setting(0, "output", "turntable", "int",
                             "render N frames of a full turn around the patient's long axis into "
                             "turntable/frame_NNNN.png (and turntable.mp4 where Blender has FFmpeg)",
                             flag="--turntable", metavar="N", low=0, high=720)
    labels_on: List[str] = setting(None, "output", "labels_on", "strs",
                                   "structures (names) labelled in the png views, each by a leader line",
                                   allowed="a list of structure names", factory=list, flag="--labels-on",
                                   metavar="NAMES")
    lod: int = setting(0, "output", "lod", "int",
                     "also write N GLB levels of detail, <scan>_lod0.glb (finest) .. _lod{N-1}.glb, each half "
                     "the faces of the one before, from one progressive decimation run", flag="--lod", metavar="N", low=0, high=8)
    distance_to: Optional[Union[int, str]] = setting(None, "distance", "to", "label",
                                                     "colour every other surface by its distance to this "
                                                     "structure (name or value)", flag="--distance-to",
                                                     metavar="LABEL")
    margins: List[float] = setting(None, "distance", "margins_mm", "floats",
                                   "safety margins for --distance-to, coloured red, yellow, green", unit="mm",
                                   allowed="a list of distances in mm, e.g. [2, 5, 10]",
                                   factory=lambda: [2.0, 5.0, 10.0], low=0, low_open=True, flag="--margins",
                                   metavar="MM")
    web_levels: int = setting(2, "web", "levels", "int", "levels of detail of the web page, the coarsest shown first",
                              low=1, high=4, flag="--web-levels", metavar="N")
    web_views: Optional[str] = setting(None, "web", "views", "path",
                                       "saved views listed in the web page: a TOML or JSON file of name = URL "
                                       "fragment or table (keys hide, opacity, clip, view, camera, measure)",
                                       flag="--web-views", metavar="FILE")

    def smoothing_overrides(self) -> Dict:
        """What this recipe sets of the smoothing preset's own settings (``iterations``, ``lam``,
        ``mu``; those left at None are the preset's)."""
        return {k: v for k, v in (("iterations", self.iterations), ("lam", self.lam), ("mu", self.mu))
                if v is not None}


def check_recipe(recipe: Recipe) -> None:
    """Raise :class:`AnatomeshError` (one line, naming the setting) for a setting out of range;
    reads no input file. Normalises ``recipe`` in place (format names, fit, margins): a run
    checks its own copy."""
    if not recipe.input:
        raise AnatomeshError("no input scan: give a path (or input.path in a recipe)")
    if recipe.smooth != SMOOTH_NONE:
        from ...core.smooth.presets import check_settings

        check_settings(recipe.smooth, **recipe.smoothing_overrides())
    recipe.formats = [str(f).strip().lower().lstrip(".") for f in recipe.formats]
    bad = [f for f in recipe.formats if f not in FORMATS]
    if bad or not recipe.formats:
        raise AnatomeshError(f"unknown --format {','.join(bad) or '(none)'}; use a comma list of "
                             f"{', '.join(FORMATS)}")
    read_number_lists(recipe)  # numbers from the flags' texts
    check_preprocess(recipe)
    check_values(recipe)
    if recipe.level_names and len(recipe.level_names) != len(recipe.levels):
        raise AnatomeshError(f"level_names names each of the {len(recipe.levels)} levels, got "
                             f"{len(recipe.level_names)} names")
    if recipe.decimate is not None and recipe.target_faces is not None:
        raise AnatomeshError("give --decimate RATIO or --target-faces N, not both (--max-error MM "
                             "may come with either as a cap on the error)")
    if not isinstance(recipe.fuse, list) or not all(isinstance(g, list) for g in recipe.fuse):
        raise AnatomeshError(f"fuse must be a list of label groups (lists of values or names), got {recipe.fuse!r}")
    recipe.fit = check_fit(recipe.fit)  # cut to fit
    if len(recipe.render_size) != 2:
        raise AnatomeshError(f"render_size is [width, height] in pixels, got {recipe.render_size!r}")
    check_views(recipe)
    from ...core.geometry.margins import check_margins  # distance colouring

    recipe.margins = list(check_margins(recipe.margins))
    if recipe.web_views:  # the page's saved views: a bad file is refused before reading the scan
        from ..web.views import read_views

        read_views(recipe.web_views)


def check_views(recipe: Recipe) -> None:
    """The camera settings as lists (a flag gives a comma text), views in lower case and known, in
    place; one-line error naming the unknown view."""
    for name in ("views", "labels_on"):
        value = getattr(recipe, name)
        if isinstance(value, str):
            setattr(recipe, name, [v.strip() for v in value.split(",") if v.strip()])
    recipe.views = [str(v).strip().lower() for v in recipe.views] or ["anterior"]
    bad = [v for v in recipe.views if v not in VIEWS]
    if bad:
        raise AnatomeshError(f"unknown --view {','.join(bad)}; use a comma list of {', '.join(VIEWS)}")


#: the Recipe's sections (:func:`~anatomesh.app.flow.settings.sections`)
SECTIONS = sections(Recipe)
_HEADER = ("# Anatomesh recipe: run it with `anatomesh mesh --recipe THIS_FILE`",
           "# (command-line flags override it; relative paths are relative to this file)")


def load_recipe(path) -> Recipe:
    """Read a recipe TOML file into a :class:`Recipe`.

    Relative paths in it (input, label table, output folder, report) are taken relative to the
    file's folder. Keys not given keep :class:`Recipe`'s defaults. Raises :class:`AnatomeshError`
    for a missing or malformed file, an unknown section or key (naming the allowed ones) or a
    value of the wrong type.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise AnatomeshError("no such recipe file; check the path", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise AnatomeshError(f"cannot read the recipe ({exc})", path) from None
    return recipe_from_text(text, base=path.parent, source=path)


def recipe_from_text(text: str, base=None, source=None, recipe_type=Recipe) -> Recipe:
    """:func:`load_recipe` on TOML text; relative paths resolve against ``base`` (if given)."""
    return from_toml(text, recipe_type, base=base, source=source)


def dump_recipe(recipe: Recipe, base=None) -> str:
    """The recipe as TOML text (settings that are None left out). With ``base`` (the folder the
    file will be written to), paths are written relative to it; :func:`load_recipe` of the
    written file gives back an equal :class:`Recipe` (paths absolute)."""
    return to_toml(recipe, base=base, header=_HEADER)


def setting_help(name: str, unset: str = "") -> str:
    """A Recipe setting's help as a panel shows it (:func:`~anatomesh.app.flow.settings.field_help`)."""
    return field_help(fields_of(Recipe)[name], unset)


if __name__ == "__main__":  # python -m anatomesh.app.flow.recipe > table: the docs' settings table
    from .settings import settings_table

    print(settings_table(Recipe), end="")
