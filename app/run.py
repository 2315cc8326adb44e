"""The one place the steps are chained:
read → extract → smooth → decimate → shells → clean → write → (print check) → report.

A :class:`Recipe` holds every setting (the CLI flags, a recipe file (:mod:`.recipe`) and the
Blender panel fill the same fields); :func:`run` executes it with a progress callback and returns a
:class:`Result` (the surfaces, the SurfaceSet of a label map, the report).

Outputs (``formats``), all in mm in ``space``: ``stl``, ``ply``, ``obj``, ``3mf`` one file per
surface; ``3mf`` also one combined print-ready ``<stem>.3mf`` (one object per part, colours);
``glb`` one ``<stem>.glb`` with every surface; ``blend`` a Blender file ``<stem>.blend`` built by
the add-on exactly as its Extract button would (:mod:`anatomesh.addon.headless`, needs ``bpy``);
``png`` a Cycles render of that scene. ``<stem>`` is a slug of the scan's name. Next to the
report, ``recipe.toml`` holds the recipe, so ``anatomesh mesh --recipe OUT/recipe.toml`` re-runs it.
"""
from __future__ import annotations

import dataclasses
import json
import re
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Union

import numpy as np

from ..core.geometry import topology as topolib
from ..core.model import mesh as meshlib
from ..core.model.errors import AnatomeshError
from ..core.io.describe import describe
from ..core.io import load
from ..core.model.mesh import Mesh
from ..core.model.progress import Progress, report, sub
from ..core.model.volume import Volume
from ..core.model.labels import LabelInfo, select_labels

SMOOTH_NONE = "none"
SMOOTH_DEFAULT = "organ"  # core.smooth.DEFAULT: Taubin in the voxel cell, volumes kept
#: per-surface formats, whole-scene formats, and the ones that need Blender (bpy)
SURFACE_FORMATS = ("stl", "ply", "obj", "3mf")
SCENE_ONLY_FORMATS = ("glb", "blend", "png")
FORMATS = SURFACE_FORMATS + SCENE_ONLY_FORMATS
BLENDER_FORMATS = ("blend", "png")
SPACES = ("RAS", "LPS")
STAIRCASE = ("auto", "on", "off")
PROFILES = ("fdm", "resin")
RECIPE_FILE = "recipe.toml"


@dataclass
class Recipe:
    """Everything a run needs. Paths may be strings; units are mm.

    ``labels``: "all", or a list of label values and/or names (label maps only).
    ``levels``: isovalues for scalar scans (required for them).
    ``space``: the space every written vertex is in ("RAS" or "LPS").
    ``formats``: any of :data:`FORMATS` ("stl", "ply", "obj", "3mf", "glb", "blend", "png").
    ``smooth``: a preset or filter of :mod:`anatomesh.core.smooth.driver` ("organ" by default, "none" keeps
    the raw surface); ``iterations``/``lam``/``mu`` override the preset, ``max_deviation`` (mm) caps
    every vertex's displacement, ``damping_distance`` (mm) enables distance-aware damping,
    ``staircase`` ("auto", "on", "off") the extra slice-axis passes for thick slices.
    ``decimate`` (ratio of faces kept, 0–1] or ``target_faces``, and/or ``max_error`` (mm):
    decimation after smoothing (:mod:`anatomesh.core.decimate.qem`; a label map's SurfaceSet as a
    whole, so seams stay shared). With a ratio or face count, ``max_error`` caps the error (default:
    one voxel, the largest spacing), so a target the shapes cannot reach stops short with a warning
    instead of ruining small organs. ``check``: run the print checks (:func:`~anatomesh.core.printing.checks.
    check_parts`) with ``profile`` ("fdm", "resin"), ``min_wall``/``min_gap`` (mm) overriding it.
    Print fixes (label maps; each reported under ``fixes``): ``fuse`` — groups of labels (values
    or names) merged into one solid each before extraction; ``thicken`` — grow parts thinner than
    the minimum wall (``min_wall`` or the profile's) in the label map before extraction;
    ``clearance`` (mm) — pull touching parts apart along their shared interfaces after decimation,
    so separately printed parts fit together (:mod:`anatomesh.core.printing.fixes`).
    ``render_samples``/``render_size``: Cycles samples and pixel size of the "png" output.
    ``lod``: number of levels of detail written as ``<scan>_lod0.glb`` (the final surfaces) ..
    ``<scan>_lod{n-1}.glb`` (each level half the faces of the one before, or the coarsest that keeps
    every shell's topology), all from one progressive decimation run (:mod:`anatomesh.core.decimate.progressive`,
    Hoppe 1996); 0 or 1: none.
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
    decimate: Optional[float] = None
    target_faces: Optional[int] = None
    max_error: Optional[float] = None
    check: bool = False
    profile: str = "fdm"
    min_wall: Optional[float] = None
    min_gap: Optional[float] = None
    fuse: List[List[Union[int, str]]] = field(default_factory=list)
    thicken: bool = False
    clearance: Optional[float] = None
    formats: List[str] = field(default_factory=lambda: ["stl"])
    render_samples: int = 32
    render_size: List[int] = field(default_factory=lambda: [960, 540])
    lod: int = 0
    report: Optional[str] = None
    overwrite: bool = False


@dataclass
class Result:
    """What :func:`run` made: the volume read, the final surfaces (one closed :class:`Mesh` per
    label or level, mm), ``surface_set`` (the final :class:`~anatomesh.core.model.surfaceset.SurfaceSet`
    of a label map, None for isosurfaces), the report dict and where the files went."""

    volume: Volume
    surfaces: List[Mesh]
    report: Dict
    report_path: Optional[Path] = None
    surface_set: Optional[object] = None
    recipe: Optional[Recipe] = None
    files: Dict[str, Path] = field(default_factory=dict)


def run(recipe: Recipe, progress: Optional[Progress] = None) -> Result:
    """Execute ``recipe``: read, extract, smooth, decimate, clean, write, check, report.

    Every setting is checked first (:func:`check_recipe`), every output path before anything is
    written: existing files are refused unless ``overwrite``. Returns the :class:`Result`; the report is
    also written to ``report`` (default ``out_dir/report.json``) with ``recipe.toml`` beside it.
    """
    check_recipe(recipe)
    headless = _blender() if any(f in BLENDER_FORMATS for f in recipe.formats) else None
    t0 = time.perf_counter()
    report(progress, 0.0, "reading")
    volume = load(recipe.input, series=recipe.series, volume_index=recipe.volume_index,
                  labels=recipe.label_table, space=recipe.space, progress=sub(progress, 0.0, 0.2))
    timings = {"read_s": time.perf_counter() - t0}
    volume, fixes = fix_volume(volume, recipe)

    t1 = time.perf_counter()
    report(progress, 0.2, "extracting surfaces")
    raw = extract(volume, recipe, sub(progress, 0.2, 0.4))
    timings["extract_s"] = time.perf_counter() - t1

    t2 = time.perf_counter()
    report(progress, 0.4, f"smoothing ({recipe.smooth})")
    smoothed, smoothing = smooth(raw, volume, recipe, sub(progress, 0.4, 0.55))
    timings["smooth_s"] = time.perf_counter() - t2

    t3 = time.perf_counter()
    report(progress, 0.55, "decimating")
    final, decimation = decimate(smoothed, recipe, sub(progress, 0.55, 0.7),
                                 default_cap=float(max(volume.spacing)))
    timings["decimate_s"] = time.perf_counter() - t3
    surface_set = final if hasattr(final, "shells") else None
    surfaces = final.shells() if surface_set is not None else list(final)
    if recipe.clearance is not None:
        from ..core.printing.fixes import separate_parts

        surfaces, info = separate_parts(final, recipe.clearance)
        fixes.append({"fix": "clearance", **info})
    entries = [_clean(m, recipe) for m in surfaces]

    report(progress, 0.7, "writing")
    t4 = time.perf_counter()
    out_dir = Path(recipe.out_dir)
    report_path = Path(recipe.report) if recipe.report else out_dir / "report.json"
    recipe_path = report_path.parent / RECIPE_FILE
    stem = scan_stem(volume, recipe)
    files = _plan_files(surfaces, recipe, out_dir)
    scene_files = _plan_scene_files(stem, files, recipe, out_dir)
    lod_files = [out_dir / f"{stem}_lod{i}.glb" for i in range(recipe.lod if recipe.lod > 1 else 0)]
    _refuse_overwrite([p for fs in files for p in fs.values()] + list(scene_files.values())
                      + lod_files + [report_path, recipe_path], recipe.overwrite)
    write_outputs(surfaces, files, scene_files, stem, sub(progress, 0.7, 0.8))
    lods = write_lods(final, recipe, lod_files, stem, report_path.parent, sub(progress, 0.8, 0.85))
    timings["write_s"] = time.perf_counter() - t4
    result = Result(volume, surfaces, {}, report_path, surface_set, recipe, scene_files)
    if headless is not None:
        t5 = time.perf_counter()
        report(progress, 0.8, "building the Blender scene")
        headless.write_blend(result, scene_files.get("blend"), render_png=scene_files.get("png"),
                             samples=recipe.render_samples, size=tuple(recipe.render_size))
        timings["blender_s"] = time.perf_counter() - t5

    print_check = None
    if recipe.check:
        t6 = time.perf_counter()
        report(progress, 0.9, "print checks")
        from ..core.printing.checks import check_parts

        print_check = check_parts(surfaces, profile=recipe.profile, min_wall=recipe.min_wall,
                                  min_gap=recipe.min_gap, progress=sub(progress, 0.9, 0.99))
        timings["check_s"] = time.perf_counter() - t6
    timings["total_s"] = time.perf_counter() - t0
    rep = build_report(volume, recipe, surfaces, entries, files, report_path, timings, smoothing,
                       decimation=decimation, scene_files=scene_files, print_check=print_check)
    if lods:
        rep["lod"] = lods
    if fixes:
        rep["fixes"] = fixes
    rep["warnings"] = list(volume.warnings) + list(getattr(raw, "warnings", [])) + \
        list(smoothing.get("warnings") or []) + _decimation_warnings(decimation, recipe)
    save_report(rep, recipe, report_path, recipe_path)
    result.report = rep
    report(progress, 1.0, "done")
    return result


def _decimation_warnings(decimation: Optional[Dict], recipe: Recipe) -> List[str]:
    out = []
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


def save_report(rep: Dict, recipe: Recipe, report_path: Path, recipe_path: Path) -> None:
    """Write the JSON report and, beside it, the recipe (paths relative to it, no overwrite)."""
    from .recipe import dump_recipe

    report_path.parent.mkdir(parents=True, exist_ok=True)
    report_path.write_text(json.dumps(rep, indent=2, default=_json_default))
    recipe_path.write_text(dump_recipe(dataclasses.replace(recipe, overwrite=False),
                                       base=recipe_path.parent))


def check_recipe(recipe: Recipe) -> None:
    """Raise :class:`AnatomeshError` (one line, naming the setting) for a setting out of range."""
    if not recipe.input:
        raise AnatomeshError("no input scan: give a path (or input.path in a recipe)")
    recipe.formats = [str(f).strip().lower().lstrip(".") for f in recipe.formats]
    bad = [f for f in recipe.formats if f not in FORMATS]
    if bad or not recipe.formats:
        raise AnatomeshError(f"unknown --format {','.join(bad) or '(none)'}; use a comma list of "
                             f"{', '.join(FORMATS)}")
    for name, value, allowed in (("space", recipe.space, SPACES), ("staircase", recipe.staircase, STAIRCASE),
                                 ("profile", recipe.profile, PROFILES)):
        if value not in allowed:
            raise AnatomeshError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
    if not (isinstance(recipe.lod, int) and 0 <= recipe.lod <= 8):
        raise AnatomeshError(f"--lod is the number of GLB levels of detail, 0..8, got {recipe.lod!r}")
    if recipe.decimate is not None and recipe.target_faces is not None:
        raise AnatomeshError("give --decimate RATIO or --target-faces N, not both (--max-error MM "
                             "may come with either as a cap on the error)")
    if recipe.decimate is not None and not 0.0 < recipe.decimate <= 1.0:
        raise AnatomeshError(f"--decimate is the fraction of faces kept, in (0, 1], got {recipe.decimate}")
    if recipe.target_faces is not None and (int(recipe.target_faces) != recipe.target_faces
                                            or recipe.target_faces < 4):
        raise AnatomeshError(f"--target-faces must be a whole number >= 4, got {recipe.target_faces}")
    if not isinstance(recipe.fuse, list) or not all(isinstance(g, list) for g in recipe.fuse):
        raise AnatomeshError(f"fuse must be a list of label groups (lists of values or names), got {recipe.fuse!r}")
    for name in ("max_error", "min_wall", "min_gap", "max_deviation", "damping_distance", "clearance"):
        value = getattr(recipe, name)
        if value is not None and not value > 0:
            raise AnatomeshError(f"--{name.replace('_', '-')} is a distance in mm and must be > 0, got {value}")
    if recipe.render_samples < 1 or len(recipe.render_size) != 2 or min(recipe.render_size) < 16:
        raise AnatomeshError("render_samples must be >= 1 and render_size two pixel counts >= 16")


def _blender():
    """:mod:`anatomesh.addon.headless` (imports ``bpy``), or a clear error when Blender is missing."""
    try:
        from ..addon import headless
    except ImportError as exc:
        raise AnatomeshError(f"the blend/png outputs need Blender: install its Python module "
                             f"(pip install bpy==5.0.1) or run inside Blender ({exc})") from None
    return headless


# ---------------------------------------------------------------------------------------------
def fix_volume(volume: Volume, recipe: Recipe):
    """Apply the label-map print fixes of ``recipe`` (fuse, thicken) before extraction.

    Returns ``(volume, fixes)``: a fused label keeps the first label's value and colour and is
    named after all of them ("liver+spleen"); ``fixes`` lists what each fix did."""
    from dataclasses import replace

    from ..core.printing.fixes import fuse_labels, thicken_labels

    fixes: List[Dict] = []
    if not (recipe.fuse or recipe.thicken or recipe.clearance is not None):
        return volume, fixes
    if not volume.is_label_map:
        raise AnatomeshError("--fuse, --thicken and --clearance work on label maps; this is a scalar "
                             "scan", volume.meta.get("source"))
    table = dict(volume.labels or {})
    wanted = select_labels(volume, recipe.labels)  # named before fusing renames them
    for group in recipe.fuse:
        values = select_labels(volume, group)
        if not values or len(values) < 2:
            raise AnatomeshError(f"--fuse needs two or more labels in a group, got {group!r}")
        volume, info = fuse_labels(volume, values)
        names = [table[v].name if v in table else str(v) for v in values]
        first = table.get(values[0], LabelInfo(values[0], str(values[0])))
        table[values[0]] = replace(first, name="+".join(names))
        for v in values[1:]:
            table.pop(v, None)
        volume = replace(volume, labels=table)
        fixes.append({"fix": "fuse", **info, "name": "+".join(names)})
        if wanted is not None:
            wanted = list(dict.fromkeys(values[0] if w in values else w for w in wanted))
    if wanted is not None:
        recipe.labels = wanted
    if recipe.thicken:
        from ..core.printing.checks import resolve_profile

        wall = resolve_profile(recipe.profile, recipe.min_wall)["min_wall"]
        volume, info = thicken_labels(volume, wall, labels=wanted)
        fixes.append({"fix": "thicken", **info})
    return volume, fixes


def extract(volume: Volume, recipe: Recipe, progress: Optional[Progress] = None):
    """A SurfaceSet (label map: conforming shells) or a list of isosurface Meshes (scalar scan)."""
    from ..core.extract import isosurfaces, label_surfaces

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
    :func:`anatomesh.core.smooth.driver.smooth_surfaces` (which measures volume change and the distance
    to the unsmoothed surface).
    """
    from ..core.smooth.driver import smooth_mesh, smooth_surfaces

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
        sm, rep = smooth_mesh(m, method, affine=volume.affine, progress=sub(
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


def decimate(surfaces, recipe: Recipe, progress: Optional[Progress] = None,
             default_cap: Optional[float] = None):
    """Decimate a SurfaceSet as a whole (seams stay shared) or each isosurface Mesh.

    A ratio or face-count target is capped by ``recipe.max_error`` or else ``default_cap`` (mm,
    the pipeline passes one voxel): the run stops short rather than exceed it.

    Returns ``(decimated, summary)``; ``summary`` is None without a target, else the target, the
    worst shell's ``hausdorff_mm``/``mean_mm``, the face counts, ``seconds``, ``target_met`` or
    ``error_bound_met`` and ``shells`` {value as text: {faces_before, faces_after, hausdorff_mm,
    mean_mm, volume_change_pct}} (:func:`anatomesh.core.decimate.qem.decimate`).
    """
    from ..core.decimate.qem import decimate_mesh, decimate_surfaces

    target = {k: v for k, v in (("ratio", recipe.decimate), ("target_faces", recipe.target_faces),
                                ("max_error", recipe.max_error)) if v is not None}
    if not target:
        return surfaces, None
    if "target_faces" in target:
        target["target_faces"] = int(target["target_faces"])
    capped_by_default = "max_error" not in target and default_cap is not None
    if capped_by_default:
        target["max_error"] = round(default_cap, 4)
    if hasattr(surfaces, "shells"):
        out, rep = decimate_surfaces(surfaces, progress=progress, **target)
        shells = {_value_key(k): v for k, v in rep["shells"].items()}
        reps = [rep]
    else:
        out, shells, reps = [], {}, []
        total = max(1, sum(m.n_faces for m in surfaces))
        for i, m in enumerate(surfaces):
            if not m.n_faces:
                out.append(m)
                continue
            mine = dict(target)
            if "target_faces" in mine:  # the set's budget, shared by face count
                mine["target_faces"] = max(4, int(round(target["target_faces"] * m.n_faces / total)))
            dm, rep = decimate_mesh(m, progress=sub(progress, i / len(surfaces), (i + 1) / len(surfaces)),
                                    **mine)
            out.append(dm)
            shells[_value_key(m.value)] = next(iter(rep["shells"].values()))
            reps.append(rep)
    summary = {"target": {("ratio" if k == "ratio" else k + ("_mm" if k == "max_error" else "")): v
                          for k, v in target.items()},
               "faces_before": int(sum(r["faces_before"] for r in reps)),
               "faces_after": int(sum(r["faces_after"] for r in reps)),
               "hausdorff_mm": max((float(s["hausdorff_mm"]) for s in shells.values()), default=0.0),
               "mean_mm": max((float(s["mean_mm"]) for s in shells.values()), default=0.0),
               "seconds": float(sum(r["seconds"] for r in reps)), "shells": shells}
    if capped_by_default:
        summary["target"]["max_error_mm_source"] = "default cap: one voxel"
    for flag in ("target_met", "error_bound_met"):
        if any(flag in r for r in reps):
            summary[flag] = all(r.get(flag, True) for r in reps)
    return out, summary


def _value_key(value) -> str:
    """Report key of a label value or isovalue (``5`` not ``5.0``)."""
    if value is None:
        return "None"
    v = float(value)
    return str(int(v)) if v.is_integer() else str(v)


def scan_stem(volume: Volume, recipe: Recipe) -> str:
    """A file-name slug of the scan's name (``example_seg.nii.gz`` → ``example_seg``)."""
    src = volume.meta.get("source") or recipe.input
    if isinstance(src, (list, tuple)):
        src = Path(str(src[0])).parent if len(src) > 1 else src[0]
    base = Path(str(src).rstrip("/\\")).name or "scan"
    for suffix in (".nii.gz", ".nii", ".seg.nrrd", ".nrrd", ".nhdr", ".dcm"):
        if base.lower().endswith(suffix) and len(base) > len(suffix):
            base = base[: -len(suffix)]
            break
    return _slug(base)


def _clean(m: Mesh, recipe: Recipe) -> Dict:
    """Apply keep-largest / min-component to ``m`` in place; returns what was dropped."""
    dropped = []
    if m.n_faces and (recipe.keep_largest or recipe.min_component_mm3 > 0):
        comps = topolib.component_measures(m.vertices, m.faces)
        keep = []
        for i, c in enumerate(comps):
            if (recipe.keep_largest and i > 0) or abs(c["volume_mm3"]) < recipe.min_component_mm3:
                dropped.append({"volume_mm3": round(c["volume_mm3"], 3), "area_mm2": round(c["area_mm2"], 3),
                                "faces": int(len(c["faces"]))})
            else:
                keep.append(c["faces"])
        if dropped:
            faces = m.faces[np.sort(np.concatenate(keep))] if keep else m.faces[:0]
            v, f, n, used = meshlib.compact(m.vertices, faces, m.normals)
            m.vertices, m.faces, m.normals = v, f, n
            if m.meta.get("vertex_ids") is not None:  # index into the SurfaceSet stays valid
                m.meta["vertex_ids"] = np.asarray(m.meta["vertex_ids"])[used]
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
        plans.append({fmt: out_dir / f"{stem}.{fmt}" for fmt in recipe.formats if fmt in SURFACE_FORMATS})
    return plans


def _plan_scene_files(stem: str, files: List[Dict[str, Path]], recipe: Recipe,
                      out_dir: Path) -> Dict[str, Path]:
    """Whole-scene outputs: the combined 3MF, the GLB, the .blend and the PNG, ``<stem>.<fmt>``."""
    taken = {p for fs in files for p in fs.values()}
    name = stem if all(out_dir / f"{stem}.{fmt}" not in taken for fmt in ("3mf", "glb")) else f"{stem}_all"
    return {fmt: out_dir / f"{name}.{fmt}" for fmt in ("3mf",) + SCENE_ONLY_FORMATS
            if fmt in recipe.formats}


def write_outputs(surfaces: List[Mesh], files: List[Dict[str, Path]], scene_files: Dict[str, Path],
                  title: str, progress: Optional[Progress] = None) -> None:
    """Write every per-surface file, then the combined 3MF and the GLB (not blend/png)."""
    from ..core.export.mesh_files import write_mesh

    scene = _scene_writers([f for fs in files for f in fs] + [f for f in scene_files if f in ("3mf", "glb")])
    for i, (m, fs) in enumerate(zip(surfaces, files)):
        for fmt, path in fs.items():
            if fmt in scene:
                scene[fmt]([m], path, title=m.name)
            else:
                write_mesh(m, path, fmt)
        report(progress, (i + 1) / max(1, len(surfaces)) * 0.8, f"wrote {m.name}")
    for fmt in ("3mf", "glb"):
        if fmt in scene_files:
            scene[fmt](surfaces, scene_files[fmt], title=title)
    report(progress, 1.0, "files written")


def write_lods(final, recipe: Recipe, paths: List[Path], title: str, base: Path,
               progress: Optional[Progress] = None) -> List[Dict]:
    """Levels of detail of the final surfaces as GLB files, ``paths[0]`` the finest.

    One progressive decimation run per SurfaceSet (seams shared at every level) or per isosurface
    Mesh (:func:`anatomesh.core.decimate.progressive.progressive`), levels at face ratios 1, 1/2, 1/4, ...; returns
    per file ``{file, faces, hausdorff_mm, mean_mm}`` (the worst shell's distances to level 0).
    """
    if not paths:
        return []
    from ..core.export import SCENE_FORMATS
    from ..core.decimate.progressive import progressive

    ratios = [0.5 ** i for i in range(len(paths) - 1, 0, -1)]  # coarsest first, 1.0 implied
    sources = [final] if hasattr(final, "shells") else [m for m in final if m.n_faces]
    pms = [progressive(src, face_ratios=ratios, progress=sub(progress, i / len(sources), (i + 1) / len(sources)))
           for i, src in enumerate(sources)]
    out = []
    for i, path in enumerate(paths):
        meshes, worst = [], {"hausdorff_mm": 0.0, "mean_mm": 0.0}
        for pm in pms:
            k = pm.n_levels - 1 - min(i, pm.n_levels - 1)
            level = pm.level(k)
            meshes += level.shells() if hasattr(level, "shells") else [level]
            for sh in pm.measure(k).values():
                worst = {key: max(worst[key], float(sh[key])) for key in worst}
        for m in meshes:
            _clean(m, recipe)
        SCENE_FORMATS["glb"](meshes, path, title=f"{title} lod{i}")
        out.append({"file": _rel(path, base.resolve()), "faces": int(sum(m.n_faces for m in meshes)),
                    **{k: round(v, 4) for k, v in worst.items()}})
    return out


def _scene_writers(formats) -> Dict:
    need = sorted({f for f in formats if f in ("3mf", "glb")})
    if not need:
        return {}
    try:
        from ..core.export import SCENE_FORMATS
    except ImportError:
        SCENE_FORMATS = {}
    missing = [f for f in need if f not in SCENE_FORMATS]
    if missing:
        raise AnatomeshError(f"{', '.join(missing)} output is not available in this installation "
                             "(anatomesh.core.export.SCENE_FORMATS); use stl, ply or obj")
    return {f: SCENE_FORMATS[f] for f in need}


def _refuse_overwrite(paths: List[Path], overwrite: bool) -> None:
    existing = [p for p in paths if p.exists()]
    if existing and not overwrite:
        raise AnatomeshError(f"{len(existing)} output file(s) already exist (e.g. {existing[0]}); "
                             "pass --overwrite to replace them or choose another --out folder")


def build_report(volume: Volume, recipe: Recipe, surfaces: List[Mesh], entries: List[Dict],
                 files: List[Dict[str, Path]], report_path: Path, timings: Dict,
                 smoothing: Optional[Dict] = None, *, decimation: Optional[Dict] = None,
                 scene_files: Optional[Dict[str, Path]] = None,
                 print_check: Optional[Dict] = None) -> Dict:
    """The JSON report: space, units, input facts, recipe, smoothing, decimation, files and one
    entry per surface (and ``print_check``, :func:`~anatomesh.core.printing.checks.check_parts`'s report).

    With smoothing, each surface also has ``volume_change_pct``, ``max_deviation_mm`` and
    ``mean_deviation_mm`` (symmetric Hausdorff and mean distance to the unsmoothed surface) and
    ``topology_changed``. With decimation, ``faces_before``, ``decimation_max_error_mm``,
    ``decimation_mean_error_mm`` (symmetric Hausdorff and mean distance to the smoothed surface)
    and ``decimation_volume_change_pct``.
    """
    smoothing = smoothing or {"method": SMOOTH_NONE, "params": {}, "shells": {}, "warnings": []}
    base = report_path.parent.resolve()
    facts = describe(volume)
    facts.pop("histogram", None)
    out = {"space": volume.space, "units": "mm", "input": facts,
           "recipe": {k: v for k, v in asdict(recipe).items()},
           "smoothing": {"preset": recipe.smooth,
                         **{k: smoothing.get(k) for k in ("method", "params", "seconds", "warnings")}},
           "decimation": _decimation_summary(decimation),
           "files": {fmt: _rel(p, base) for fmt, p in (scene_files or {}).items()},
           "timings": {k: round(v, 4) for k, v in timings.items()},
           "surfaces": []}
    out["files"].update(report=_rel(report_path, base), recipe=_rel(report_path.parent / RECIPE_FILE, base))
    for m, extra, fs in zip(surfaces, entries, files):
        topo = topolib.topology(m.vertices, m.faces)
        comps = topolib.face_components(m.faces, m.n_vertices)[0] if m.n_faces else 0
        out["surfaces"].append({
            "value": m.value, "name": m.name, "color": list(m.color),
            "files": {fmt: _rel(p, base) for fmt, p in fs.items()},
            "vertices": topo.vertices, "faces": topo.faces,
            "volume_mm3": round(meshlib.signed_volume(m.vertices, m.faces), 3),
            "area_mm2": round(meshlib.surface_area(m.vertices, m.faces), 3),
            "closed": topo.closed, "manifold": topo.manifold, "oriented": topo.oriented,
            "euler": topo.euler, "genus": topo.genus, "components": comps,
            "degenerate_faces": topo.degenerate_faces, **_smoothing_fields(smoothing, m),
            **_decimation_fields(decimation, m), **extra})
    if print_check is not None:
        out["print_check"] = print_check
    return out


def _decimation_summary(decimation: Optional[Dict]) -> Optional[Dict]:
    if decimation is None:
        return None
    out = {k: v for k, v in decimation.items() if k != "shells"}
    for k in ("hausdorff_mm", "mean_mm", "seconds"):
        out[k] = round(float(out[k]), 4)
    return out


def _decimation_fields(decimation: Optional[Dict], m: Mesh) -> Dict:
    shell = (decimation or {}).get("shells", {}).get(_value_key(m.value))
    if not shell:
        return {}
    return {"faces_before": int(shell["faces_before"]),
            "decimation_max_error_mm": round(float(shell["hausdorff_mm"]), 4),
            "decimation_mean_error_mm": round(float(shell["mean_mm"]), 4),
            "decimation_volume_change_pct": round(float(shell["volume_change_pct"]), 4)}


def _json_default(obj):
    """numpy scalars and arrays in the report (e.g. from the print checks) as plain JSON."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


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
