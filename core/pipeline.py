"""The one place the steps are chained: read → extract → clean → (smooth) → write → report.

A :class:`Recipe` holds every setting (the CLI flags, a recipe file and the Blender panel fill the
same fields); :func:`run` executes it with a progress callback and returns a :class:`Result`.
"""
from __future__ import annotations

import difflib
import json
import re
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Union

import numpy as np

from . import mesh as meshlib
from .errors import AnatomeshError
from .inspect import describe
from .io import load
from .mesh import Mesh
from .progress import Progress, report, sub
from .volume import Volume

SMOOTH_NONE = "none"
SMOOTH_DEFAULT = "organ"  # core.smooth.DEFAULT: Taubin in the voxel cell, volumes kept


@dataclass
class Recipe:
    """Everything a run needs. Paths may be strings; units are mm.

    ``labels``: "all", or a list of label values and/or names (label maps only).
    ``levels``: isovalues for scalar scans (required for them).
    ``space``: the space every written vertex is in ("RAS" or "LPS").
    ``formats``: any of "stl", "ply", "obj".
    ``smooth``: a preset or filter of :mod:`anatomesh.core.smooth` ("organ" by default, "none" keeps
    the raw surface); ``iterations``/``lam``/``mu`` override the preset, ``max_deviation`` (mm) caps
    every vertex's displacement, ``damping_distance`` (mm) enables distance-aware damping,
    ``staircase`` ("auto", "on", "off") the extra slice-axis passes for thick slices.
    """

    input: Union[str, List[str]] = ""
    out_dir: str = "out"
    series: Optional[str] = None
    volume_index: Optional[int] = None
    label_table: Optional[str] = None
    labels: Union[str, List[Union[int, str]]] = "all"
    levels: List[float] = field(default_factory=list)
    space: str = "RAS"
    cap: bool = True
    keep_largest: bool = False
    min_component_mm3: float = 0.0
    smooth: str = SMOOTH_DEFAULT
    iterations: Optional[int] = None
    lam: Optional[float] = None
    mu: Optional[float] = None
    max_deviation: Optional[float] = None
    damping_distance: Optional[float] = None
    staircase: str = "auto"
    formats: List[str] = field(default_factory=lambda: ["stl"])
    report: Optional[str] = None
    overwrite: bool = False


@dataclass
class Result:
    volume: Volume
    surfaces: List[Mesh]
    report: Dict
    report_path: Optional[Path] = None


def run(recipe: Recipe, progress: Optional[Progress] = None) -> Result:
    """Execute ``recipe``: returns the surfaces and the report, and writes files when ``out_dir`` is set."""
    t0 = time.perf_counter()
    report(progress, 0.0, "reading")
    volume = load(recipe.input, series=recipe.series, volume_index=recipe.volume_index,
                  labels=recipe.label_table, space=recipe.space, progress=sub(progress, 0.0, 0.25))
    timings = {"read_s": time.perf_counter() - t0}

    t1 = time.perf_counter()
    report(progress, 0.25, "extracting surfaces")
    raw = extract(volume, recipe, sub(progress, 0.25, 0.5))
    timings["extract_s"] = time.perf_counter() - t1

    t2 = time.perf_counter()
    report(progress, 0.5, f"smoothing ({recipe.smooth})")
    smoothed, smoothing = smooth(raw, volume, recipe, sub(progress, 0.5, 0.7))
    surfaces = smoothed.shells() if hasattr(smoothed, "shells") else smoothed
    timings["smooth_s"] = time.perf_counter() - t2

    entries = []
    for m in surfaces:
        entries.append(_clean(m, recipe))
    report(progress, 0.75, "writing")
    out_dir = Path(recipe.out_dir)
    report_path = Path(recipe.report) if recipe.report else out_dir / "report.json"
    files = _plan_files(surfaces, recipe, out_dir)
    _refuse_overwrite([p for fs in files for p in fs.values()] + [report_path], recipe.overwrite)
    from .export import write_mesh
    for i, (m, fs) in enumerate(zip(surfaces, files)):
        for fmt, path in fs.items():
            write_mesh(m, path, fmt)
        report(progress, 0.75 + 0.2 * (i + 1) / max(1, len(surfaces)), f"wrote {m.name}")
    timings["total_s"] = time.perf_counter() - t0
    rep = build_report(volume, recipe, surfaces, entries, files, report_path, timings, smoothing)
    rep["warnings"] = list(volume.warnings) + list(getattr(raw, "warnings", [])) + \
        list(smoothing.get("warnings") or [])
    report_path.parent.mkdir(parents=True, exist_ok=True)
    report_path.write_text(json.dumps(rep, indent=2))
    report(progress, 1.0, "done")
    return Result(volume, surfaces, rep, report_path)


# ---------------------------------------------------------------------------------------------
def extract(volume: Volume, recipe: Recipe, progress: Optional[Progress] = None):
    """A SurfaceSet (label map: conforming shells) or a list of isosurface Meshes (scalar scan)."""
    from .extract import isosurfaces, label_surfaces

    if volume.is_label_map:
        if recipe.levels:
            raise AnatomeshError("--level is for scalar scans; this is a label map (use --labels)",
                                 volume.meta.get("source"))
        values = select_labels(volume, recipe.labels)
        return label_surfaces(volume, values=values, progress=progress)
    if not recipe.levels:
        raise AnatomeshError("this is a scalar scan: give one or more isovalues with --level "
                             "(see `anatomesh inspect` for the histogram peaks)", volume.meta.get("source"))
    return isosurfaces(volume, list(recipe.levels), cap=recipe.cap, progress=progress)


def smooth(surfaces, volume: Volume, recipe: Recipe, progress: Optional[Progress] = None):
    """Smooth a SurfaceSet (seams move once, for both labels) or each isosurface Mesh.

    Returns ``(smoothed, {value: per-shell measures})`` plus the method and parameters used, via
    :func:`anatomesh.core.smooth.smooth_surfaces` (which measures volume change and the distance
    to the unsmoothed surface).
    """
    from .smooth import smooth_surfaces

    method = recipe.smooth or SMOOTH_NONE
    if method == SMOOTH_NONE:
        return surfaces, {"method": SMOOTH_NONE, "params": {}, "shells": {}, "warnings": []}
    params = {k: v for k, v in (("iterations", recipe.iterations), ("lam", recipe.lam),
                                ("mu", recipe.mu)) if v is not None}
    options = dict(max_deviation=recipe.max_deviation, damping_distance=recipe.damping_distance,
                   staircase={"auto": "auto", "on": True, "off": False}[recipe.staircase])
    if hasattr(surfaces, "shells"):
        out, rep = smooth_surfaces(surfaces, method, progress=progress, **options, **params)
        return out, rep.as_dict()
    meshes, merged = [], None
    for i, m in enumerate(surfaces):
        sm, rep = smooth_surfaces(m, method, affine=volume.affine, progress=sub(
            progress, i / len(surfaces), (i + 1) / len(surfaces)), **options, **params)
        sm.meta = dict(m.meta)
        meshes.append(sm)
        d = rep.as_dict()
        shell = next(iter(d["shells"].values()), None)
        if merged is None:
            merged = dict(d, shells={})
        else:
            merged["warnings"] += d["warnings"]
            merged["seconds"] += d["seconds"]
        if shell is not None:
            merged["shells"][str(m.value)] = shell
    return meshes, merged or {"method": method, "params": {}, "shells": {}, "warnings": []}


def select_labels(volume: Volume, wanted: Union[str, Sequence[Union[int, str]]]) -> Optional[List[int]]:
    """Label values for ``wanted`` ("all", values, or names matched case-insensitively)."""
    if wanted in (None, "all", ["all"]):
        return None
    table = volume.labels or {}
    by_name = {info.name.lower(): v for v, info in table.items()}
    values = []
    for w in wanted:
        if isinstance(w, (int, np.integer)) or str(w).strip().isdigit():
            values.append(int(w))
            continue
        key = str(w).strip().lower()
        if key not in by_name:
            close = difflib.get_close_matches(key, list(by_name), n=5, cutoff=0.6)
            close += [n for n in by_name if key in n and n not in close][:5]
            hint = f"; did you mean {', '.join(close)}?" if close else \
                "; run `anatomesh inspect` to list the labels"
            raise AnatomeshError(f"no label named {w!r}{hint}", volume.meta.get("source"))
        values.append(by_name[key])
    return values


def _clean(m: Mesh, recipe: Recipe) -> Dict:
    """Apply keep-largest / min-component to ``m`` in place; returns what was dropped."""
    dropped = []
    if m.n_faces and (recipe.keep_largest or recipe.min_component_mm3 > 0):
        comps = meshlib.component_measures(m.vertices, m.faces)
        keep = []
        for i, c in enumerate(comps):
            if (recipe.keep_largest and i > 0) or abs(c["volume_mm3"]) < recipe.min_component_mm3:
                dropped.append({"volume_mm3": round(c["volume_mm3"], 3), "area_mm2": round(c["area_mm2"], 3),
                                "faces": int(len(c["faces"]))})
            else:
                keep.append(c["faces"])
        if dropped:
            faces = m.faces[np.sort(np.concatenate(keep))] if keep else m.faces[:0]
            v, f, n, _ = meshlib.compact(m.vertices, faces, m.normals)
            m.vertices, m.faces, m.normals = v, f, n
    return {"dropped_components": dropped}


def _slug(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_")
    return s or "surface"


def _plan_files(surfaces: List[Mesh], recipe: Recipe, out_dir: Path) -> List[Dict[str, Path]]:
    used = set()
    plans = []
    for m in surfaces:
        stem = _slug(m.name)
        if stem in used:
            stem = f"{stem}_{_slug(str(m.value))}"
        used.add(stem)
        plans.append({fmt: out_dir / f"{stem}.{fmt}" for fmt in recipe.formats})
    return plans


def _refuse_overwrite(paths: List[Path], overwrite: bool) -> None:
    existing = [p for p in paths if p.exists()]
    if existing and not overwrite:
        raise AnatomeshError(f"{len(existing)} output file(s) already exist (e.g. {existing[0]}); "
                             "pass --overwrite to replace them or choose another --out folder")


def build_report(volume: Volume, recipe: Recipe, surfaces: List[Mesh], entries: List[Dict],
                 files: List[Dict[str, Path]], report_path: Path, timings: Dict,
                 smoothing: Optional[Dict] = None) -> Dict:
    """The JSON report: space, units, input facts, recipe, smoothing and one entry per surface.

    With smoothing, each surface also has ``volume_change_pct``, ``max_deviation_mm`` and
    ``mean_deviation_mm`` (symmetric Hausdorff and mean distance to the unsmoothed surface) and
    ``topology_changed``.
    """
    smoothing = smoothing or {"method": SMOOTH_NONE, "params": {}, "shells": {}, "warnings": []}
    base = report_path.parent.resolve()
    facts = describe(volume)
    facts.pop("histogram", None)
    out = {"space": volume.space, "units": "mm", "input": facts,
           "recipe": {k: v for k, v in asdict(recipe).items()},
           "smoothing": {"preset": recipe.smooth,
                         **{k: smoothing.get(k) for k in ("method", "params", "seconds", "warnings")}},
           "timings": {k: round(v, 4) for k, v in timings.items()},
           "surfaces": []}
    for m, extra, fs in zip(surfaces, entries, files):
        topo = meshlib.topology(m.vertices, m.faces)
        comps = meshlib.face_components(m.faces, m.n_vertices)[0] if m.n_faces else 0
        out["surfaces"].append({
            "value": m.value, "name": m.name, "color": list(m.color),
            "files": {fmt: _rel(p, base) for fmt, p in fs.items()},
            "vertices": topo.vertices, "faces": topo.faces,
            "volume_mm3": round(meshlib.signed_volume(m.vertices, m.faces), 3),
            "area_mm2": round(meshlib.surface_area(m.vertices, m.faces), 3),
            "closed": topo.closed, "manifold": topo.manifold, "oriented": topo.oriented,
            "euler": topo.euler, "genus": topo.genus, "components": comps,
            "degenerate_faces": topo.degenerate_faces, **_smoothing_fields(smoothing, m), **extra})
    return out


def _smoothing_fields(smoothing: Dict, m: Mesh) -> Dict:
    key = str(int(m.value)) if m.value is not None and float(m.value).is_integer() else str(m.value)
    shell = smoothing.get("shells", {}).get(key) or smoothing.get("shells", {}).get(str(m.value))
    if not shell:
        return {}
    return {"volume_change_pct": round(shell["volume_change_pct"], 4),
            "max_deviation_mm": round(shell.get("hausdorff_mm", float("nan")), 4),
            "mean_deviation_mm": round(shell.get("mean_distance_mm", float("nan")), 4),
            "max_displacement_mm": round(shell["max_displacement_mm"], 4),
            "topology_changed": bool(shell["topology_changed"])}


def _rel(p: Path, base: Path) -> str:
    try:
        return str(p.resolve().relative_to(base))
    except ValueError:
        return str(p.resolve())
