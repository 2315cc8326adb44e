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
from .preprocess_settings import KEYS as PREPROCESS_KEYS, check_preprocess  # preprocessing
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

    input: Union[str, List[str]] = ""
    out_dir: str = "out"
    series: Optional[str] = None
    volume_index: Optional[int] = None
    label_table: Optional[str] = None
    labels: Union[str, List[Union[int, str]]] = "all"
    levels: List[float] = field(default_factory=list)
    space: str = "RAS"
    cap: bool = True
    keep_largest: bool = False
    min_component_mm3: float = 0.0
    smooth: str = SMOOTH_DEFAULT
    iterations: Optional[int] = None
    lam: Optional[float] = None
    mu: Optional[float] = None
    max_deviation: Optional[float] = None
    damping_distance: Optional[float] = None
    staircase: str = "auto"
    decimate: Optional[float] = None
    target_faces: Optional[int] = None
    max_error: Optional[float] = None
    check: bool = False
    profile: str = "fdm"
    min_wall: Optional[float] = None
    min_gap: Optional[float] = None
    fuse: List[List[Union[int, str]]] = field(default_factory=list)
    thicken: bool = False
    clearance: Optional[float] = None
    # printable-part tools: hollow to this wall (mm) with drain holes
    hollow: Optional[float] = None
    drain_holes: int = 2
    drain_diameter: Optional[float] = None
    connectors: List[List[Union[int, str]]] = field(default_factory=list)
    # cut to fit the build volume [x, y, z] mm, pins across the cuts
    fit: Optional[List[float]] = None
    fit_connectors: bool = False
    formats: List[str] = field(default_factory=lambda: ["stl"])
    render_samples: int = 32
    render_size: List[int] = field(default_factory=lambda: [960, 540])
    lod: int = 0
    report: Optional[str] = None
    overwrite: bool = False
    # distance colouring and the web page
    distance_to: Optional[Union[int, str]] = None
    margins: List[float] = field(default_factory=lambda: [2.0, 5.0, 10.0])
    web_levels: int = 2
    # segmentations
    grid: Optional[str] = None
    contours: str = CONTOURS_RASTER
    # -- preprocessing before and around extraction (see app/preprocess_settings.py) --
    resample: Optional[List[float]] = None
    resample_method: str = "linear"
    roi: Optional[List[float]] = None
    smooth_volume: Optional[str] = None
    interpolate: bool = False
    fuzzy_boundary: bool = False
    fill_cavities: bool = False
    close_handles: Optional[float] = None
    fuzzy: Optional[List[float]] = None
    precise: bool = False
    difference_colors: bool = False

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


#: TOML section → {TOML key: Recipe field}
SECTIONS: Dict[str, Dict[str, str]] = {
    "input": {"path": "input", "series": "series", "volume": "volume_index",
              "label_table": "label_table", "labels": "labels", "levels": "levels", "space": "space",
              "grid": "grid", "contours": "contours"},
    "preprocess": {k: k for k in PREPROCESS_KEYS},
    "surfaces": {"cap": "cap", "keep_largest": "keep_largest", "min_component_mm3": "min_component_mm3"},
    "smoothing": {"method": "smooth", "iterations": "iterations", "lambda": "lam", "mu": "mu",
                  "max_deviation_mm": "max_deviation", "damping_distance_mm": "damping_distance",
                  "staircase": "staircase"},
    "decimation": {"ratio": "decimate", "target_faces": "target_faces", "max_error_mm": "max_error"},
    "check": {"enabled": "check", "profile": "profile", "min_wall_mm": "min_wall", "min_gap_mm": "min_gap",
              "fuse": "fuse", "thicken": "thicken", "clearance_mm": "clearance",
              "hollow_mm": "hollow", "drain_holes": "drain_holes", "drain_diameter_mm": "drain_diameter",
              "connectors": "connectors"},
    "output": {"dir": "out_dir", "formats": "formats", "report": "report", "overwrite": "overwrite",
               "render_samples": "render_samples", "render_size": "render_size", "lod": "lod"},
}
# cut to fit
SECTIONS["check"].update(fit_mm="fit", fit_connectors="fit_connectors")
# distance colouring and the web page
SECTIONS["distance"] = {"to": "distance_to", "margins_mm": "margins"}
SECTIONS["web"] = {"levels": "web_levels"}
#: a comment written above each section
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
#: Recipe fields holding paths (resolved against the recipe's folder)
PATH_FIELDS = ("input", "label_table", "out_dir", "report")

_NUMBER = "a number"
#: Recipe field → (check, what is allowed), for the one-line type errors
_TYPES = {
    "input": (lambda v: isinstance(v, str) or (isinstance(v, list) and v and all(isinstance(x, str) for x in v)),
              "a path or a list of paths"),
    "series": (lambda v: isinstance(v, (str, int)) and not isinstance(v, bool), "a series UID or number"),
    "volume_index": (lambda v: _is_int(v), "a whole number"),
    "label_table": (lambda v: isinstance(v, str), "a path"),
    "labels": (lambda v: v == "all" or (isinstance(v, list) and all(
        isinstance(x, str) or _is_int(x) for x in v)), "\"all\" or a list of label values/names"),
    "levels": (lambda v: isinstance(v, list) and all(_is_number(x) for x in v), "a list of numbers"),
    "space": (lambda v: isinstance(v, str), "\"RAS\" or \"LPS\""),
    "grid": (lambda v: isinstance(v, str), "a mask name, \"image\" or \"native\""),
    "contours": (lambda v: isinstance(v, str), "\"raster\" or \"tile\""),
    "cap": (lambda v: isinstance(v, bool), "true or false"),
    "keep_largest": (lambda v: isinstance(v, bool), "true or false"),
    "min_component_mm3": (lambda v: _is_number(v), _NUMBER),
    "smooth": (lambda v: isinstance(v, str), "a smoothing preset or method name"),
    "iterations": (lambda v: _is_int(v), "a whole number"),
    "lam": (lambda v: _is_number(v), _NUMBER),
    "mu": (lambda v: _is_number(v), _NUMBER),
    "max_deviation": (lambda v: _is_number(v), _NUMBER),
    "damping_distance": (lambda v: _is_number(v), _NUMBER),
    "staircase": (lambda v: isinstance(v, str), "\"auto\", \"on\" or \"off\""),
    "decimate": (lambda v: _is_number(v), "a number in (0, 1]"),
    "target_faces": (lambda v: _is_int(v), "a whole number"),
    "max_error": (lambda v: _is_number(v), _NUMBER),
    "check": (lambda v: isinstance(v, bool), "true or false"),
    "profile": (lambda v: isinstance(v, str), "\"fdm\" or \"resin\""),
    "min_wall": (lambda v: _is_number(v), _NUMBER),
    "min_gap": (lambda v: _is_number(v), _NUMBER),
    "fuse": (lambda v: isinstance(v, list) and all(isinstance(g, list) and all(
        isinstance(x, str) or _is_int(x) for x in g) for g in v), "a list of label groups, e.g. [[\"liver\", \"spleen\"]]"),
    "thicken": (lambda v: isinstance(v, bool), "true or false"),
    "clearance": (lambda v: _is_number(v), _NUMBER),
    "hollow": (lambda v: _is_number(v), _NUMBER),
    "drain_holes": (lambda v: _is_int(v), "a whole number"),
    "drain_diameter": (lambda v: _is_number(v), _NUMBER),
    "connectors": (lambda v: isinstance(v, list) and all(isinstance(g, list) and len(g) == 2 and all(
        isinstance(x, str) or _is_int(x) for x in g) for g in v), "a list of label pairs, e.g. [[\"liver\", \"stomach\"]]"),
    "out_dir": (lambda v: isinstance(v, str), "a folder path"),
    "formats": (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), "a list of format names"),
    "report": (lambda v: isinstance(v, str), "a file path"),
    "overwrite": (lambda v: isinstance(v, bool), "true or false"),
    "render_samples": (lambda v: _is_int(v), "a whole number"),
    "lod": (lambda v: _is_int(v), "a whole number (GLB levels of detail, 0: none)"),
    "render_size": (lambda v: isinstance(v, list) and len(v) == 2 and all(_is_int(x) for x in v),
                    "[width, height] in pixels"),
    # preprocessing
    "resample": (lambda v: _is_number(v) or (isinstance(v, list) and len(v) in (1, 3) and all(_is_number(x) for x in v)),
                 "a voxel size in mm or [x, y, z]"),
    "resample_method": (lambda v: isinstance(v, str), "\"linear\", \"cubic\" or \"lanczos\""),
    "roi": (lambda v: isinstance(v, list) and len(v) == 6 and all(_is_number(x) for x in v),
            "[x0, y0, z0, x1, y1, z1] in mm"),
    "smooth_volume": (lambda v: isinstance(v, str), "\"gaussian:SIGMA_MM\", \"median:SIZE_MM\" or \"diffusion:ITERATIONS\""),
    "interpolate": (lambda v: isinstance(v, bool), "true or false"),
    "fuzzy_boundary": (lambda v: isinstance(v, bool), "true or false"),
    "fill_cavities": (lambda v: isinstance(v, bool), "true or false"),
    "close_handles": (lambda v: _is_number(v), "a size in mm"),
    "fuzzy": (lambda v: isinstance(v, list) and len(v) in (2, 3) and all(_is_number(x) for x in v),
              "[I1, I2] or [I1, I2, N]"),
    "precise": (lambda v: isinstance(v, bool), "true or false"),
    "difference_colors": (lambda v: isinstance(v, bool), "true or false"),
}
# cut to fit
_TYPES["fit"] = (lambda v: isinstance(v, list) and len(v) == 3 and all(_is_number(x) for x in v),
                 "the build volume [x, y, z] in mm")
_TYPES["fit_connectors"] = (lambda v: isinstance(v, bool), "true or false")
# distance colouring and the web page
_TYPES["distance_to"] = (lambda v: isinstance(v, str) or _is_int(v), "a label name or value")
_TYPES["margins"] = (lambda v: isinstance(v, list) and all(_is_number(x) for x in v),
                     "a list of distances in mm, e.g. [2, 5, 10]")
_TYPES["web_levels"] = (lambda v: _is_int(v), "a whole number (1..4)")
_FLOAT_FIELDS = {"min_component_mm3", "lam", "mu", "max_deviation", "damping_distance", "decimate",
                 "max_error", "min_wall", "min_gap", "clearance", "hollow", "drain_diameter",
                 "close_handles"}


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


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


def recipe_from_text(text: str, base=None, source=None) -> Recipe:
    """:func:`load_recipe` on TOML text; relative paths resolve against ``base`` (if given)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise AnatomeshError(f"not valid TOML ({exc}); fix the recipe file", source) from None
    values = {}
    for section, body in doc.items():
        keys = SECTIONS.get(section)
        if keys is None:
            raise AnatomeshError(f"unknown recipe section [{section}]; allowed sections: "
                                 f"{', '.join(SECTIONS)}", source)
        if not isinstance(body, dict):
            raise AnatomeshError(f"{section} must be a [{section}] section with keys "
                                 f"{', '.join(keys)}", source)
        for key, value in body.items():
            name = keys.get(key)
            if name is None:
                raise AnatomeshError(f"unknown key {key!r} in [{section}]; allowed keys: "
                                     f"{', '.join(keys)}", source)
            ok, allowed = _TYPES[name]
            if not ok(value):
                raise AnatomeshError(f"[{section}] {key} must be {allowed}, got {value!r}", source)
            if name in _FLOAT_FIELDS:
                value = float(value)
            if name in ("levels", "margins", "fit"):
                value = [float(x) for x in value]
            if name == "series":
                value = str(value)
            values[name] = value
    if base is not None:
        for name in PATH_FIELDS:
            if values.get(name):
                values[name] = _resolve(values[name], Path(base))
    return Recipe(**values)


def _resolve(value, base: Path):
    if isinstance(value, list):
        return [_resolve(v, base) for v in value]
    p = Path(os.path.expanduser(value))
    return str(p if p.is_absolute() else Path(os.path.abspath(base / p)))


# ---------------------------------------------------------------------------------------------
def dump_recipe(recipe: Recipe, base=None) -> str:
    """The recipe as TOML text (sections as in :data:`SECTIONS`; settings that are None left out).

    With ``base`` (the folder the file will be written to), paths are written relative to it, so
    a folder holding a recipe and its scan can be moved as a whole; :func:`load_recipe` of the
    written file gives back an equal :class:`Recipe` (paths absolute).
    """
    values = dataclasses.asdict(recipe)
    if base is not None:
        for name in PATH_FIELDS:
            if values.get(name):
                values[name] = _relative(values[name], Path(base))
    lines = ["# Anatomesh recipe: run it with `anatomesh mesh --recipe THIS_FILE`",
             "# (command-line flags override it; relative paths are relative to this file)"]
    for section, keys in SECTIONS.items():
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
