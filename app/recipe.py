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

import dataclasses
import json
import math
import os
import tomllib
from pathlib import Path
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Union

from ..core.model.errors import AnatomeshError
from ..core.model.volume import SPACES
from ..core.printing.profiles import PROFILES as PRINTER_PROFILES
from .preprocess_settings import check_preprocess
from .fit import check_fit  # cut to fit

SMOOTH_NONE = "none"
SMOOTH_DEFAULT = "organ"  # the smoothing driver's default: Taubin in the voxel cell, volumes kept
#: per-surface formats, whole-scene formats, and the ones that need Blender (bpy)
SURFACE_FORMATS = ("stl", "ply", "obj", "3mf", "dicom")
SCENE_ONLY_FORMATS = ("glb", "blend", "png")
#: the web page: a folder (index.html + scripts), not one file
WEB_FORMAT = "web"
FORMATS = SURFACE_FORMATS + SCENE_ONLY_FORMATS + (WEB_FORMAT,)
BLENDER_FORMATS = ("blend", "png")
STAIRCASE = ("auto", "on", "off")
PROFILES = tuple(PRINTER_PROFILES)
RECIPE_FILE = "recipe.toml"
# segmentations: DICOM write-back, RT contour methods
DICOM_FORMAT = "dicom"
CONTOURS_RASTER, CONTOURS_TILE = "raster", "tile"
CONTOURS = (CONTOURS_RASTER, CONTOURS_TILE)


#: what a setting's value may be in a recipe file: (check, words for the error, conversion)
_KINDS = {
    "bool": (lambda v: isinstance(v, bool), "true or false", None),
    "int": (lambda v: _is_int(v), "a whole number", None),
    "float": (lambda v: _is_number(v), "a number", float),
    "str": (lambda v: isinstance(v, str), "a text", None),
    "path": (lambda v: isinstance(v, str), "a path", None),
    "paths": (lambda v: isinstance(v, str) or (isinstance(v, list) and v and all(isinstance(x, str) for x in v)),
              "a path or a list of paths", None),
    "floats": (lambda v: isinstance(v, list) and all(_is_number(x) for x in v), "a list of numbers",
               lambda v: [float(x) for x in v]),
    "strs": (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), "a list of names", None),
    "ints": (lambda v: isinstance(v, list) and all(_is_int(x) for x in v), "a list of whole numbers", None),
    "label": (lambda v: isinstance(v, str) or _is_int(v), "a label name or value", None),
    "labels": (lambda v: v == "all" or (isinstance(v, list) and all(isinstance(x, str) or _is_int(x) for x in v)),
               "\"all\" or a list of label values/names", None),
    "label_groups": (lambda v: isinstance(v, list) and all(isinstance(g, list) and all(
        isinstance(x, str) or _is_int(x) for x in g) for g in v), "a list of label groups", None),
    "label_pairs": (lambda v: isinstance(v, list) and all(isinstance(g, list) and len(g) == 2 and all(
        isinstance(x, str) or _is_int(x) for x in g) for g in v), "a list of label pairs", None),
    "series": (lambda v: isinstance(v, (str, int)) and not isinstance(v, bool), "a series UID or number", str),
    "number_or_floats": (lambda v: _is_number(v) or (isinstance(v, list) and all(_is_number(x) for x in v)),
                         "a number or a list of numbers", None),
}


def setting(default, section: str, key: str, kind: str, help: str, *, unit: str = "",
            allowed: str = "", count: tuple = (), choices: tuple = (), flag: str = "",
            metavar: str = "", factory=None):
    """A recipe field, defined once: its default, where it sits in a recipe file (``[section]
    key``), its kind (:data:`_KINDS`; a list kind with ``count``: one of these lengths; a text
    with ``choices``: one of them), what it does (``help``: the command line's help and the
    documentation's), its ``unit``, its command-line ``flag`` (with ``metavar``; flags of plain
    kinds are made from this definition: :func:`anatomesh.app.cli.settings_args.add_setting_args`)
    and, for the one-line error of a wrong value, what is ``allowed`` (default: the choices or
    the kind's words)."""
    if choices and not allowed:
        allowed = " or ".join(f'"{c}"' for c in choices)
    meta = {"section": section, "key": key, "kind": kind, "help": help, "unit": unit,
            "allowed": allowed or _KINDS[kind][1], "count": count, "choices": tuple(choices),
            "flag": flag, "metavar": metavar}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


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
    (``<part>_1``, ...), with pins across the cuts when ``fit_connectors`` (:mod:`anatomesh.app.fit`).
    ``render_samples``/``render_size``: Cycles samples and pixel size of the "png" output.
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
    ``web_levels`` — levels of detail of the "web" page (:mod:`anatomesh.app.web`), 1..4.
    """
    input: Union[str, List[str]] = setting("", "input", "path", "paths", "the scan, label map, mask folder or DICOM file/folder")
    out_dir: str = setting("out", "output", "dir", "path", "the output folder")
    series: Optional[str] = setting(None, "input", "series", "series", "a DICOM folder's series (number or UID)")
    volume_index: Optional[int] = setting(None, "input", "volume", "int", "the volume of a 4D file")
    label_table: Optional[str] = setting(None, "input", "label_table", "path", "label names (JSON, CSV or Slicer colour table)")
    labels: Union[str, List[Union[int, str]]] = setting("all", "input", "labels", "labels", "the labels to mesh")
    levels: List[float] = setting(None, "input", "levels", "floats", "isovalues of a scalar scan", factory=list)
    space: str = setting("RAS", "input", "space", "str", "coordinate space of the written vertices",
                         choices=SPACES, flag="--space")
    grid: Optional[str] = setting(None, "input", "grid", "str", "the grid masks or a segmentation are meshed on",
                                  allowed="a mask name, \"image\" or \"native\"")
    contours: str = setting(CONTOURS_RASTER, "input", "contours", "str",
                            "RTSTRUCT contours to surfaces: raster (even-odd rasterisation, shape-based "
                            "interpolation, conforming extraction) or tile (direct tiling between adjacent "
                            "contours)", choices=CONTOURS, flag="--contours")
    resample: Optional[List[float]] = setting(None, "preprocess", "resample", "number_or_floats",
                                              "resample to this voxel size", unit="mm", allowed="a voxel size in mm or [x, y, z]",
                                              count=(1, 3))
    resample_method: str = setting("linear", "preprocess", "resample_method", "str", "interpolation of --resample",
                                   allowed="\"linear\", \"cubic\" or \"lanczos\"")
    roi: Optional[List[float]] = setting(None, "preprocess", "roi", "floats", "crop to this box", unit="mm",
                                         allowed="[x0, y0, z0, x1, y1, z1] in mm", count=(6,))
    smooth_volume: Optional[str] = setting(None, "preprocess", "smooth_volume", "str", "filter the volume first",
                                           allowed="\"gaussian:SIGMA_MM\", \"median:SIZE_MM\" or \"diffusion:ITERATIONS\"")
    interpolate: bool = setting(False, "preprocess", "interpolate", "bool", "label maps: shape-based interpolation")
    fuzzy_boundary: bool = setting(False, "preprocess", "fuzzy_boundary", "bool", "label maps: morphological fuzzy boundary")
    fill_cavities: bool = setting(False, "preprocess", "fill_cavities", "bool", "label maps: fill enclosed pockets")
    close_handles: Optional[float] = setting(None, "preprocess", "close_handles", "float", "label maps: plug tunnels up to this size",
                                             unit="mm", allowed="a size in mm")
    fuzzy: Optional[List[float]] = setting(None, "preprocess", "fuzzy", "floats", "N nested isosurfaces over [I1, I2]",
                                           allowed="[I1, I2] or [I1, I2, N]", count=(2, 3))
    precise: bool = setting(False, "preprocess", "precise", "bool", "refine isosurfaces onto the trilinear interpolant")
    difference_colors: bool = setting(False, "preprocess", "difference_colors", "bool",
                                      "colour surfaces by their distance to the surface without preprocessing")
    cap: bool = setting(True, "surfaces", "cap", "bool",
                        "leave isosurfaces open where they leave the volume (default: capped, closed)",
                        flag="--no-cap")
    keep_largest: bool = setting(False, "surfaces", "keep_largest", "bool",
                                 "keep only the largest component per surface", flag="--keep-largest")
    min_component_mm3: float = setting(0.0, "surfaces", "min_component_mm3", "float",
                                       "drop components smaller than this volume", unit="mm³",
                                       flag="--min-component", metavar="MM3")
    smooth: str = setting(SMOOTH_DEFAULT, "smoothing", "method", "str",
                          "smoothing preset or filter: organ (Taubin kept inside each voxel cell, volumes "
                          "restored), light, strong, taubin, laplacian, hc, mean_curvature, normal_mean, "
                          "normal_median, none (raw surface)", allowed="a smoothing preset or method name",
                          flag="--smooth")
    iterations: Optional[int] = setting(None, "smoothing", "iterations", "int",
                                         "smoothing iterations (overrides the preset)", flag="--iterations")
    lam: Optional[float] = setting(None, "smoothing", "lambda", "float", "smoothing step λ (overrides the preset)",
                                  flag="--lambda")
    mu: Optional[float] = setting(None, "smoothing", "mu", "float", "Taubin's negative step μ (overrides the preset)",
                                 flag="--mu")
    max_deviation: Optional[float] = setting(None, "smoothing", "max_deviation_mm", "float",
                                             "no vertex moves further than this from the unsmoothed surface",
                                             unit="mm", flag="--max-deviation", metavar="MM")
    damping_distance: Optional[float] = setting(None, "smoothing", "damping_distance_mm", "float",
                                                "smooth less where another structure is closer than this "
                                                "(Mönch et al. 2011)", unit="mm", flag="--damping-distance",
                                                metavar="MM")
    staircase: str = setting("auto", "smoothing", "staircase", "str",
                             "extra slice-axis smoothing for thick slices (auto: slice >= 1.5x in-plane)",
                             choices=STAIRCASE, flag="--staircase")
    decimate: Optional[float] = setting(None, "decimation", "ratio", "float",
                                        "after smoothing, keep this fraction of the faces (0.1 = 10 %); seams stay "
                                        "shared, shells closed; the error in mm is measured and reported",
                                        allowed="a number in (0, 1]", flag="--decimate", metavar="RATIO")
    target_faces: Optional[int] = setting(None, "decimation", "target_faces", "int", "decimate to N faces in all",
                                           flag="--target-faces", metavar="N")
    max_error: Optional[float] = setting(None, "decimation", "max_error_mm", "float",
                                         "decimate as far as the surface stays within this of the smoothed one; "
                                         "with --decimate/--target-faces a cap on their error (default: one voxel)",
                                         unit="mm", flag="--max-error", metavar="MM")
    check: bool = setting(False, "check", "enabled", "bool",
                          "run the 3D-print checks on the result (exit code 1 when one fails)", flag="--check")
    profile: str = setting("fdm", "check", "profile", "str", "printer profile of the print checks and tools",
                           choices=PROFILES, flag="--profile")
    min_wall: Optional[float] = setting(None, "check", "min_wall_mm", "float",
                                        "thinnest printable wall (overrides the profile)", unit="mm",
                                        flag="--min-wall", metavar="MM")
    min_gap: Optional[float] = setting(None, "check", "min_gap_mm", "float",
                                       "narrowest gap that stays open (overrides the profile)", unit="mm",
                                       flag="--min-gap", metavar="MM")
    fuse: List[List[Union[int, str]]] = setting(None, "check", "fuse", "label_groups", "label groups merged into one solid each",
                                                allowed="a list of label groups, e.g. [[\"liver\", \"spleen\"]]", factory=list)
    thicken: bool = setting(False, "check", "thicken", "bool",
                            "print fix: grow parts thinner than the minimum wall (--min-wall or the profile's) "
                            "in the label map before extraction", flag="--thicken")
    clearance: Optional[float] = setting(None, "check", "clearance_mm", "float",
                                         "print fix: pull touching parts apart by this along their shared "
                                         "interfaces, so separately printed parts fit together", unit="mm",
                                         flag="--clearance", metavar="MM")
    hollow: Optional[float] = setting(None, "check", "hollow_mm", "float",
                                      "print tool (resin/powder): hollow every part to a shell of this wall, with "
                                      "drain holes at its lowest points (+z of the patient is up)", unit="mm",
                                      flag="--hollow", metavar="WALL_MM")
    drain_holes: int = setting(2, "check", "drain_holes", "int", "drain holes per cavity",
                                flag="--drain-holes", metavar="N")
    drain_diameter: Optional[float] = setting(None, "check", "drain_diameter_mm", "float",
                                              "drain hole diameter (default: the profile's, fdm 4 mm, resin 3 mm)",
                                              unit="mm", flag="--drain-diameter", metavar="MM")
    connectors: List[List[Union[int, str]]] = setting(None, "check", "connectors", "label_pairs",
                                                      "pairs of touching labels joined by pins and pockets",
                                                      allowed="a list of label pairs, e.g. [[\"liver\", \"stomach\"]]", factory=list)
    fit: Optional[List[float]] = setting(None, "check", "fit_mm", "floats", "the printer's build volume: bigger parts are cut to fit",
                                         unit="mm", allowed="the build volume [x, y, z] in mm", count=(3,))
    fit_connectors: bool = setting(False, "check", "fit_connectors", "bool", "pins across the cuts")
    formats: List[str] = setting(None, "output", "formats", "strs", "output formats", allowed="a list of format names",
                                 factory=lambda: ["stl"])
    report: Optional[str] = setting(None, "output", "report", "path",
                                    "report path (default OUT/report.json; recipe.toml is written beside it)",
                                    flag="--report")
    overwrite: bool = setting(False, "output", "overwrite", "bool", "replace existing output files",
                              flag="--overwrite")
    render_samples: int = setting(32, "output", "render_samples", "int", "Cycles samples of the png")
    render_size: List[int] = setting(None, "output", "render_size", "ints", "pixel size of the png",
                                     allowed="[width, height] in pixels", count=(2,),
                                     factory=lambda: [960, 540])
    lod: int = setting(0, "output", "lod", "int",
                     "also write N GLB levels of detail, <scan>_lod0.glb (finest) .. _lod{N-1}.glb, each half "
                     "the faces of the one before, from one progressive decimation run",
                     allowed="a whole number (GLB levels of detail, 0: none)", flag="--lod", metavar="N")
    distance_to: Optional[Union[int, str]] = setting(None, "distance", "to", "label", "colour every surface by its distance to this one")
    margins: List[float] = setting(None, "distance", "margins_mm", "floats", "distance bands: red, yellow, green", unit="mm",
                                   allowed="a list of distances in mm, e.g. [2, 5, 10]", factory=lambda: [2.0, 5.0, 10.0])
    web_levels: int = setting(2, "web", "levels", "int", "levels of detail of the web page", allowed="a whole number (1..4)")

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
        from ..core.smooth.presets import check_settings

        check_settings(recipe.smooth, **recipe.smoothing_overrides())
    recipe.formats = [str(f).strip().lower().lstrip(".") for f in recipe.formats]
    bad = [f for f in recipe.formats if f not in FORMATS]
    if bad or not recipe.formats:
        raise AnatomeshError(f"unknown --format {','.join(bad) or '(none)'}; use a comma list of "
                             f"{', '.join(FORMATS)}")
    for name, value, allowed in (("space", recipe.space, SPACES), ("staircase", recipe.staircase, STAIRCASE),
                                 ("profile", recipe.profile, PROFILES), ("contours", recipe.contours, CONTOURS)):
        if value not in allowed:
            raise AnatomeshError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
    if not (isinstance(recipe.lod, int) and 0 <= recipe.lod <= 8):
        raise AnatomeshError(f"--lod is the number of GLB levels of detail, 0..8, got {recipe.lod!r}")
    if recipe.decimate is not None and recipe.target_faces is not None:
        raise AnatomeshError("give --decimate RATIO or --target-faces N, not both (--max-error MM "
                             "may come with either as a cap on the error)")
    if recipe.decimate is not None and not 0.0 < recipe.decimate <= 1.0:
        raise AnatomeshError(f"--decimate is the fraction of faces kept, in (0, 1], got {recipe.decimate}")
    if recipe.target_faces is not None and (int(recipe.target_faces) != recipe.target_faces
                                            or recipe.target_faces < 4):
        raise AnatomeshError(f"--target-faces must be a whole number >= 4, got {recipe.target_faces}")
    if not isinstance(recipe.fuse, list) or not all(isinstance(g, list) for g in recipe.fuse):
        raise AnatomeshError(f"fuse must be a list of label groups (lists of values or names), got {recipe.fuse!r}")
    for name in ("max_error", "min_wall", "min_gap", "max_deviation", "damping_distance", "clearance",
                 "hollow", "drain_diameter"):
        value = getattr(recipe, name)
        if value is not None and not value > 0:
            raise AnatomeshError(f"--{name.replace('_', '-')} is a distance in mm and must be > 0, got {value}")
    if not (isinstance(recipe.drain_holes, int) and 0 <= recipe.drain_holes <= 16):
        raise AnatomeshError(f"--drain-holes is a count of holes per cavity, 0..16, got {recipe.drain_holes!r}")
    recipe.fit = check_fit(recipe.fit)  # cut to fit
    if recipe.render_samples < 1 or len(recipe.render_size) != 2 or min(recipe.render_size) < 16:
        raise AnatomeshError("render_samples must be >= 1 and render_size two pixel counts >= 16")
    # distance colouring and the web page
    from ..core.geometry.margins import check_margins  # speed: numba's kernels load on use

    recipe.margins = list(check_margins(recipe.margins))
    if not (isinstance(recipe.web_levels, int) and 1 <= recipe.web_levels <= 4):
        raise AnatomeshError(f"--web-levels is the number of levels of detail of the page, 1..4, "
                             f"got {recipe.web_levels!r}")
    check_preprocess(recipe)  # preprocessing


#: the order of a recipe file's sections, each with a comment written above it
_NOTES = {
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
    "output": "formats: stl, ply, obj, 3mf, dicom, glb, blend, png, web; lod: GLB levels of detail (0: none)",
    "distance": "colour every surface by its distance (mm) to the structure `to` (name or value): "
                "within margins_mm red, yellow, green",
    "web": "the web page (format web): levels of detail, coarsest shown first",
}


def sections(recipe_type=Recipe) -> Dict[str, Dict[str, str]]:
    """TOML section → {TOML key: field name} of a recipe type, from its fields' own definitions
    (sections in the order of :data:`_NOTES`)."""
    out: Dict[str, Dict[str, str]] = {section: {} for section in _NOTES}
    for f in dataclasses.fields(recipe_type):
        out[f.metadata["section"]][f.metadata["key"]] = f.name
    return out


def _fields(recipe_type=Recipe) -> Dict[str, dataclasses.Field]:
    return {f.name: f for f in dataclasses.fields(recipe_type)}


def _path_fields(recipe_type=Recipe) -> tuple:
    """The fields holding paths (resolved against the recipe's folder)."""
    return tuple(f.name for f in dataclasses.fields(recipe_type) if f.metadata["kind"] in ("path", "paths"))


#: the Recipe's sections (:func:`sections`)
SECTIONS = sections(Recipe)


def setting_help(name: str, unset: str = "") -> str:
    """A Recipe setting's help as a panel shows it (a Blender property's description): what it
    does, its unit, and what the panel's ``unset`` value means (e.g. "0: the preset's own")."""
    m = _fields()[name].metadata
    text = m["help"][:1].upper() + m["help"][1:]
    if m["unit"] and m["unit"] not in text:
        text += f", {m['unit']}"
    return text + (f" ({unset})" if unset else "")


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def settings_table(recipe_type=Recipe) -> str:
    """Every recipe setting as a Markdown table (section, key, value, default, unit, what it does,
    command-line flag), from the fields' own definitions."""
    rows = ["| section | key | value | default | unit | what it does | flag |", "|---|---|---|---|---|---|---|"]
    fields = _fields(recipe_type)
    for f in (fields[name] for keys in sections(recipe_type).values() for name in keys.values()):
        m = f.metadata
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        rows.append(f"| `[{m['section']}]` | `{m['key']}` | {m['allowed']} | "
                    f"{'' if default in (None, '') else '`' + _toml_value(default) + '`'} | {m['unit']} | {m['help']} | "
                    f"{'`' + m['flag'] + '`' if m['flag'] else ''} |")
    return "\n".join(rows) + "\n"


# ---------------------------------------------------------------------------------------------
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
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise AnatomeshError(f"not valid TOML ({exc}); fix the recipe file", source) from None
    values = {}
    known, fields = sections(recipe_type), _fields(recipe_type)
    for section, body in doc.items():
        keys = known.get(section)
        if keys is None:
            raise AnatomeshError(f"unknown recipe section [{section}]; allowed sections: "
                                 f"{', '.join(known)}", source)
        if not isinstance(body, dict):
            raise AnatomeshError(f"{section} must be a [{section}] section with keys "
                                 f"{', '.join(keys)}", source)
        for key, value in body.items():
            name = keys.get(key)
            if name is None:
                raise AnatomeshError(f"unknown key {key!r} in [{section}]; allowed keys: "
                                     f"{', '.join(keys)}", source)
            meta = fields[name].metadata
            ok, _, convert = _KINDS[meta["kind"]]
            if not ok(value) or (meta["count"] and isinstance(value, list) and len(value) not in meta["count"]):
                raise AnatomeshError(f"[{section}] {key} must be {meta['allowed']}, got {value!r}", source)
            values[name] = value if convert is None else convert(value)
    if base is not None:
        for name in _path_fields(recipe_type):
            if values.get(name):
                values[name] = _resolve(values[name], Path(base))
    return recipe_type(**values)


def _resolve(value, base: Path):
    if isinstance(value, list):
        return [_resolve(v, base) for v in value]
    p = Path(os.path.expanduser(value))
    return str(p if p.is_absolute() else Path(os.path.abspath(base / p)))


# ---------------------------------------------------------------------------------------------
def dump_recipe(recipe: Recipe, base=None) -> str:
    """The recipe as TOML text (sections as in :func:`sections`; settings that are None left out).

    With ``base`` (the folder the file will be written to), paths are written relative to it, so
    a folder holding a recipe and its scan can be moved as a whole; :func:`load_recipe` of the
    written file gives back an equal :class:`Recipe` (paths absolute).
    """
    values = dataclasses.asdict(recipe)
    if base is not None:
        for name in _path_fields(type(recipe)):
            if values.get(name):
                values[name] = _relative(values[name], Path(base))
    lines = ["# Anatomesh recipe: run it with `anatomesh mesh --recipe THIS_FILE`",
             "# (command-line flags override it; relative paths are relative to this file)"]
    for section, keys in sections(type(recipe)).items():
        body = [f"{key} = {_toml_value(values[name])}" for key, name in keys.items()
                if values[name] is not None]
        if body:
            lines += ["", f"# {_NOTES[section]}", f"[{section}]"] + body
    return "\n".join(lines) + "\n"


def _relative(value, base: Path):
    if isinstance(value, list):
        return [_relative(v, base) for v in value]
    p = os.path.abspath(os.path.expanduser(str(value)))
    b = os.path.abspath(base)
    try:
        common = os.path.commonpath([p, b])
    except ValueError:  # another drive (Windows)
        return p
    if os.path.dirname(common) == common:  # only the filesystem root in common: keep it absolute
        return p
    return Path(os.path.relpath(p, b)).as_posix()


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # JSON's string escapes are TOML basic strings'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise AnatomeshError(f"cannot write {type(v).__name__} value {v!r} into a recipe")


if __name__ == "__main__":  # python -m anatomesh.app.recipe > table: the docs' settings table
    print(settings_table(), end="")
