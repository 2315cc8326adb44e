"""``anatomesh web``: a self-contained 3D page of the surfaces of earlier runs or of mesh files.

One model per ``report.json`` given (several reports: one page to switch between them, e.g.
resection variants; structures they share are stored once), plus one model of all mesh files
given (STL, PLY, OBJ, GLB). The page (:mod:`anatomesh.app.web`) opens from the folder with a
double-click. The distance options are shared with ``anatomesh mesh``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ...core.model.errors import AnatomeshError
from .common import EXIT_OK, TerminalProgress, split_list, write_json


def add_distance_args(p: argparse.ArgumentParser) -> None:
    """``--distance-to``, ``--margins`` and ``--web-levels`` (``mesh`` and ``web``)."""
    p.add_argument("--distance-to", metavar="LABEL",
                   help="colour every other surface by its distance to this structure (name or value)")
    p.add_argument("--margins", metavar="MM,MM,MM",
                   help="safety margins for --distance-to, coloured red, yellow, green (default 2,5,10)")
    p.add_argument("--web-levels", type=int, metavar="N",
                   help="levels of detail of the web page, the coarsest shown first (1..4, default 2)")


def margins_arg(text):
    """``"2,5,10"`` → ``[2.0, 5.0, 10.0]`` (None stays None)."""
    if text is None:
        return None
    try:
        return [float(x) for x in split_list(text)]
    except ValueError:
        raise AnatomeshError(f"--margins must be distances in mm, e.g. 2,5,10; got {text!r}") from None


def add_parser(subs) -> argparse.ArgumentParser:
    w = subs.add_parser("web", help="write a self-contained 3D page (index.html) of reports or mesh files",
                        description="Write a folder with index.html that shows the surfaces in any "
                                    "web browser, offline (double-click it, or serve the folder).")
    w.add_argument("inputs", nargs="+", metavar="REPORT_OR_FILE",
                   help="report.json of `anatomesh mesh` (one model each) or mesh files (stl, ply, obj, glb)")
    w.add_argument("--out", required=True, help="output folder of the page")
    w.add_argument("--title", help="title of the page (default: the first model's name)")
    add_distance_args(w)
    w.add_argument("--report", help="write the page's summary (sizes, triangles per level) to this JSON file")
    w.add_argument("--overwrite", action="store_true", help="replace an existing page")
    w.set_defaults(func=cmd_web)
    return w


def cmd_web(args) -> int:
    from ..web import write_page  # speed: the page's modules load for this command only
    from ..web_models import models_of_inputs

    models = models_of_inputs(args.inputs, n_levels=2 if args.web_levels is None else args.web_levels,
                              distance_to=args.distance_to, margins=margins_arg(args.margins),
                              progress=TerminalProgress("levels"))
    summary = write_page(models, args.out, title=args.title or "", overwrite=args.overwrite)
    if args.report:
        write_json(summary, args.report)
    sizes = ", ".join(f"{lv['file']} {lv['triangles']:,} triangles {lv['bytes'] / 1e6:.2f} MB"
                      for lv in summary["levels"])
    print(f"{summary['structures']} structures in {len(models)} model(s) -> "
          f"{Path(summary['page'])}; {summary['total_bytes'] / 1e6:.2f} MB in all ({sizes})")
    return EXIT_OK
