"""What ``anatomesh inspect`` adds for preprocessing and isovalue guidance:
``--histogram FILE.png`` (the histogram with its labelled peaks and the chosen levels marked,
:mod:`anatomesh.app.pictures.histogram`; levels from ``--level`` or the presets of
:func:`anatomesh.app.pictures.gallery.preset_levels`) and hints (:mod:`anatomesh.app.flow.hints`)."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Dict

from ...core.model.errors import AnatomeshError
from ..flow.hints import hints


def add_extra_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--histogram", metavar="FILE.png",
                   help="also write the histogram as a picture: peaks labelled, levels marked")
    p.add_argument("--level", action="append", metavar="LEVEL",
                   help="a level to mark on the histogram picture: VALUE or NAME:VALUE (repeat; "
                        "default: the preset levels `anatomesh preview` shows)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing histogram PNG")


def extras(volume, facts: Dict, args) -> Dict:
    """``{"hints": [...]}`` and, with ``--histogram``, ``"histogram_png"`` (the picture written)."""
    out: Dict = {"hints": hints(volume)}
    if args.histogram:
        out.update(_histogram_png(volume, facts, args))
    return out


def _histogram_png(volume, facts: Dict, args) -> Dict:
    """Write ``--histogram``'s picture; ``{"histogram_png", "histogram_levels"}``."""
    from ...core.export.common import refuse_overwrite  # speed: loaded when asked for
    from ...core.export.snapshot import write_png
    from ...core.io.describe import looks_like_hounsfield
    from ..pictures.gallery import parse_levels, preset_levels
    from ..pictures.histogram import histogram_picture

    out: Dict = {}
    path = Path(args.histogram)
    if path.suffix.lower() != ".png":
        raise AnatomeshError("--histogram must name a .png file", path)
    if volume.is_label_map:
        raise AnatomeshError("--histogram draws the values of a scalar scan; this is a label map",
                             volume.meta.get("source"))
    refuse_overwrite([path], args.overwrite)
    levels = parse_levels(args.level) if args.level else preset_levels(volume)
    data = volume.data.ravel(order="K")
    sample = data[:: max(1, data.size // 4_000_000)]
    title = f"{Path(str(facts.get('path', 'scan'))).name}  {facts['modality']}  " \
            f"{'x'.join(str(s) for s in facts['shape'])}"
    picture, info = histogram_picture(sample, looks_like_hounsfield(sample),
                                      [(n, v) for n, v, _ in levels], title)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_png(picture, path)
    out["histogram_png"] = str(path)
    out["histogram_levels"] = info["levels"]
    return out
