"""``anatomesh mesh``: extract, smooth, decimate and write surfaces, with a JSON report.

Settings come from the flags, a recipe file (``--recipe FILE``, :mod:`anatomesh.app.recipe`), or
both (flags given on the command line override the file); :func:`anatomesh.app.run.run` does the
work.
"""
from __future__ import annotations

import argparse
import sys

from ...core.model.errors import AnatomeshError
from ..fit import fit_arg  # cut to fit
from ..recipe import FORMATS, Recipe, load_recipe
from .common import (EXIT_CHECK_FAILED, EXIT_OK, TerminalProgress, add_input_args, path_arg,
                     short_list, split_list)
from .web import add_distance_args, margins_arg
from . import preprocess_args  # --resample, --interpolate, --fuzzy, ...

#: flags that set the Recipe field of the same name as given
RECIPE_FLAGS = ("series", "volume_index", "label_table", "space", "cap", "keep_largest",
                "min_component_mm3", "smooth", "iterations", "lam", "mu", "max_deviation",
                "damping_distance", "staircase", "decimate", "target_faces", "max_error", "check",
                "profile", "min_wall", "min_gap", "report", "overwrite", "lod", "thicken", "clearance",
                "grid", "contours", "hollow", "drain_holes", "drain_diameter")


def add_parser(subs) -> argparse.ArgumentParser:
    m = subs.add_parser("mesh", help="extract surfaces and write mesh files + a JSON report",
                        description="Extract, smooth, decimate and write surfaces. Settings come from "
                                    "the flags and/or a recipe file (--recipe; flags override it).")
    add_input_args(m, required=False)
    m.add_argument("--recipe", metavar="FILE", help="TOML recipe with the settings (e.g. OUT/recipe.toml "
                                                    "of an earlier run); flags given here override it")
    m.add_argument("--out", help="output folder (required without a recipe)")
    _surface_args(m)
    _smoothing_args(m)
    _decimation_args(m)
    _print_args(m)
    add_distance_args(m)  # distance colouring, web page levels
    preprocess_args.add_arguments(m)
    m.add_argument("--report", help="report path (default OUT/report.json; recipe.toml is written beside it)")
    m.add_argument("--overwrite", action="store_true", default=None, help="replace existing output files")
    m.set_defaults(func=cmd_mesh)
    return m


def _surface_args(m) -> None:
    m.add_argument("--level", type=float, action="append", metavar="VALUE",
                   help="isovalue for a scalar scan (repeat for several surfaces)")
    m.add_argument("--labels", help="all (default), or values/names: 1,5,7 or liver,spleen")
    m.add_argument("--format", help="comma list of stl, ply, obj, 3mf, dicom, glb, blend, png, web (default "
                                    "stl); 3mf also writes one combined print file, dicom one Encapsulated "
                                    "STL object per surface in the source's study, glb one file with every "
                                    "surface, blend a Blender scene, png its Cycles render (need bpy), web a "
                                    "3D page OUT/web/index.html")
    m.add_argument("--contours", choices=("raster", "tile"),
                   help="RTSTRUCT contours to surfaces: raster (default: even-odd rasterisation, shape-based "
                        "interpolation, conforming extraction) or tile (direct tiling between adjacent contours)")
    m.add_argument("--space", choices=("RAS", "LPS"),
                   help="coordinate space of the written vertices (default RAS)")
    m.add_argument("--no-cap", dest="cap", action="store_false", default=None,
                   help="leave isosurfaces open where they leave the volume (default: capped, closed)")
    m.add_argument("--keep-largest", action="store_true", default=None,
                   help="keep only the largest component per surface")
    m.add_argument("--min-component", dest="min_component_mm3", type=float, metavar="MM3",
                   help="drop components smaller than this volume in mm³")


def _smoothing_args(m) -> None:
    m.add_argument("--smooth",
                   help="smoothing preset or filter: organ (default: Taubin kept inside each voxel cell, "
                        "volumes restored), light, strong, taubin, laplacian, hc, mean_curvature, "
                        "normal_mean, normal_median, none (raw surface)")
    m.add_argument("--iterations", type=int, help="smoothing iterations (overrides the preset)")
    m.add_argument("--lambda", dest="lam", type=float, help="smoothing step λ (overrides the preset)")
    m.add_argument("--mu", type=float, help="Taubin's negative step μ (overrides the preset)")
    m.add_argument("--max-deviation", type=float, metavar="MM",
                   help="no vertex moves further than this from the unsmoothed surface")
    m.add_argument("--damping-distance", type=float, metavar="MM",
                   help="smooth less where another structure is closer than this (Mönch et al. 2010)")
    m.add_argument("--staircase", choices=("auto", "on", "off"),
                   help="extra slice-axis smoothing for thick slices (auto: slice >= 1.5x in-plane)")


def _decimation_args(m) -> None:
    m.add_argument("--decimate", type=float, metavar="RATIO",
                   help="after smoothing, keep this fraction of the faces (0.1 = 10 %%); seams stay shared, "
                        "shells closed; the error in mm is measured and reported")
    m.add_argument("--target-faces", type=int, metavar="N", help="decimate to N faces in all")
    m.add_argument("--max-error", type=float, metavar="MM",
                   help="decimate as far as the surface stays within MM of the smoothed one; with "
                        "--decimate/--target-faces a cap on their error (default: one voxel)")
    m.add_argument("--lod", type=int, metavar="N",
                   help="also write N GLB levels of detail, <scan>_lod0.glb (finest) .. _lod{N-1}.glb, "
                        "each half the faces of the one before, from one progressive decimation run")


def _print_args(m) -> None:
    m.add_argument("--fuse", action="append", metavar="LABELS",
                   help="print fix: merge these labels (comma list of values/names) into one solid "
                        "before extraction; repeat for several groups")
    m.add_argument("--thicken", action="store_true", default=None,
                   help="print fix: grow parts thinner than the minimum wall (--min-wall or the "
                        "profile's) in the label map before extraction")
    m.add_argument("--clearance", type=float, metavar="MM",
                   help="print fix: pull touching parts apart by MM along their shared interfaces, "
                        "so separately printed parts fit together")
    hollow_args(m)
    connector_args(m)
    fit_args(m)  # cut to fit
    m.add_argument("--check", action="store_true", default=None,
                   help="run the 3D-print checks on the result (exit code 1 when one fails)")
    m.add_argument("--profile", choices=("fdm", "resin"), help="printer profile for --check (default fdm)")
    m.add_argument("--min-wall", type=float, metavar="MM", help="thinnest printable wall (overrides the profile)")
    m.add_argument("--min-gap", type=float, metavar="MM", help="narrowest gap that stays open (overrides the profile)")


def hollow_args(m) -> None:
    """``--hollow WALL_MM [--drain-holes N] [--drain-diameter MM]`` (mesh and check)."""
    m.add_argument("--hollow", type=float, metavar="WALL_MM",
                   help="print tool (resin/powder): hollow every part to a shell of this wall, with "
                        "drain holes at its lowest points (+z of the patient is up)")
    m.add_argument("--drain-holes", type=int, metavar="N", help="drain holes per cavity (default 2)")
    m.add_argument("--drain-diameter", type=float, metavar="MM",
                   help="drain hole diameter (default: the profile's, fdm 4 mm, resin 3 mm)")


def fit_args(m) -> None:
    """``--fit X,Y,Z [--fit-connectors]`` (mesh and check)."""
    m.add_argument("--fit", metavar="X,Y,Z",
                   help="print tool: cut every part too big for the printer's build volume (mm) into "
                        "pieces that fit, <part>_1, <part>_2, ... (fewest axis-aligned cuts, where the "
                        "cross-section is smallest)")
    m.add_argument("--fit-connectors", action="store_true", default=None,
                   help="with --fit: pins on one piece and pockets in the other across each cut")


def connector_args(m) -> None:
    """``--connectors A,B`` (repeat)."""
    m.add_argument("--connectors", action="append", metavar="A,B",
                   help="print tool: pins on part A and matching pockets in part B across their shared "
                        "interface (names or values; clearance from the profile); repeat for more pairs")


def _pair(text: str):
    parts = split_list(text)
    if len(parts) != 2:
        raise AnatomeshError(f"--connectors takes two parts, A,B; got {text!r}")
    return parts


def recipe_from_args(args) -> Recipe:
    """The Recipe of a ``mesh`` command line: the recipe file (if any), then every flag given."""
    recipe = load_recipe(args.recipe) if args.recipe else Recipe(out_dir="")
    if args.path:
        recipe.input = path_arg(args.path)
    if args.out is not None:
        recipe.out_dir = args.out
    if args.level:
        recipe.levels = list(args.level)
    if args.labels is not None:
        recipe.labels = split_list(args.labels) if args.labels.strip().lower() != "all" else "all"
    if args.format is not None:
        recipe.formats = _formats(args.format)
    if args.fuse:
        recipe.fuse = [split_list(g) for g in args.fuse]
    if args.connectors:
        recipe.connectors = [_pair(g) for g in args.connectors]
    if args.fit is not None:  # cut to fit
        recipe.fit = fit_arg(args.fit)
    if args.fit_connectors:
        recipe.fit_connectors = True
    targets = ("decimate", "target_faces", "max_error")
    if any(getattr(args, t) is not None for t in targets):  # a target given here replaces the file's
        for t in targets:
            setattr(recipe, t, None)
    for name in RECIPE_FLAGS:
        value = getattr(args, name)
        if value is not None:
            setattr(recipe, name, value)
    for name, value in (("distance_to", args.distance_to), ("margins", margins_arg(args.margins)),
                        ("web_levels", args.web_levels)):
        if value is not None:
            setattr(recipe, name, value)
    preprocess_args.apply(args, recipe)
    if not recipe.input:
        raise AnatomeshError("no input: give a scan path or a --recipe whose [input] has a path")
    if not recipe.out_dir:
        raise AnatomeshError("no output folder: give --out DIR (or a --recipe whose [output] has dir)")
    return recipe


def cmd_mesh(args) -> int:
    from ..run import run  # speed: the flow's modules load only for this command

    recipe = recipe_from_args(args)
    result = run(recipe, TerminalProgress("meshing"), keep_voxels=False)  # memory: one shot
    rep = result.report
    for note in rep.get("notes", []):  # segmentations: what was meshed, on which grid
        print(f"note: {note}", file=sys.stderr)
    for w in rep.get("warnings", []):
        print(f"warning: {w}", file=sys.stderr)
    n_closed = sum(1 for s in rep["surfaces"] if s["closed"])
    line = f"{len(result.surfaces)} surfaces ({n_closed} closed) in {recipe.space} mm"
    dec = rep.get("decimation")
    if dec:
        line += (f", decimated {dec['faces_before']} -> {dec['faces_after']} faces "
                 f"(max error {dec['hausdorff_mm']:.3g} mm)")
    for pre_line in preprocess_args.summary_lines(rep):
        print(pre_line)
    print(f"{line} -> {recipe.out_dir}; report {result.report_path}")
    check = rep.get("print_check")
    if check is None:
        return EXIT_OK
    name = check["profile"].get("name", recipe.profile)
    if check["passed"]:
        print(f"print check ({name}): passed")
        return EXIT_OK
    failed = [p["name"] for p in check["parts"] if not p["passed"]]
    fused = [f"{g['a']}+{g['b']}" for g in check["gaps"] if g.get("fuses")]
    what = [f"{len(failed)} part(s) fail {short_list(failed)}"] if failed else []
    what += [f"{len(fused)} pair(s) would fuse {short_list(fused)}"] if fused else []
    print(f"print check ({name}): FAILED, {'; '.join(what) or 'parts intersect'}; details in the "
          "report's print_check", file=sys.stderr)
    return EXIT_CHECK_FAILED


def _formats(text: str):
    fmts = [f.lower().lstrip(".") for f in split_list(text)]
    bad = [f for f in fmts if f not in FORMATS]
    if bad or not fmts:
        raise AnatomeshError(f"unknown --format {','.join(bad) or text!r}; use a comma list of {', '.join(FORMATS)}")
    return fmts
