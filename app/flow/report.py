"""The report of a run: what ran, with its parameters, timings and measured effects, as JSON.

``report.json`` holds ``space``, ``units``, ``input`` (facts of the volume read), ``recipe``,
``smoothing``, ``decimation``, ``files``, ``timings``, ``warnings`` and one entry per surface:
``value, name, color, files, vertices, faces, volume_mm3, area_mm2, closed, manifold, oriented,
euler, genus, components, degenerate_faces, pinch_points`` (the topology measured on the surface
as written, read back by position; ``pinch_points``: vertex copies moved apart where the
structure touches itself, summed up with the rule and gap in the report's ``pinch_points``);
with smoothing also ``volume_change_pct``,
``max_deviation_mm``, ``mean_deviation_mm`` (symmetric Hausdorff and mean distance to the
unsmoothed surface), ``max_displacement_mm``, ``topology_changed``; with decimation
``faces_before``, ``decimation_max_error_mm``, ``decimation_mean_error_mm`` and
``decimation_volume_change_pct``. Beside it, ``recipe.toml`` re-runs the same job. The Blender
panels show the same numbers.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import numpy as np

from ...core.geometry.topology import Topology, topology_and_size
from ...core.model.mesh import Mesh
from .outputs import relative
from .recipe import SMOOTH_NONE, dump_recipe
from .stages import value_key

from .result import Result


def build_report(result: Result) -> Dict:
    """The report dict of a finished run (see the module docstring)."""
    recipe, p = result.recipe, result.plan
    smoothing = result.smoothing or {"method": SMOOTH_NONE, "params": {}, "shells": {}, "warnings": []}
    base = p.report.parent.resolve()
    facts = dict(result.input_facts)  # taken by run() before the voxels may be let go
    sizes = result.surface_sizes or surface_sizes(result.surfaces)
    out = {"space": result.volume.space, "units": "mm", "input": facts,
           "recipe": dataclasses.asdict(recipe),
           "smoothing": {"preset": recipe.smooth,
                         **{k: smoothing.get(k) for k in ("method", "params", "seconds", "warnings")}},
           "decimation": _decimation_summary(result.decimation),
           "files": {fmt: relative(path, base) for fmt, path in p.scene.items()},
           "timings": {k: round(v, 4) for k, v in result.timings.items()},
           "surfaces": [surface_entry(m, size, extra, files, smoothing, result.decimation, base)
                        for m, size, extra, files in zip(result.surfaces, sizes, result.cleaning,
                                                         p.surfaces)]}
    out["files"].update(report=relative(p.report, base), recipe=relative(p.recipe, base))
    if "layers" in facts:  # segmentations: overlapping structures, one layer each
        out["layers"], out["overlaps"] = facts["layers"], facts["overlaps"]
    out["notes"] = list(facts["meta"].get("notes") or [])
    if p.dicom_reference and p.dicom_reference.get("note"):
        out["notes"].append(p.dicom_reference["note"])
    if result.pinch_points is not None:
        out["pinch_points"] = result.pinch_points
    for key in ("lod", "fixes", "print_check"):
        if getattr(result, key):
            out[key] = getattr(result, key)
    for key in ("distance", "web", "preprocess", "render"):
        if getattr(result, key, None):
            out[key] = getattr(result, key)
    out["warnings"] = list(result.warnings)
    return out


def surface_sizes(meshes: List[Mesh]) -> List[Tuple[Topology, float, float]]:
    """Per mesh ``(topology, area mm², enclosed volume mm³)`` for its entry, the topology of the
    surface as written and read back by position (vertices at the same float32 position joined,
    as STL readers, slicers and mesh tools do:
    :func:`~anatomesh.core.geometry.topology.topology_and_size`; its kernels release the GIL,
    so :func:`~anatomesh.app.flow.run.run` computes them while the files are written)."""
    return [topology_and_size(m.vertices, m.faces, by_position=True) for m in meshes]


def surface_entry(m: Mesh, size: Tuple[Topology, float, float], extra: Dict,
                  files: Dict[str, Path], smoothing: Dict, decimation: Optional[Dict],
                  base: Path) -> Dict:
    """One surface's entry: its files, topology and size (``size`` from
    :func:`surface_sizes`), and the smoothing/decimation measures."""
    topo, area, volume = size
    return {"value": m.value, "name": m.name, "color": list(m.color),
            "files": {fmt: relative(path, base) for fmt, path in files.items()},
            "vertices": topo.vertices, "faces": topo.faces,
            "volume_mm3": round(volume, 3),
            "area_mm2": round(area, 3),
            "closed": topo.closed, "manifold": topo.manifold, "oriented": topo.oriented,
            "euler": topo.euler, "genus": topo.genus, "components": topo.components,
            "degenerate_faces": topo.degenerate_faces,
            "pinch_points": int(m.meta.get("pinch_points", 0)), **_smoothing_fields(smoothing, m),
            **_decimation_fields(decimation, m), **extra}


def warnings_of(volume_warnings: List[str], surfaces_warnings: List[str], smoothing: Optional[Dict],
                decimation: Optional[Dict]) -> List[str]:
    """Every warning of a run, reader first, one line each."""
    out = list(volume_warnings) + list(surfaces_warnings) + list((smoothing or {}).get("warnings") or [])
    if decimation is None:
        return out
    bound = decimation["target"].get("max_error_mm")
    if decimation.get("target_met") is False:
        cap = f", or exceed the {bound} mm error cap (--max-error raises it)" if bound is not None else ""
        out.append(f"decimation stopped at {decimation['faces_after']} faces, short of its target: "
                   f"every further collapse would change a shell's topology, spoil triangles{cap}")
    if decimation.get("error_bound_met") is False:
        out.append(f"decimation could not keep every shell within {bound} mm "
                   "(see decimation_max_error_mm)")
    return out


def save(report: Dict, recipe, report_path: Path, recipe_path: Path) -> None:
    """Write the JSON report and, beside it, the recipe (paths relative to it, no overwrite)."""
    report_path.parent.mkdir(parents=True, exist_ok=True)
    report_path.write_text(json.dumps(report, indent=2, default=json_default))
    recipe_path.write_text(dump_recipe(dataclasses.replace(recipe, overwrite=False),
                                       base=recipe_path.parent))


def json_default(obj):
    """numpy scalars and arrays, and paths, in reports as plain JSON."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _decimation_summary(decimation: Optional[Dict]) -> Optional[Dict]:
    if decimation is None:
        return None
    out = {k: v for k, v in decimation.items() if k != "shells"}
    for k in ("hausdorff_mm", "mean_mm", "seconds"):
        out[k] = round(float(out[k]), 4)
    return out


def _decimation_fields(decimation: Optional[Dict], m: Mesh) -> Dict:
    shell = (decimation or {}).get("shells", {}).get(value_key(m.value))
    if not shell:
        return {}
    return {"faces_before": int(shell["faces_before"]),
            "decimation_max_error_mm": round(float(shell["hausdorff_mm"]), 4),
            "decimation_mean_error_mm": round(float(shell["mean_mm"]), 4),
            "decimation_volume_change_pct": round(float(shell["volume_change_pct"]), 4)}


def _smoothing_fields(smoothing: Dict, m: Mesh) -> Dict:
    shells = smoothing.get("shells", {})
    shell = shells.get(value_key(m.value)) or shells.get(str(m.value))
    if not shell:
        return {}
    return {"volume_change_pct": round(shell["volume_change_pct"], 4),
            "max_deviation_mm": round(shell.get("hausdorff_mm", float("nan")), 4),
            "mean_deviation_mm": round(shell.get("mean_distance_mm", float("nan")), 4),
            "max_displacement_mm": round(shell["max_displacement_mm"], 4),
            "topology_changed": bool(shell["topology_changed"])}
