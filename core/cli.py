"""The ``anatomesh`` command line: ``inspect``, ``mesh`` and ``check`` (in :mod:`.cli_check`).

Exit codes: 0 success, 2 bad input (one line on stderr, no traceback unless ``--debug``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from typing import List, Optional

from .errors import AnatomeshError, Cancelled

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

    m = subs.add_parser("mesh", help="extract surfaces and write mesh files + a JSON report")
    _input_args(m)
    m.add_argument("--out", required=True, help="output folder")
    m.add_argument("--level", type=float, action="append", default=[], metavar="VALUE",
                   help="isovalue for a scalar scan (repeat for several surfaces)")
    m.add_argument("--labels", default="all", help="all, or values/names: 1,5,7 or liver,spleen")
    m.add_argument("--format", default="stl", help="comma list of stl, ply, obj (default stl)")
    m.add_argument("--space", choices=("RAS", "LPS"), default="RAS",
                   help="coordinate space of the written vertices (default RAS)")
    m.add_argument("--no-cap", dest="cap", action="store_false",
                   help="leave isosurfaces open where they leave the volume (default: capped, closed)")
    m.add_argument("--keep-largest", action="store_true", help="keep only the largest component per surface")
    m.add_argument("--min-component", type=float, default=0.0, metavar="MM3",
                   help="drop components smaller than this volume in mm³")
    m.add_argument("--smooth", default="organ",
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
    m.add_argument("--staircase", choices=("auto", "on", "off"), default="auto",
                   help="extra slice-axis smoothing for thick slices (auto: slice >= 1.5x in-plane)")
    m.add_argument("--report", help="report path (default OUT/report.json)")
    m.add_argument("--overwrite", action="store_true", help="replace existing output files")
    m.add_argument("--debug", action="store_true", help=argparse.SUPPRESS)
    m.set_defaults(func=cmd_mesh)

    from .cli_check import add_parser as add_check
    add_check(subs)
    return p


def _input_args(sp: argparse.ArgumentParser) -> None:
    sp.add_argument("path", nargs="+", help="DICOM folder or files, .nii/.nii.gz, .nrrd/.nhdr/.seg.nrrd")
    sp.add_argument("--series", help="DICOM series: UID or number when a folder holds several")
    sp.add_argument("--volume", type=int, dest="volume_index", help="volume index of a 4D NIfTI")
    sp.add_argument("--label-table", help="label names/colours (TotalSegmentator JSON, Slicer .ctbl, ITK-SNAP)")


def _path_arg(paths: List[str]):
    return paths[0] if len(paths) == 1 else paths


def cmd_inspect(args) -> int:
    from .inspect import describe, format_text
    from .io import load

    vol = load(_path_arg(args.path), series=args.series, volume_index=args.volume_index,
               labels=args.label_table, progress=TerminalProgress("reading"))
    facts = describe(vol)
    facts["path"] = [str(p) for p in args.path] if len(args.path) > 1 else str(args.path[0])
    print(json.dumps(facts, indent=2) if args.json else format_text(facts))
    return EXIT_OK


def cmd_mesh(args) -> int:
    from .pipeline import Recipe, run

    recipe = Recipe(
        input=_path_arg(args.path), out_dir=args.out, series=args.series, volume_index=args.volume_index,
        label_table=args.label_table, labels=_split(args.labels) if args.labels != "all" else "all",
        levels=args.level, space=args.space, cap=args.cap, keep_largest=args.keep_largest,
        min_component_mm3=args.min_component, smooth=args.smooth, iterations=args.iterations,
        lam=args.lam, mu=args.mu, max_deviation=args.max_deviation,
        damping_distance=args.damping_distance, staircase=args.staircase,
        formats=_formats(args.format), report=args.report, overwrite=args.overwrite)
    result = run(recipe, TerminalProgress("meshing"))
    for w in result.report.get("warnings", []):
        print(f"warning: {w}", file=sys.stderr)
    n_closed = sum(1 for s in result.report["surfaces"] if s["closed"])
    print(f"{len(result.surfaces)} surfaces ({n_closed} closed) in {recipe.space} mm -> {args.out}; "
          f"report {result.report_path}")
    return EXIT_OK


def _split(text: str) -> List[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _formats(text: str) -> List[str]:
    fmts = [f.lower() for f in _split(text)]
    from .export import FORMATS
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
