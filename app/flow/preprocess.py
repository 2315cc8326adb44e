"""Preprocessing in the flow: the steps before and around extraction, each with its measured
effect on the surface.

Order (each only when the recipe asks for it):

* the region of interest (``roi``): the scan is cut to it first; the cut scan is the reference
  "without preprocessing" for everything below;
* scalar scans: ``resample`` (:mod:`anatomesh.core.preprocess.resample`), then ``smooth_volume``
  (:mod:`anatomesh.core.preprocess.filters`);
* label maps: ``interpolate`` (shape-based, :mod:`anatomesh.core.preprocess.interpolate`), then
  ``fill_cavities`` and ``close_handles`` (:mod:`anatomesh.core.preprocess.label_topology`);
* extraction: ``fuzzy_boundary`` (label maps; :mod:`anatomesh.core.preprocess.fuzzy_boundary`,
  each label's fuzzy field at 0.5), ``fuzzy`` (scalar scans; nested shells,
  :mod:`anatomesh.core.extract.fuzzy`), ``precise`` (:mod:`anatomesh.core.extract.precise`).

Every step's effect is measured on the surfaces: the raw surfaces (same labels or levels) are
extracted before and after it and compared per surface (symmetric Hausdorff and mean distance in
mm, :func:`anatomesh.core.geometry.measure.surface_distance`; the topology steps add genus and
component counts). With ``difference_colors`` the final surfaces are coloured by their signed
distance to the surfaces the same run makes without preprocessing (:mod:`.difference`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from ...core.extract.fuzzy import fuzzy_isosurfaces, fuzzy_levels
from ...core.extract.isosurface import isosurfaces
from ...core.extract.precise import refine
from ...core.model.errors import AnatomeshError
from ...core.model.labels import LabelInfo, select_labels
from ...core.model.progress import Progress, report, sub
from ...core.model.surfaceset import SurfaceSet
from ...core.model.volume import Volume
from ...core.preprocess import filters, label_topology
from ...core.preprocess.fuzzy_boundary import ISOVALUE, fuzzy_boundary
from ...core.preprocess.interpolate import interpolate_labels
from ...core.preprocess.resample import crop, resample, roi_bounds
from . import stages
from .difference import color_differences, compare_sets
from .preprocess_settings import active, parse_smooth_volume
from .recipe import Recipe

SCALAR_ONLY = ("resample", "smooth_volume", "fuzzy", "precise")
LABEL_ONLY = ("interpolate", "fuzzy_boundary", "fill_cavities", "close_handles")


@dataclass
class Preprocessing:
    """What preprocessing did: ``base`` the scan as read, cut to the ROI (the reference without
    preprocessing), ``volume`` after every volume step, ``steps`` one report dict per step,
    ``surfaces`` the raw surfaces of ``volume`` when measuring made them already."""

    base: Volume
    volume: Volume
    steps: List[Dict] = field(default_factory=list)
    surfaces: Optional[SurfaceSet] = None
    input: Dict = field(default_factory=dict)
    difference: Optional[Dict] = None

    def summary(self) -> Dict:
        """The report's ``preprocess`` section."""
        out = {"input": self.input, "steps": self.steps}
        if self.difference is not None:
            out["difference"] = self.difference
        return out


def prepare(volume: Volume, recipe: Recipe, progress: Optional[Progress] = None) -> Tuple[Volume, Optional[Preprocessing]]:
    """Run the recipe's volume steps on ``volume``, measuring each one's effect (module doc).

    Returns ``(volume, preprocessing)``; ``(volume, None)`` when nothing is asked."""
    if not active(recipe):
        return volume, None
    _check_kind(volume, recipe)
    pre = Preprocessing(volume, volume, input={"shape": list(volume.shape),
                                               "spacing": [round(s, 6) for s in volume.spacing]})
    if recipe.roi is not None:
        t0 = time.perf_counter()
        pre.base = pre.volume = crop(volume, *roi_bounds(volume, recipe.roi, recipe.space))
        pre.steps.append(_entry("roi", {"box_mm": recipe.roi, "space": recipe.space}, t0, pre.volume,
                                {"voxels_kept": int(np.prod(pre.volume.shape))}))
    steps = volume_steps(pre.volume, recipe)
    if steps:
        pre.surfaces = raw_surfaces(pre.volume, recipe)
    for n, (name, params, fn) in enumerate(steps):
        report(progress, n / len(steps), f"preprocessing: {name}")
        t0 = time.perf_counter()
        new, info = fn(pre.volume, sub(progress, n / len(steps), (n + 0.7) / len(steps)))
        entry = _entry(name, params, t0, new, info)
        after = raw_surfaces(new, recipe)
        entry["effect"] = compare_sets(pre.surfaces, after, topology=name in ("fill_cavities", "close_handles"))
        pre.steps.append(entry)
        pre.volume, pre.surfaces = new, after
    report(progress, 1.0, "preprocessing done")
    return pre.volume, pre


def volume_steps(volume: Volume, recipe: Recipe) -> List[Tuple[str, Dict, Callable]]:
    """``(name, params, fn(volume, progress) -> (volume, info))`` of the recipe's volume steps."""
    out = []
    if recipe.resample is not None:
        params = {"spacing_mm": list(recipe.resample), "method": recipe.resample_method}
        out.append(("resample", params, lambda v, p: (resample(
            v, recipe.resample if len(recipe.resample) == 3 else recipe.resample[0],
            recipe.resample_method, progress=p), {})))
    if recipe.smooth_volume is not None:
        name, args = parse_smooth_volume(recipe.smooth_volume)
        out.append(("smooth_volume", {"filter": name, "value": args[0] if len(args) == 1 else args},
                    _smoother(name, args)))
    if recipe.interpolate:
        out.append(("interpolate", {"method": "shape-based: signed distances, cubic B-spline, "
                                              "volumes kept", "spacing_mm": round(min(volume.spacing), 6)},
                    lambda v, p: (interpolate_labels(v, progress=p), {})))
    values = None if not volume.is_label_map else select_labels(volume, recipe.labels)
    if recipe.fill_cavities:
        out.append(("fill_cavities", {}, lambda v, p: _topology_info(
            *label_topology.fill_cavities(v, values, progress=p))))
    if recipe.close_handles is not None:
        out.append(("close_handles", {"size_mm": recipe.close_handles}, lambda v, p: _topology_info(
            *label_topology.close_handles(v, recipe.close_handles, values, progress=p))))
    return out


def _smoother(name: str, args: List[float]) -> Callable:
    value = args[0] if len(args) == 1 else args
    if name == "gaussian":
        return lambda v, p: _with_info(filters.gaussian(v, value))
    if name == "median":
        return lambda v, p: _with_info(filters.median(v, value))
    return lambda v, p: _with_info(filters.diffusion(v, int(args[0]), progress=p))


def _with_info(v: Volume):
    return v, dict(v.meta.get("smoothed", {}))


def _topology_info(volume: Volume, info: Dict[int, Dict]):
    table = volume.labels or {}
    return volume, {"labels": {str(v): dict(i, name=table[v].name if v in table else f"label_{v}")
                               for v, i in info.items()}}


# ---------------------------------------------------------------------------------------------
# extraction
# ---------------------------------------------------------------------------------------------
def raw_surfaces(volume: Volume, recipe: Recipe, progress: Optional[Progress] = None) -> SurfaceSet:
    """The plain surfaces the recipe asks for: the usual extraction (:func:`~.stages.extract`: a
    label map's shells or the isosurfaces at ``recipe.levels``), or the ``fuzzy`` levels' nested
    isosurfaces."""
    if recipe.fuzzy is None:
        return stages.extract(volume, recipe, progress)
    meshes = fuzzy_isosurfaces(volume, *recipe.fuzzy[:2], n=int(_fuzzy_count(recipe)), cap=recipe.cap,
                               progress=progress)
    return SurfaceSet.from_meshes(meshes, volume.affine, volume.space)


def extract(volume: Volume, recipe: Recipe, pre: Optional[Preprocessing],
            progress: Optional[Progress] = None) -> Optional[SurfaceSet]:
    """The surfaces of the preprocessed volume with the extraction-level steps (fuzzy boundary,
    fuzzy shells, precise); None when the recipe asks for none of it (the run's own extraction
    applies). Each step's effect is added to ``pre.steps``."""
    if pre is None or not (recipe.fuzzy_boundary or recipe.fuzzy is not None or recipe.precise
                           or pre.surfaces is not None):
        return None
    plain = pre.surfaces if pre.surfaces is not None else raw_surfaces(volume, recipe, progress)
    pre.surfaces = plain
    if recipe.fuzzy is not None:
        levels, alphas = fuzzy_levels(*recipe.fuzzy[:2], _fuzzy_count(recipe))
        pre.steps.append({"step": "fuzzy", "params": {"interval": recipe.fuzzy[:2],
                                                       "surfaces": _fuzzy_count(recipe)},
                          "levels": [round(float(x), 4) for x in levels],
                          "alphas": [round(float(a), 3) for a in alphas]})
    if recipe.fuzzy_boundary:
        return _fuzzy_boundary(volume, recipe, plain, pre, progress)
    if recipe.precise:
        return _precise(volume, plain, pre)
    return plain


def _fuzzy_boundary(volume, recipe, plain, pre, progress) -> SurfaceSet:
    t0 = time.perf_counter()
    fields = fuzzy_boundary(volume, select_labels(volume, recipe.labels), progress=progress)
    table = {**(volume.labels or {}), **plain.labels}  # the plain surfaces' styled colours
    meshes = []
    for value, fld in fields.items():
        m = isosurfaces(fld, [ISOVALUE], cap=True)[0]
        info = table.get(value) or LabelInfo(value, f"label_{value}")
        m.name, m.value, m.color = info.name, float(value), info.mesh_color()
        m.meta["material"] = info.material
        meshes.append(m)
    out = SurfaceSet.from_meshes(meshes, volume.affine, volume.space)
    entry = _entry("fuzzy_boundary", {"isovalue": ISOVALUE, "steps_voxels": 3}, t0, volume,
                   {"labels": {str(v): f.meta["fuzzy_boundary"] for v, f in fields.items()}})
    entry["effect"] = compare_sets(plain, out)
    voxel = float(max(volume.spacing))
    entry["effect"]["within_one_voxel"] = bool(entry["effect"]["max_mm"] <= voxel + 1e-6)
    entry["effect"]["voxel_mm"] = round(voxel, 4)
    pre.steps.append(entry)
    return out


def _precise(volume: Volume, plain: SurfaceSet, pre: Preprocessing) -> SurfaceSet:
    t0 = time.perf_counter()
    meshes, per = [], {}
    for m in plain.shells():
        m.meta.pop("vertex_ids", None)
        fine, info = refine(m, volume, m.value)
        fine.meta.pop("vertex_ids", None)
        meshes.append(fine)
        per[_key(m.value)] = {"name": m.name, **info}
    out = SurfaceSet.from_meshes(meshes, volume.affine, volume.space)
    worst = max(per.values(), key=lambda d: d["max_moved_mm"], default={})
    pre.steps.append(_entry("precise", {"method": "triangles split onto the trilinear interpolant "
                                                  "(Allamandri et al. 1998)",
                                        "tolerance_mm": worst.get("tolerance_mm")}, t0, volume,
                            {"surfaces": per}))
    pre.steps[-1]["effect"] = {"max_mm": worst.get("max_moved_mm", 0.0),
                               "mean_mm": max((d["mean_moved_all_mm"] for d in per.values()), default=0.0),
                               "faces_before": sum(d["faces_before"] for d in per.values()),
                               "faces_after": sum(d["faces_after"] for d in per.values())}
    return out


def _fuzzy_count(recipe: Recipe) -> int:
    return int(recipe.fuzzy[2]) if len(recipe.fuzzy) == 3 else 5


# ---------------------------------------------------------------------------------------------
def _check_kind(volume: Volume, recipe: Recipe) -> None:
    source = volume.meta.get("source")
    asked = [k for k in (SCALAR_ONLY if volume.is_label_map else LABEL_ONLY)
             if getattr(recipe, k) not in (None, False)]
    if asked:
        flags = ", ".join("--" + k.replace("_", "-") for k in asked)
        if volume.is_label_map:
            raise AnatomeshError(f"{flags}: for scalar scans; this is a label map (use --interpolate, "
                                 "--fuzzy-boundary, --fill-cavities, --close-handles)", source)
        raise AnatomeshError(f"{flags}: for label maps; this is a scalar scan (use --resample, "
                             "--smooth-volume, --fuzzy, --precise)", source)


def _entry(name: str, params: Dict, t0: float, volume: Volume, info: Dict) -> Dict:
    return {"step": name, "params": params, "seconds": round(time.perf_counter() - t0, 4),
            "grid": {"shape": list(volume.shape), "spacing": [round(s, 6) for s in volume.spacing]},
            **({"info": info} if info else {})}


def _key(value) -> str:
    v = float(value)
    return str(int(v)) if v.is_integer() else str(v)


# ---------------------------------------------------------------------------------------------
# after the run's own stages
# ---------------------------------------------------------------------------------------------
def finish(meshes, pre: Optional[Preprocessing], recipe: Recipe,
           progress: Optional[Progress] = None) -> Tuple[Optional[Dict], List[str]]:
    """Colour ``meshes`` (the run's final surfaces) by their difference to the same run without
    preprocessing when ``recipe.difference_colors``; returns ``(report section or None,
    warnings)``. The reference: the ROI-cut scan's plain surfaces, smoothed as the recipe says."""
    if pre is None:
        warn = ["--difference-colors: no preprocessing step was asked, so there is no difference "
                "to colour"] if recipe.difference_colors else []
        return None, warn
    if recipe.difference_colors:
        report(progress, 0.0, "difference colours: the surfaces without preprocessing")
        reference, _ = stages.smooth(raw_surfaces(pre.base, recipe), recipe)
        pre.difference = color_differences(meshes, reference.shells())
        report(progress, 1.0, "difference colours done")
    return pre.summary(), []
