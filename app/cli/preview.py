"""``anatomesh preview SCAN --out gallery.png``: one picture of small renders of the isosurface at
each named level (CT presets or histogram-derived levels, or ``--levels``), so a user picks an
isovalue by looking (:func:`anatomesh.app.pictures.gallery.gallery`)."""
from __future__ import annotations

import argparse
from pathlib import Path

from ...core.model.errors import AnatomeshError
from .common import EXIT_OK, TerminalProgress, add_input_args, path_arg


def add_parser(subs) -> argparse.ArgumentParser:
    p = subs.add_parser("preview", help="a PNG gallery of isosurfaces at named levels, to pick one by looking")
    add_input_args(p)
    p.add_argument("--out", required=True, help="the PNG to write")
    p.add_argument("--levels", nargs="+", metavar="LEVEL",
                   help="VALUE or NAME:VALUE items, e.g. skin:-500 bone:300 (default: CT presets in "
                        "HU, else levels between the histogram's peaks)")
    p.add_argument("--view", default="anterior", help="the side the pictures look from: anterior (default), posterior, left, right, "
                                                     "superior, inferior")
    p.add_argument("--size", default="256", help="pixels per picture (default 256)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing PNG")
    p.set_defaults(func=cmd_preview)
    return p


def cmd_preview(args) -> int:
    from ...core.export.common import refuse_overwrite  # speed: loaded for this command only
    from ...core.export.snapshot import VIEWS, write_png
    from ...core.io import load
    from ..pictures.gallery import gallery, parse_levels

    out = Path(args.out)
    if out.suffix.lower() != ".png":
        raise AnatomeshError("--out must name a .png file", out)
    try:
        tile = int(args.size)
    except ValueError:
        tile = 0
    if not 64 <= tile <= 2048:
        raise AnatomeshError(f"--size is the pixels per picture, 64..2048, got {args.size!r}")
    if args.view not in VIEWS:
        raise AnatomeshError(f"unknown --view {args.view!r}; use one of {', '.join(VIEWS)}")
    levels = parse_levels(args.levels) if args.levels else None
    refuse_overwrite([out], args.overwrite)
    vol = load(path_arg(args.path), series=args.series, volume_index=args.volume_index,
               labels=args.label_table, progress=TerminalProgress("reading"))
    sheet, info = gallery(vol, levels, tile=tile, view=args.view, progress=TerminalProgress("preview"))
    out.parent.mkdir(parents=True, exist_ok=True)
    write_png(sheet, out)
    shown = ", ".join(f"{i['name']} {i['value']:g} ({i['faces']:,} triangles)" for i in info)
    print(f"{out}: {len(info)} isosurfaces, {sheet.shape[1]}x{sheet.shape[0]} px: {shown}")
    return EXIT_OK
