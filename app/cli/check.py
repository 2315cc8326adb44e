"""``anatomesh check PATH...``: print-readiness checks of mesh files, all parts together.

Reads STL/PLY/OBJ/3MF files or a folder written by ``anatomesh mesh`` (:mod:`anatomesh.app.flow.check_files`),
checks all parts together for a printer profile (:func:`anatomesh.core.printing.checks.check_parts`),
prints a summary and optionally writes the JSON report. Optional fixes (``--remove-tiny``,
``--close-holes``, ``--separate``) work on the meshes read and write the fixed parts to ``--out``
as STL, plus all of them in one print-ready ``parts.3mf``; the checks then run on the fixed parts.

Exit codes: 0 every check passes, 1 a check fails, 2 bad input (one line on stderr).
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Dict, List

from ...core.model.errors import AnatomeshError
from ...core.printing.profiles import GAP_REPORT_MM, resolve_profile
from .mesh import fit_args, hollow_args
from ..flow.fit import fit_arg, summary as fit_summary  # cut to fit
from .common import EXIT_CHECK_FAILED, EXIT_OK, TerminalProgress, write_json


def add_parser(subs) -> argparse.ArgumentParser:
    """Add the ``check`` sub-command to ``subs`` (an argparse sub-parsers object)."""
    p = subs.add_parser("check", help="print-readiness checks of mesh files or a folder from `anatomesh mesh`",
                        description="Check meshes for 3D printing: solid (closed, manifold, no "
                                    "self-intersections), wall thickness and gaps between parts, "
                                    "all parts together. Exit 0 pass, 1 a check fails, 2 bad input.")
    p.add_argument("path", nargs="+", help="STL/PLY/OBJ/3MF files, or a folder written by `anatomesh mesh`")
    p.add_argument("--profile", default="fdm", choices=("fdm", "resin"),
                   help="printer profile: fdm (min wall 0.8 mm, min gap 0.5 mm) or resin (0.4 / 0.2 mm)")
    p.add_argument("--min-wall", type=float, metavar="MM", help="minimum printable wall (overrides the profile)")
    p.add_argument("--min-gap", type=float, metavar="MM", help="minimum gap that stays open (overrides the profile)")
    p.add_argument("--report", metavar="FILE", help="write the JSON report here")
    p.add_argument("--remove-tiny", type=float, metavar="MM3",
                   help="fix: remove shells enclosing less than this volume (mm³); needs --out")
    p.add_argument("--close-holes", type=int, metavar="EDGES",
                   help="fix: close boundary loops of up to this many edges; needs --out")
    p.add_argument("--separate", type=float, metavar="MM",
                   help="fix: pull touching parts apart by this clearance (each side of a shared "
                        "interface moves back by half); needs --out")
    hollow_args(p)  # print tools
    fit_args(p)  # cut to fit
    p.add_argument("--out", metavar="DIR", help="write the fixed parts here as STL and all in one "
                                                "parts.3mf (with a fix or tool option)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files in --out")
    p.set_defaults(func=cmd_check)
    return p


def cmd_check(args) -> int:
    # speed: the checks, readers and writers load only for this command
    from ...core.printing.checks import check_parts
    from ..flow.check_files import read_parts

    fixing = any(x is not None for x in (args.remove_tiny, args.close_holes, args.separate, args.hollow, args.fit))
    if fixing and not args.out:
        raise AnatomeshError("--remove-tiny/--close-holes/--separate/--hollow/--fit write fixed files: add --out DIR")
    if args.out and not fixing:
        raise AnatomeshError("--out is for fixed files: add --remove-tiny MM3, --close-holes EDGES, "
                             "--separate MM, --hollow WALL_MM and/or --fit X,Y,Z")
    fit = None if args.fit is None else fit_arg(args.fit)  # bad sizes exit 2 early
    prof = resolve_profile(args.profile, args.min_wall, args.min_gap)  # bad numbers: exit 2 early
    meshes = read_parts(args.path)
    fixes = []
    if fixing:
        meshes, fixes = _write_fixed(meshes, args, fit)
    rep = check_parts(meshes, prof, progress=TerminalProgress("checking"))
    rep["profile"]["name"] = args.profile if (args.min_wall is None and args.min_gap is None) \
        else f"{args.profile} (overridden)"
    rep["files"] = [str(p) for p in args.path]
    if fixes:
        rep["fixes"] = fixes
    if args.report:
        write_json(rep, args.report)
    for f in fixes:
        if "file" in f:  # the per-part fit entries have their own line
            print(f"fixed {f['name']}: {f['summary']} -> {f['file']}")
        else:
            print(f"fit {fit_summary(f)}")
    for line in summary_lines(rep):
        print(line)
    if args.report:
        print(f"report {args.report}")
    return EXIT_OK if rep["passed"] else EXIT_CHECK_FAILED


def _write_fixed(meshes, args, fit=None):
    """Fix the parts (and cut them to ``fit`` the build volume); write each as STL and
    all in ``parts.3mf`` into ``args.out``."""
    from ...core.export.common import refuse_overwrite, unique_stems
    from ...core.export.mesh_files import write_stl
    from ...core.export.threemf import write_3mf
    from ..flow.check_files import fix_parts
    from ..flow.fit import PART_INDEX, fit_parts
    from ..flow.print_parts import hollow_part

    out = Path(args.out)
    plans = [out / f"{s}.stl" for s in unique_stems([m.name for m in meshes])]
    combined = out / "parts.3mf"
    refuse_overwrite(plans + [combined], args.overwrite, "pass --overwrite or choose another --out folder")
    fixed, log = fix_parts(meshes, args.remove_tiny, args.close_holes, args.separate)
    if args.hollow is not None:  # print tools
        for k, m in enumerate(fixed):
            fixed[k], info = hollow_part(m, args.hollow, 2 if args.drain_holes is None else args.drain_holes,
                                         args.drain_diameter, args.profile)
            log[k]["summary"] = "; ".join(x for x in (log[k]["summary"].replace("nothing to fix", ""),
                                                      _hollow_text(info)) if x)
            log[k]["hollow"] = info
    fit_entries = []
    if fit is not None:  # cut to fit; one file per piece
        parts = [m.name for m in fixed]
        fixed, fit_entries = fit_parts(fixed, fit, bool(args.fit_connectors), args.profile, args.min_wall)
        log = [_piece_log(log[m.meta[PART_INDEX]], parts[m.meta[PART_INDEX]], m.name) for m in fixed]
        plans = [out / f"{s}.stl" for s in unique_stems([m.name for m in fixed])]
        refuse_overwrite(plans, args.overwrite, "pass --overwrite or choose another --out folder")
    for m, path, entry in zip(fixed, plans, log):
        write_stl(m, path)
        entry["file"] = str(path)
    write_3mf(fixed, combined, title="fixed parts")
    return fixed, log + fit_entries


def _piece_log(entry: Dict, part: str, name: str) -> Dict:
    """A piece's log entry, from its part's."""
    if name == part:
        return dict(entry)
    text = "; ".join(x for x in (entry["summary"].replace("nothing to fix", ""), f"cut from {part} to fit") if x)
    return dict(entry, name=name, summary=text)


def _hollow_text(info: Dict) -> str:
    return (f"hollowed to {info['wall_mm']:g} mm walls, {info['saved_mm3']:.0f} mm³ "
            f"({info['saved_pct']:.0f} %) saved, {len(info['drain_holes'])} drain hole(s)")


def summary_lines(rep: Dict) -> List[str]:
    """A short human summary of a :func:`check_parts` report, one problem per line."""
    prof = rep["profile"]
    lines = [f"profile {prof['name']}: min wall {prof['min_wall']} mm, min gap {prof['min_gap']} mm"]
    for p in rep["parts"]:
        wall = "?" if p["min_wall_mm"] is None else f"{p['min_wall_mm']:.2f}"
        state = "ok  " if p["passed"] else "FAIL"
        reasons = p.get("reasons", [])
        lines.append(f"{state} {p['name']} (min wall {wall} mm)" + (": " + reasons[0] if reasons else ""))
        lines += [f"       {r}" for r in reasons[1:4]]
        if len(reasons) > 4:
            lines.append(f"       ... {len(reasons) - 4} more in the report")
    for g in rep["gaps"]:
        if g.get("intersecting"):
            lines.append(f"FAIL {g['a']} and {g['b']} intersect at {g['location']}")
        elif g["fuses"]:
            lines.append(f"FAIL {g['a']} – {g['b']}: {g['clearance_mm']} mm apart at "
                         f"{g.get('clearance_location', g['location'])} (< {prof['min_gap']} mm: fuses)")
    n_touch = sum(bool(g["touching"]) for g in rep["gaps"])
    n_close = len(rep["gaps"]) - n_touch
    n_ok = sum(p["passed"] for p in rep["parts"])
    lines.append(f"{'PASSED' if rep['passed'] else 'FAILED'}: {n_ok}/{len(rep['parts'])} parts pass; "
                 f"{n_touch} touching pairs (shared seams), {n_close} other pairs closer than "
                 f"{GAP_REPORT_MM:g} mm")
    return lines
