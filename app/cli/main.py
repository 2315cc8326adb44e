"""The ``anatomesh`` command line: ``inspect``, ``mesh`` and ``check`` (in :mod:`.cli_check`).

``mesh`` takes its settings from flags, from a recipe file (``--recipe FILE``, see
:mod:`.recipe`), or both (flags given on the command line override the file).

Exit codes: 0 success, 1 a print check failed (``mesh --check``), 2 bad input (one line on
stderr, no traceback unless ``--debug``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from typing import List, Optional

from ...core.model.errors import AnatomeshError, Cancelled

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return args.func(args)
    except AnatomeshError as err:
        if args.debug:
            raise
        print(f"error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Cancelled:
        print("cancelled", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="anatomesh", description="Medical scans to surface meshes (mm).")
    p.add_argument("--debug", action="store_true", help="show tracebacks")
    subs = p.add_subparsers(dest="command")

    ins = subs.add_parser("inspect", help="describe a scan or label map before meshing")
    _input_args(ins)
    ins.add_argument("--json", action="store_true", help="print the facts as JSON")
    ins.add_argument("--debug", action="store_true", help=argparse.SUPPRESS)
    ins.set_defaults(func=cmd_inspect)

    m = subs.add_parser("mesh", help="extract surfaces and write mesh files + a JSON report",
                        description="Extract, smooth, decimate and write surfaces. Settings come from "
                                    "the flags and/or a recipe file (--recipe; flags override it).")
    _input_args(m, required=False)
    m.add_argument("--recipe", metavar="FILE", help="TOML recipe with the settings (e.g. OUT/recipe.toml "
                                                    "of an earlier run); flags given here override it")
    m.add_argument("--out", help="output folder (required without a recipe)")
    m.add_argument("--level", type=float, action="append", metavar="VALUE",
                   help="isovalue for a scalar scan (repeat for several surfaces)")
    m.add_argument("--labels", help="all (default), or values/names: 1,5,7 or liver,spleen")
    m.add_argument("--format", help="comma list of stl, ply, obj, 3mf, glb, blend, png (default stl); "
                                    "3mf also writes one combined print file, glb one file with every "
                                    "surface, blend a Blender scene, png its Cycles render (need bpy)")
    m.add_argument("--space", choices=("RAS", "LPS"),
                   help="coordinate space of the written vertices (default RAS)")
    m.add_argument("--no-cap", dest="cap", action="store_false", default=None,
                   help="leave isosurfaces open where they leave the volume (default: capped, closed)")
    m.add_argument("--keep-largest", action="store_true", default=None,
                   help="keep only the largest component per surface")
    m.add_argument("--min-component", dest="min_component_mm3", type=float, metavar="MM3",
                   help="drop components smaller than this volume in mm³")
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
    m.add_argument("--fuse", action="append", metavar="LABELS",
                   help="print fix: merge these labels (comma list of values/names) into one solid "
                        "before extraction; repeat for several groups")
    m.add_argument("--thicken", action="store_true", default=None,
                   help="print fix: grow parts thinner than the minimum wall (--min-wall or the "
                        "profile's) in the label map before extraction")
    m.add_argument("--clearance", type=float, metavar="MM",
                   help="print fix: pull touching parts apart by MM along their shared interfaces, "
                        "so separately printed parts fit together")
    m.add_argument("--check", action="store_true", default=None,
                   help="run the 3D-print checks on the result (exit code 1 when one fails)")
    m.add_argument("--profile", choices=("fdm", "resin"), help="printer profile for --check (default fdm)")
    m.add_argument("--min-wall", type=float, metavar="MM", help="thinnest printable wall (overrides the profile)")
    m.add_argument("--min-gap", type=float, metavar="MM", help="narrowest gap that stays open (overrides the profile)")
    m.add_argument("--report", help="report path (default OUT/report.json; recipe.toml is written beside it)")
    m.add_argument("--overwrite", action="store_true", default=None, help="replace existing output files")
    m.add_argument("--debug", action="store_true", help=argparse.SUPPRESS)
    m.set_defaults(func=cmd_mesh)

    from .check import add_parser as add_check
    add_check(subs)
    return p


def _input_args(sp: argparse.ArgumentParser, required: bool = True) -> None:
    sp.add_argument("path", nargs="+" if required else "*",
                    help="DICOM folder or files, .nii/.nii.gz, .nrrd/.nhdr/.seg.nrrd")
    sp.add_argument("--series", help="DICOM series: UID or number when a folder holds several")
    sp.add_argument("--volume", type=int, dest="volume_index", help="volume index of a 4D NIfTI")
    sp.add_argument("--label-table", help="label names/colours (TotalSegmentator JSON, Slicer .ctbl, ITK-SNAP)")


def _path_arg(paths: List[str]):
    return paths[0] if len(paths) == 1 else paths


def cmd_inspect(args) -> int:
    from ...core.io.describe import describe, format_text
    from ...core.io import load

    vol = load(_path_arg(args.path), series=args.series, volume_index=args.volume_index,
               labels=args.label_table, progress=TerminalProgress("reading"))
    facts = describe(vol)
    facts["path"] = [str(p) for p in args.path] if len(args.path) > 1 else str(args.path[0])
    print(json.dumps(facts, indent=2) if args.json else format_text(facts))
    return EXIT_OK


#: ``mesh`` flags that set a Recipe field of the same name as given
_RECIPE_FLAGS = ("series", "volume_index", "label_table", "space", "cap", "keep_largest",
                 "min_component_mm3", "smooth", "iterations", "lam", "mu", "max_deviation",
                 "damping_distance", "staircase", "decimate", "target_faces", "max_error", "check",
                 "profile", "min_wall", "min_gap", "report", "overwrite", "lod", "thicken", "clearance")


def recipe_from_args(args):
    """The Recipe of a ``mesh`` command line: the recipe file (if any), then every flag given."""
    from ..run import Recipe

    if args.recipe:
        from ..recipe import load_recipe

        recipe = load_recipe(args.recipe)
    else:
        recipe = Recipe(out_dir="")
    if args.path:
        recipe.input = _path_arg(args.path)
    if args.out is not None:
        recipe.out_dir = args.out
    if args.level:
        recipe.levels = list(args.level)
    if args.labels is not None:
        recipe.labels = _split(args.labels) if args.labels.strip().lower() != "all" else "all"
    if args.format is not None:
        recipe.formats = _formats(args.format)
    if args.fuse:
        recipe.fuse = [_split(g) for g in args.fuse]
    targets = ("decimate", "target_faces", "max_error")
    if any(getattr(args, t) is not None for t in targets):  # a target given here replaces the file's
        for t in targets:
            setattr(recipe, t, None)
    for name in _RECIPE_FLAGS:
        value = getattr(args, name)
        if value is not None:
            setattr(recipe, name, value)
    if not recipe.input:
        raise AnatomeshError("no input: give a scan path or a --recipe whose [input] has a path")
    if not recipe.out_dir:
        raise AnatomeshError("no output folder: give --out DIR (or a --recipe whose [output] has dir)")
    return recipe


def cmd_mesh(args) -> int:
    from ..run import run

    recipe = recipe_from_args(args)
    result = run(recipe, TerminalProgress("meshing"))
    rep = result.report
    for w in rep.get("warnings", []):
        print(f"warning: {w}", file=sys.stderr)
    n_closed = sum(1 for s in rep["surfaces"] if s["closed"])
    line = f"{len(result.surfaces)} surfaces ({n_closed} closed) in {recipe.space} mm"
    dec = rep.get("decimation")
    if dec:
        line += (f", decimated {dec['faces_before']} -> {dec['faces_after']} faces "
                 f"(max error {dec['hausdorff_mm']:.3g} mm)")
    print(f"{line} -> {recipe.out_dir}; report {result.report_path}")
    check = rep.get("print_check")
    if check is not None:
        failed = [p["name"] for p in check["parts"] if not p["passed"]]
        fused = [f"{g['a']}+{g['b']}" for g in check["gaps"] if g.get("fuses")]
        if check["passed"]:
            print(f"print check ({check['profile'].get('name', recipe.profile)}): passed")
        else:
            what = [f"{len(failed)} part(s) fail {_short(failed)}"] if failed else []
            what += [f"{len(fused)} pair(s) would fuse {_short(fused)}"] if fused else []
            print(f"print check ({check['profile'].get('name', recipe.profile)}): FAILED, "
                  f"{'; '.join(what) or 'parts intersect'}; details in the report's print_check",
                  file=sys.stderr)
            return EXIT_CHECK_FAILED
    return EXIT_OK


def _short(names: List[str], n: int = 4) -> str:
    if not names:
        return ""
    return "(" + ", ".join(names[:n]) + (f", +{len(names) - n} more" if len(names) > n else "") + ")"


def _split(text: str) -> List[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _formats(text: str) -> List[str]:
    fmts = [f.lower().lstrip(".") for f in _split(text)]
    from ..run import FORMATS
    bad = [f for f in fmts if f not in FORMATS]
    if bad or not fmts:
        raise AnatomeshError(f"unknown --format {','.join(bad) or text!r}; use a comma list of {', '.join(FORMATS)}")
    return fmts


class TerminalProgress:
    """A one-line progress bar on stderr when it is a terminal; silent otherwise."""

    def __init__(self, title: str, width: int = 30):
        self.title, self.width = title, width
        self.enabled = sys.stderr.isatty()
        self.t0 = time.perf_counter()
        self._last = -1

    def __call__(self, fraction: float, text: str = "") -> None:
        if not self.enabled:
            return
        filled = int(round(self.width * fraction))
        key = (filled, text)
        if key == self._last:
            return
        self._last = key
        bar = "#" * filled + "-" * (self.width - filled)
        sys.stderr.write(f"\r{self.title} [{bar}] {fraction * 100:5.1f}% {time.perf_counter() - self.t0:6.1f}s "
                         f"{text[:40]:<40}")
        if fraction >= 1.0:
            sys.stderr.write("\n")
        sys.stderr.flush()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
