"""``anatomesh web``: a self-contained 3D page of the surfaces of earlier runs or of mesh files.

One model per ``report.json`` given (several reports: one page to switch between them, e.g.
resection variants; structures they share are stored once), plus one model of all mesh files
given (STL, PLY, OBJ, GLB). The page (:mod:`anatomesh.app.web.page`) opens from the folder with a
double-click. The distance options are shared with ``anatomesh mesh``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..flow.recipe import Recipe
from ..flow.settings import check_values, read_number_lists
from .common import EXIT_OK, TerminalProgress, write_json
from .settings_args import add_setting_args, flag_values


#: the distance colouring and page settings (``mesh`` and ``web``), flags made from their definitions
DISTANCE_FLAGS = ("distance_to", "margins", "web_levels", "web_views")


def add_distance_args(p: argparse.ArgumentParser) -> None:
    """``--distance-to``, ``--margins``, ``--web-levels`` and ``--web-views`` (``mesh`` and ``web``)."""
    add_setting_args(p, DISTANCE_FLAGS)


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
    from ..web.page import write_page
    from ..web.models import models_of_inputs
    from ..web.views import read_views

    settings = Recipe(**flag_values(args, DISTANCE_FLAGS))  # checked as a run checks them
    read_number_lists(settings)
    check_values(settings)
    views = read_views(settings.web_views) if settings.web_views else []
    models = models_of_inputs(args.inputs, n_levels=settings.web_levels, distance_to=settings.distance_to,
                              margins=settings.margins, progress=TerminalProgress("levels"))
    summary = write_page(models, args.out, title=args.title or "", overwrite=args.overwrite, views=views)
    if args.report:
        write_json(summary, args.report)
    sizes = ", ".join(f"{lv['file']} {lv['triangles']:,} triangles {lv['bytes'] / 1e6:.2f} MB"
                      for lv in summary["levels"])
    print(f"{summary['structures']} structures in {len(models)} model(s) -> "
          f"{Path(summary['page'])}; {summary['total_bytes'] / 1e6:.2f} MB in all ({sizes})")
    return EXIT_OK
