"""``anatomesh inspect PATH``: what a scan or label map is, before meshing it.

Prints format, modality, shape, spacing, orientation, the voxel → mm affine, the value range, a
histogram with its peaks (tissues for CT) and, for label maps, each label's voxels and volume
(:func:`anatomesh.core.io.describe.describe`); ``--json`` prints the same facts as JSON.
"""
from __future__ import annotations

import argparse
import json
from typing import Dict, List

import numpy as np

from ...core.io import load
from ...core.io.describe import describe
from .common import EXIT_OK, TerminalProgress, add_input_args, path_arg
from .inspect_extras import add_extra_args, extras  # --histogram PNG, hints


def add_parser(subs) -> argparse.ArgumentParser:
    p = subs.add_parser("inspect", help="describe a scan or label map before meshing")
    add_input_args(p)
    p.add_argument("--json", action="store_true", help="print the facts as JSON")
    add_extra_args(p)
    p.set_defaults(func=cmd_inspect)
    return p


def cmd_inspect(args) -> int:
    contents = dicom_contents(args.path)  # segmentations: series and SEG/RTSTRUCT objects
    if contents and args.series is None and sum(e["kind"] != "image" for e in contents) > 1:
        facts = {"path": str(args.path[0]), "dicom_contents": contents}
        print(json.dumps(facts, indent=2) if args.json else "\n".join(
            _segmentation_lines(facts) + ["(several segmentation objects: add --series N for the details of one)"]))
        return EXIT_OK
    vol = load(path_arg(args.path), series=args.series, volume_index=args.volume_index,
               labels=args.label_table, grid=args.grid, progress=TerminalProgress("reading"))
    facts = describe(vol)
    facts["path"] = [str(p) for p in args.path] if len(args.path) > 1 else str(args.path[0])
    if contents:
        facts["dicom_contents"] = contents
    facts.update(extras(vol, facts, args))  # hints, histogram picture
    print(json.dumps(facts, indent=2) if args.json else format_text(facts))
    return EXIT_OK


def dicom_contents(paths: List[str]) -> List[Dict]:
    """The image series and segmentation objects of a DICOM folder (empty for other inputs)."""
    from pathlib import Path

    from ...core.io.dicom_objects import list_dicom
    from ...core.io.masks import mask_files

    if len(paths) != 1 or not Path(paths[0]).is_dir() or mask_files(paths[0]):
        return []
    return list_dicom(paths[0])


def _segmentation_lines(facts: Dict) -> List[str]:
    lines = []
    if facts.get("dicom_contents"):
        lines.append("contents     (choose with --series N)")
        lines += [f"  [{e['number']}] {e['kind']:<16} {e['description']}" for e in facts["dicom_contents"]]
    meta = facts.get("meta", {})
    for note in meta.get("notes") or []:
        lines.append(f"note         {note}")
    if meta.get("grid"):
        lines.append(f"grid         {meta['grid']}")
    for layer in facts.get("layers", []):
        lines.append(f"layer {layer['layer']}      {', '.join(layer['structures'])}")
    for o in facts.get("overlaps", []):
        lines.append(f"overlap      {o['a']} & {o['b']}: {o['voxels']} voxels, {o['mm3']:.1f} mm3")
    return lines


def format_text(facts: Dict) -> str:
    """Human-readable report of :func:`describe`'s facts."""
    lines = _segmentation_lines(facts) + [
        f"format       {facts['format']}   modality {facts['modality']}",
        f"shape        {' x '.join(str(s) for s in facts['shape'])} voxels   dtype {facts['dtype']}",
        f"spacing      {' x '.join(f'{s:g}' for s in facts['spacing'])} mm   "
        f"extent {' x '.join(f'{e:g}' for e in facts['extent_mm'])} mm",
        f"orientation  {facts['orientation']} (voxel axes i, j, k point to these patient directions;"
        f" coordinates in {facts['space']})",
        "affine       voxel (i, j, k) -> mm in " + facts["space"],
    ]
    for row in facts["affine"]:
        lines.append("             [" + "  ".join(f"{x:10.4f}" for x in row) + "]")
    lines.append(f"values       {facts['min']} .. {facts['max']}")
    if "histogram" in facts:
        lines.append("histogram")
        lines.extend(_text_histogram(facts["histogram"]))
        peaks = facts["histogram"]["peaks"]
        if peaks:
            lines.append("peaks        " + ", ".join(
                f"{p['value']:g}" + (f" ({p['tissue']})" if "tissue" in p else "") for p in peaks))
    if "labels" in facts:
        lines.append(f"labels       {len(facts['labels'])}")
        lines.append(f"  {'value':>6}  {'name':<32} {'voxels':>10} {'volume mm3':>14}")
        for lab in facts["labels"]:
            lines.append(f"  {lab['value']:>6}  {lab['name']:<32} {lab['voxels']:>10} "
                         f"{lab['volume_mm3']:>14.1f}")
    for w in facts.get("warnings", []):
        lines.append(f"warning      {w}")
    for h in facts.get("hints", []):
        lines.append(f"hint         {h}")
    if facts.get("histogram_png"):
        lines.append(f"histogram    picture: {facts['histogram_png']}")
    return "\n".join(lines)


def _text_histogram(hist: Dict, width: int = 50, rows: int = 16) -> List[str]:
    counts = np.asarray(hist["counts"], dtype=np.float64)
    edges = np.asarray(hist["edges"])
    step = max(1, len(counts) // rows)
    out = []
    scale = np.log1p(counts).max() or 1.0
    for i in range(0, len(counts), step):
        c = counts[i:i + step].sum()
        bar = "#" * int(round(width * np.log1p(c) / (scale + np.log(step))))
        out.append(f"  {edges[i]:>9.1f} .. {edges[min(i + step, len(edges) - 1)]:>9.1f} |{bar}")
    return out
