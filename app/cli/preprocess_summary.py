"""The lines ``anatomesh mesh`` prints about its preprocessing: each step, its parameters and its
measured effect. (The preprocessing flags are made from the recipe's definitions, like the others.)"""
from __future__ import annotations

from typing import Dict, List


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
