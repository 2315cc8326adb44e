"""The preprocessing flags of ``anatomesh mesh`` and the lines it prints about them.

Values are taken as text and checked by :func:`anatomesh.app.preprocess_settings.check_preprocess`,
so a bad one is one line naming the flag (exit code 2), not argparse's usage dump.
"""
from __future__ import annotations

import argparse
from typing import Dict, List

from ...core.model.errors import AnatomeshError
from ..preprocess_settings import parse_numbers

#: boolean flags → Recipe field
SWITCHES = ("interpolate", "fuzzy_boundary", "fill_cavities", "precise", "difference_colors")


def add_arguments(m: argparse.ArgumentParser) -> None:
    g = m.add_argument_group("preprocessing (before and around extraction; each step's effect on "
                             "the surface is measured and reported)")
    g.add_argument("--resample", metavar="MM|X,Y,Z",
                   help="scalar scans: resample to this voxel size in mm (one number: isotropic)")
    g.add_argument("--resample-method", metavar="linear|cubic|lanczos",
                   help="interpolation for --resample: linear (default), cubic (B-spline), lanczos")
    g.add_argument("--roi", nargs="+", metavar="MM",
                   help="cut the scan to the box X0 Y0 Z0 X1 Y1 Z1 in mm (in --space) before anything else, "
                        "or --roi=X0,Y0,Z0,X1,Y1,Z1")
    g.add_argument("--smooth-volume", metavar="SPEC",
                   help="scalar scans: gaussian:SIGMA_MM, median:SIZE_MM (one value or X,Y,Z) or "
                        "diffusion:ITERATIONS (edge-preserving, Perona-Malik)")
    g.add_argument("--interpolate", action="store_true", default=None,
                   help="label maps: shape-based interpolation to isotropic voxels at the finest "
                        "spacing (removes the staircase of thick slices)")
    g.add_argument("--fuzzy-boundary", action="store_true", default=None,
                   help="label maps: smooth each label at the voxel level (morphological fuzzy "
                        "boundary); the surface stays within one voxel, measured")
    g.add_argument("--fill-cavities", action="store_true", default=None,
                   help="label maps: fill background pockets enclosed by a label")
    g.add_argument("--close-handles", metavar="MM",
                   help="label maps: plug tunnels (handles) up to MM across; genus before/after reported")
    g.add_argument("--fuzzy", nargs="+", metavar="VALUE",
                   help="I1 I2 [N], scalar scans: N (default 5) nested isosurfaces over [I1, I2], the middle one "
                        "opaque, the others more transparent toward the ends (GLB, Blender)")
    g.add_argument("--precise", action="store_true", default=None,
                   help="scalar scans: refine isosurface triangles onto the trilinear interpolant; "
                        "reports how far the surface moved and the cost")
    g.add_argument("--difference-colors", action="store_true", default=None,
                   help="colour every surface by its distance to the surface without preprocessing "
                        "(PLY/GLB vertex colours, a colour attribute in Blender)")


def apply(args, recipe) -> None:
    """Copy the preprocessing flags given on the command line into ``recipe``."""
    for name in SWITCHES:
        if getattr(args, name, None) is not None:
            setattr(recipe, name, getattr(args, name))
    for name in ("resample", "smooth_volume"):
        if getattr(args, name, None) is not None:
            setattr(recipe, name, getattr(args, name))
    if args.roi is not None:
        recipe.roi = parse_numbers(",".join(args.roi), "--roi", (6,))
    if args.resample_method is not None:
        recipe.resample_method = args.resample_method
    if args.close_handles is not None:
        recipe.close_handles = parse_numbers(args.close_handles, "--close-handles", (1,))[0]
    if args.fuzzy is not None:
        recipe.fuzzy = parse_numbers(args.fuzzy, "--fuzzy I1 I2 [N]", (2, 3))
        if recipe.levels:
            raise AnatomeshError("give --fuzzy I1 I2 [N] or --level, not both (--fuzzy makes its own levels)")


def summary_lines(report: Dict) -> List[str]:
    """One line per preprocessing step: what ran, its parameters and its measured effect."""
    section = report.get("preprocess")
    if not section:
        return []
    out = []
    for step in section["steps"]:
        params = ", ".join(f"{k} {_short(v)}" for k, v in step.get("params", {}).items())
        line = f"preprocess {step['step']}" + (f" ({params})" if params else "")
        effect = step.get("effect")
        if effect and "max_mm" in effect:
            line += f": surface moved mean {effect['mean_mm']:.3g} mm"
            line += f", 99 % within {effect['p99_mm']:.3g} mm" if "p99_mm" in effect else ""
            line += f", max {effect['max_mm']:.3g} mm"
            if "within_one_voxel" in effect:
                line += f" ({'within' if effect['within_one_voxel'] else 'NOT within'} one voxel, " \
                        f"{effect['voxel_mm']:g} mm)"
        if step["step"] in ("fill_cavities", "close_handles") and effect:
            genus = [(p.get("genus_before"), p.get("genus_after")) for p in effect["surfaces"].values()
                     if "genus_before" in p]
            changed = [g for g in genus if g[0] != g[1]]
            line += f"; genus changed on {len(changed)} of {len(genus)} surfaces"
        if "seconds" in step:
            line += f" [{step['seconds']:.2f} s]"
        out.append(line)
    diff = section.get("difference")
    if diff:
        worst = max((s["max_mm"] for s in diff["surfaces"].values()), default=0.0)
        out.append(f"difference colours: up to {worst:.3g} mm from the surface without preprocessing "
                   f"(colour scale ±{diff['scale_mm']:.3g} mm; in PLY/GLB files)")
    return out


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return ",".join(_short(x) for x in v)
    return str(v)
