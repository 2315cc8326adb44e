"""``anatomesh mesh``: extract, smooth, decimate and write surfaces, with a JSON report.

Settings come from the flags, a recipe file (``--recipe FILE``, :mod:`anatomesh.app.flow.recipe`), or
both (flags given on the command line override the file); :func:`anatomesh.app.flow.run.run` does the
work.
"""
from __future__ import annotations

import argparse
import sys

from ...core.model.errors import AnatomeshError
from ..flow.fit import fit_arg  # cut to fit
from ..flow.recipe import FORMATS, Recipe, load_recipe
from .common import (EXIT_CHECK_FAILED, EXIT_OK, TerminalProgress, add_input_args, path_arg,
                     short_list, split_list)
from .web import DISTANCE_FLAGS, add_distance_args
from . import preprocess_summary
from .settings_args import add_setting_args, flag_values

#: flags made from the recipe's field definitions, set on the Recipe field of the same name as given
SURFACE_FLAGS = ("contours", "space", "cap", "keep_largest", "min_component_mm3")
SMOOTHING_FLAGS = ("smooth", "iterations", "lam", "mu", "max_deviation", "damping_distance", "staircase")
DECIMATION_FLAGS = ("decimate", "target_faces", "max_error", "lod")
PRINT_FLAGS = ("thicken", "clearance", "check", "profile", "min_wall", "min_gap")
HOLLOW_FLAGS = ("hollow", "drain_holes", "drain_diameter")
OUTPUT_FLAGS = ("report", "overwrite", "style", "views", "turntable", "labels_on", "light")
PREPROCESS_FLAGS = ("resample", "resample_method", "roi", "smooth_volume", "interpolate", "fuzzy_boundary",
                    "fill_cavities", "close_handles", "fuzzy", "precise", "difference_colors")
#: flags of add_input_args (shared with inspect) that set the Recipe field of the same name
INPUT_FLAGS = ("series", "volume_index", "label_table", "grid")
RECIPE_FLAGS = (INPUT_FLAGS + SURFACE_FLAGS + SMOOTHING_FLAGS + DECIMATION_FLAGS + PRINT_FLAGS
                + HOLLOW_FLAGS + OUTPUT_FLAGS + PREPROCESS_FLAGS + DISTANCE_FLAGS)


def add_parser(subs) -> argparse.ArgumentParser:
    m = subs.add_parser("mesh", help="extract surfaces and write mesh files + a JSON report",
                        description="Extract, smooth, decimate and write surfaces. Settings come from "
                                    "the flags and/or a recipe file (--recipe; flags override it).")
    add_input_args(m, required=False)
    m.add_argument("--recipe", metavar="FILE", help="TOML recipe with the settings (e.g. OUT/recipe.toml "
                                                    "of an earlier run); flags given here override it")
    m.add_argument("--out", help="output folder (required without a recipe)")
    _surface_args(m)
    add_setting_args(m, SMOOTHING_FLAGS)
    add_setting_args(m, DECIMATION_FLAGS)
    _print_args(m)
    add_distance_args(m)  # distance colouring, web page levels
    add_setting_args(m.add_argument_group("preprocessing (before and around extraction; each step's "
                                          "effect on the surface is measured and reported)"), PREPROCESS_FLAGS)
    add_setting_args(m, OUTPUT_FLAGS)
    m.set_defaults(func=cmd_mesh)
    return m


def _surface_args(m) -> None:
    m.add_argument("--level", action="append", metavar="[NAME:]VALUE",
                   help="isovalue for a scalar scan, optionally named (bone:300); repeat for several surfaces")
    m.add_argument("--labels", help="all (default), or values/names: 1,5,7 or liver,spleen")
    m.add_argument("--format", help="comma list of stl, ply, obj, 3mf, dicom, glb, blend, png, web (default "
                                    "stl); 3mf also writes one combined print file, dicom one Encapsulated "
                                    "STL object per surface in the source's study, glb one file with every "
                                    "surface, blend a Blender scene, png its Cycles render (need bpy), web a "
                                    "3D page OUT/web/index.html")
    add_setting_args(m, SURFACE_FLAGS)


def _print_args(m) -> None:
    m.add_argument("--fuse", action="append", metavar="LABELS",
                   help="print fix: merge these labels (comma list of values/names) into one solid "
                        "before extraction; repeat for several groups")
    hollow_args(m)
    connector_args(m)
    fit_args(m)  # cut to fit
    add_setting_args(m, PRINT_FLAGS)


def hollow_args(m) -> None:
    """``--hollow WALL_MM [--drain-holes N] [--drain-diameter MM]`` (mesh and check)."""
    add_setting_args(m, HOLLOW_FLAGS)


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
        recipe.levels, recipe.level_names = _levels(args.level)
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
    for name, value in flag_values(args, RECIPE_FLAGS).items():
        setattr(recipe, name, value)
    if not recipe.input:
        raise AnatomeshError("no input: give a scan path or a --recipe whose [input] has a path")
    if not recipe.out_dir:
        raise AnatomeshError("no output folder: give --out DIR (or a --recipe whose [output] has dir)")
    return recipe


def _levels(items):
    """``--level`` values (``300`` or ``bone:300``) → the levels and, when any is named, their
    names (an unnamed one keeps the default name)."""
    from ..pictures.gallery import parse_levels

    parts = [p.strip() for item in items for p in str(item).split(",") if p.strip()]
    named = [":" in p or "=" in p for p in parts]
    levels = parse_levels(parts, "--level")
    if not any(named):
        return [v for _, v, _ in levels], []
    names = [name if n else f"isosurface {v:g}" for (name, v, _), n in zip(levels, named)]
    return [v for _, v, _ in levels], names


def cmd_mesh(args) -> int:
    from ..flow.run import run

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
    for pre_line in preprocess_summary.summary_lines(rep):
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
