"""The stages of the one flow, each a function of (input, :class:`~anatomesh.app.flow.recipe.Recipe`).

:func:`anatomesh.app.flow.run.run` chains them for the CLI, recipes, batch runs and ``blender -b``; the
Blender panels call the very same functions for the same settings, so every door gives the same
surfaces:

=======================  ======================================================================
:func:`read`             the recipe's input as a Volume (or a Segmentation of layers)
:func:`prepare_volume`   print fixes on a label map before extraction (fuse labels, thicken)
:func:`extract`          a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`: conforming
                         shells of a label map, or one isosurface per level of a scan, styled
:func:`style`            colours, materials, opacities from the style table; touching
                         structures' colours moved apart
:func:`drop_specks`      an isosurface set without its specks (before smoothing)
:func:`smoothing`        the smoothing driver's method and settings for a recipe
:func:`smooth`           the default (guarded) smoothing of the whole set
:func:`decimate`         quadric decimation of the whole set (seams stay shared)
:func:`shells`           one closed Mesh per label/level (the clearance fix pulls touching parts
                         apart), pinch points resolved, small components dropped as asked
:func:`output_shells`    the shells as every writer shows them (pinch points resolved)
:func:`layers_of`        the label-map layers of a Segmentation (overlapping structures), each
                         run through the stages on its own
:func:`merge_reports`    one smoothing/decimation report for all layers
=======================  ======================================================================
"""
from __future__ import annotations

import dataclasses
from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from ...core.decimate.qem import decimate_surfaces
from ...core.geometry.pinches import pinch_gap_mm, separate_shells
from ...core.geometry.topology import component_sizes
from ...core.model.errors import AnatomeshError
from ...core.model.labels import LabelInfo, select_labels
from ...core.model.mesh import Mesh, compact
from ...core.model.progress import Progress
from ...core.model.segmentation import Segmentation, as_layers
from ...core.model.surfaceset import SurfaceSet
from ...core.model.volume import Volume
from ...core.printing.profiles import PROFILES as PRINTER_PROFILES, resolve_profile
from .recipe import CONTOURS_TILE, SMOOTH_NONE, Recipe

# speed: each stage imports its room when it runs, so a command loads only what it uses
# (no smoothing for --smooth none, no decimation without a target, no print fixes unasked)


def read(recipe: Recipe, progress: Optional[Progress] = None) -> Union[Volume, Segmentation]:
    """The recipe's input as a Volume (or a Segmentation of layers), read with its ``[input]``
    settings: series, 4D volume, label table, space and grid."""
    from ...core.io import load

    return load(recipe.input, series=recipe.series, volume_index=recipe.volume_index,
                labels=recipe.label_table, space=recipe.space, grid=recipe.grid, progress=progress)


def prepare_volume(volume: Volume, recipe: Recipe) -> Tuple[Volume, List[Dict]]:
    """Apply the label-map print fixes of ``recipe`` (fuse, thicken) before extraction.

    Returns ``(volume, fixes)``: a fused label keeps the first label's value and colour and is
    named after all of them ("liver+spleen"); ``fixes`` lists what each fix did. ``recipe.labels``
    is rewritten to the fused values."""
    fixes: List[Dict] = []
    if not (recipe.fuse or recipe.thicken or recipe.clearance is not None):
        return volume, fixes
    if not volume.is_label_map:
        raise AnatomeshError("--fuse, --thicken and --clearance work on label maps; this is a scalar "
                             "scan", volume.meta.get("source"))
    wanted = select_labels(volume, recipe.labels)  # named before fusing renames them
    for group in recipe.fuse:
        volume, wanted, fix = _fuse(volume, group, wanted)
        fixes.append(fix)
    if wanted is not None:
        recipe.labels = wanted
    if recipe.thicken:
        wall = resolve_profile(recipe.profile, recipe.min_wall)["min_wall"]
        from ...core.printing import fixes as printfix
        volume, info = printfix.thicken_labels(volume, wall, labels=wanted)
        fixes.append({"fix": "thicken", **info})
    return volume, fixes


def _fuse(volume: Volume, group, wanted):
    values = select_labels(volume, group)
    if not values or len(values) < 2:
        raise AnatomeshError(f"--fuse needs two or more labels in a group, got {group!r}")
    table = dict(volume.labels or {})
    from ...core.printing import fixes as printfix
    volume, info = printfix.fuse_labels(volume, values)
    names = [table[v].name if v in table else str(v) for v in values]
    first = table.get(values[0], LabelInfo(values[0], str(values[0])))
    table[values[0]] = dataclasses.replace(first, name="+".join(names))
    for v in values[1:]:
        table.pop(v, None)
    if wanted is not None:
        wanted = list(dict.fromkeys(values[0] if w in values else w for w in wanted))
    return dataclasses.replace(volume, labels=table), wanted, {"fix": "fuse", **info, "name": "+".join(names)}


def extract(volume: Volume, recipe: Recipe, progress: Optional[Progress] = None) -> SurfaceSet:
    """The surfaces of ``volume`` as one SurfaceSet: a label map's conforming shells (the labels
    of ``recipe.labels``), or a scan's isosurfaces at ``recipe.levels`` (one label per level)."""
    source = volume.meta.get("source")
    if recipe.contours == CONTOURS_TILE and volume.meta.get("contours"):
        return style(tiled_surfaces(volume, recipe), recipe)
    if volume.is_label_map:
        if recipe.levels:
            raise AnatomeshError("--level is for scalar scans; this is a label map (use --labels)", source)
        from ...core.extract.multilabel import label_surfaces

        return style(label_surfaces(volume, values=select_labels(volume, recipe.labels),
                                    progress=progress), recipe)
    if not recipe.levels:
        raise AnatomeshError("this is a scalar scan: give one or more isovalues with --level "
                             "(see `anatomesh inspect` for the histogram peaks)", source)
    from ...core.extract.isosurface import isosurfaces

    meshes = isosurfaces(volume, list(recipe.levels), cap=recipe.cap, progress=progress)
    for m, name in zip(meshes, recipe.level_names):
        m.name = name
    return style(SurfaceSet.from_meshes(meshes, volume.affine, volume.space), recipe)


def style(surfaces: SurfaceSet, recipe: Recipe) -> SurfaceSet:
    """``surfaces`` with each label's colour, material class and opacity from the recipe's style
    table (``recipe.style`` over the default, :mod:`anatomesh.core.model.style`), then the colours
    of touching structures moved apart to CIE76 ΔE >= 12 (two bones: a small step;
    :func:`anatomesh.core.model.contrast.separate_colors`). Colours the user gave (a colour
    table, DICOM display colours, a colour in the style file) stay as they are; names the style
    table does not know keep their colour. Every door shows these colours."""
    from ...core.model.contrast import separate_colors, touching_pairs
    from ...core.model.labels import fixed_colors, style_table
    from ...core.model.style import load_style

    if not surfaces.labels:
        return surfaces
    table = load_style(recipe.style)
    labels = style_table(surfaces.labels, table)
    fixed = fixed_colors(labels, table)
    surfaces.labels = separate_colors(labels, touching_pairs(surfaces), fixed=fixed)
    return surfaces


def drop_specks(surfaces: SurfaceSet) -> SurfaceSet:
    """Independent surfaces (isosurfaces, fuzzy shells, tiled contours: no voxel lattice)
    without their specks, the components under :data:`SPECK_VOXELS` of a voxel (blobs around
    single voxels barely above a level), dropped where they are made, before smoothing, so every
    door starts from the same surfaces; the set's warnings count them. A label map's shells
    (whole voxels) come back as they are."""
    if surfaces.lattice is not None or not surfaces.n_faces:
        return surfaces
    meshes = surfaces.shells()
    voxel = voxel_volume(surfaces)
    dropped = [len(clean(m, Recipe(), voxel, SPECK_VOXELS)["dropped_components"]) for m in meshes]
    if not any(dropped):
        return surfaces
    out = SurfaceSet.from_meshes(meshes, surfaces.affine, surfaces.space)
    out.warnings = list(surfaces.warnings) + [
        f"{n} speck(s) of {m.name} dropped (components under {SPECK_VOXELS:g} voxel)"
        for m, n in zip(meshes, dropped) if n]
    return out


def smoothing(recipe: Recipe) -> Tuple[str, Dict]:
    """``(method, settings)`` of the smoothing driver for ``recipe``: the preset or filter name and
    the keyword arguments of :func:`anatomesh.core.smooth.driver.smooth_surfaces` (iterations,
    λ, μ, max deviation, damping distance, staircase)."""
    settings = recipe.smoothing_overrides()
    settings.update(max_deviation=recipe.max_deviation, damping_distance=recipe.damping_distance,
                    staircase={"auto": "auto", "on": True, "off": False}[recipe.staircase])
    return recipe.smooth or SMOOTH_NONE, settings


def smooth(surfaces: SurfaceSet, recipe: Recipe,
           progress: Optional[Progress] = None) -> Tuple[SurfaceSet, Dict]:
    """The whole set smoothed at once (seams move once, for both labels) with the default guards
    (fold guard, volumes restored, untangle); returns the new set and the smoothing report as a
    dict (``method``, ``params``, ``seconds``, ``shells`` keyed by the shell's value, ``warnings``)."""
    method, settings = smoothing(recipe)
    if method == SMOOTH_NONE:
        return surfaces, {"method": SMOOTH_NONE, "params": {}, "shells": {}, "warnings": []}
    from ...core.smooth.driver import smooth_surfaces
    # the run's report gives each output surface's topology itself (after any decimation)
    out, rep = smooth_surfaces(surfaces, method, progress=progress, topology=False, **settings)
    return out, rep.as_dict()


def decimation_target(recipe: Recipe, default_cap: Optional[float] = None) -> Tuple[Dict, bool]:
    """The keyword arguments of :func:`anatomesh.core.decimate.qem.decimate_surfaces` for the
    recipe's target (``ratio``, ``target_faces``, ``max_error``; empty: no decimation), a ratio
    or face count capped by ``default_cap`` mm when no ``max_error`` is given; and whether that
    cap was added."""
    target = {k: v for k, v in (("ratio", recipe.decimate), ("target_faces", recipe.target_faces),
                                ("max_error", recipe.max_error)) if v is not None}
    if "target_faces" in target:
        target["target_faces"] = int(target["target_faces"])
    by_default = bool(target) and "max_error" not in target and default_cap is not None
    if by_default:
        target["max_error"] = round(default_cap, 4)
    return target, by_default


def one_voxel(surfaces: SurfaceSet) -> float:
    """The default cap of decimation's error: one voxel (the largest spacing of the set's
    affine), mm."""
    return float(np.linalg.norm(np.asarray(surfaces.affine, np.float64)[:3, :3], axis=0).max())


def decimate(surfaces: SurfaceSet, recipe: Recipe, default_cap: Optional[float] = None,
             progress: Optional[Progress] = None) -> Tuple[SurfaceSet, Optional[Dict]]:
    """Decimate the whole set (seams stay shared, shells closed) to the recipe's target.

    A ratio or face-count target is capped by ``recipe.max_error`` or else ``default_cap`` (mm,
    the run passes one voxel): the run stops short rather than exceed it. Returns
    ``(surfaces, summary)``; ``summary`` is None without a target, else the target, face counts,
    the worst shell's ``hausdorff_mm``/``mean_mm``, ``seconds``, ``target_met`` or
    ``error_bound_met``, and ``shells`` keyed by the shell's value."""
    target, by_default = decimation_target(recipe, default_cap)
    if not target:
        return surfaces, None
    out, rep = decimate_surfaces(surfaces, progress=progress, **target)
    summary = {k: rep[k] for k in ("faces_before", "faces_after", "seconds") if k in rep}
    summary["target"] = {(k + "_mm" if k == "max_error" else k): v for k, v in target.items()}
    if by_default:
        summary["target"]["max_error_mm_source"] = "default cap: one voxel"
    shells = {value_key(surfaces.shell_values.get(int(k), k)): v for k, v in rep["shells"].items()}
    summary["hausdorff_mm"] = max((float(s["hausdorff_mm"]) for s in shells.values()), default=0.0)
    summary["mean_mm"] = max((float(s["mean_mm"]) for s in shells.values()), default=0.0)
    summary["shells"] = shells
    for flag in ("target_met", "error_bound_met"):
        if flag in rep:
            summary[flag] = bool(rep[flag])
    return out, summary


def shells(surfaces: SurfaceSet, recipe: Recipe) -> Tuple[List[Mesh], List[Dict], Optional[Dict], Dict]:
    """One closed Mesh per label (or level), as files show it: pulled apart along shared
    interfaces by the clearance fix when ``recipe.clearance`` (mm) is set, pinch points resolved
    (:func:`output_shells`), then cleaned as the recipe asks (``keep_largest``,
    ``min_component_mm3``). Returns the meshes, what cleaning dropped per mesh, the clearance
    fix's entry (None without it) and the pinch points' entry."""
    fix = None
    if recipe.clearance is not None:
        from ...core.printing import fixes as printfix
        meshes, info = printfix.separate_parts(surfaces, recipe.clearance)
        fix = {"fix": "clearance", **info}
        pinches = separate_shells(surfaces, meshes, pinch_gap_mm(surfaces.affine))
    else:
        meshes, pinches = output_shells(surfaces)
    voxel = voxel_volume(surfaces)
    return meshes, [clean(m, recipe, voxel) for m in meshes], fix, pinches


def voxel_volume(surfaces: SurfaceSet) -> float:
    """The volume of one voxel of the set's grid, mm³."""
    return float(abs(np.linalg.det(np.asarray(surfaces.affine, np.float64)[:3, :3])))


def output_shells(surfaces: SurfaceSet) -> Tuple[List[Mesh], Dict]:
    """The shells of ``surfaces`` as every writer and the Blender scene show them: where a label
    touches itself along a voxel edge or at a corner, the touching parts are moved a small stated
    gap apart (:mod:`anatomesh.core.geometry.pinches`), so each file is 2-manifold when read back
    by position. Returns the meshes and the report's ``pinch_points`` entry."""
    meshes = surfaces.shells()
    return meshes, separate_shells(surfaces, meshes, pinch_gap_mm(surfaces.affine))


#: components enclosing less than this fraction of one voxel are specks, dropped where they are
#: made, at extraction (an isosurface's blob around one voxel barely above the level; a label
#: map's components are whole voxels)
SPECK_VOXELS = 0.1
#: kept components smaller than this are listed in the report (``small_components_mm3``): the
#: loose shells a print check reports (the largest profile's smallest shell worth printing)
SMALL_COMPONENT_MM3 = max(p["min_shell_mm3"] for p in PRINTER_PROFILES.values())


def clean(m: Mesh, recipe: Recipe, voxel_mm3: float = 0.0, speck_voxels: Optional[float] = None) -> Dict:
    """Drop from ``m`` (in place) its specks (components under ``speck_voxels`` of ``voxel_mm3``)
    and what keep-largest / min-component ask; returns the report's entries:
    ``dropped_components`` (volume, area, faces, why) and ``small_components_mm3`` (the kept
    components under :data:`SMALL_COMPONENT_MM3`, mm³).

    By default a speck here is what is left under :data:`SPECK_VOXELS` once smoothing may have
    taken its share: the component guard keeps every component within its bound of the volume
    extraction gave it, so what extraction kept stays kept, in every door, and only the specks of
    another extraction (fuzzy shells, precise surfaces) are dropped here."""
    if speck_voxels is None:
        from ...core.smooth.components import DEFAULT_BOUND_PCT

        speck_voxels = SPECK_VOXELS * (1.0 - DEFAULT_BOUND_PCT / 100.0)
    if not m.n_faces:
        return {"dropped_components": [], "small_components_mm3": []}
    lab, volumes, areas = component_sizes(m.vertices, m.faces)
    size = np.abs(volumes)
    why = np.full(size.size, "", object)
    why[size < recipe.min_component_mm3] = "min_component"
    if recipe.keep_largest:
        why[np.arange(size.size) != np.argmax(size)] = "keep_largest"
    why[size < speck_voxels * voxel_mm3] = "speck"
    drop = why != ""
    order = np.argsort(-size, kind="stable")
    counts = np.bincount(lab, minlength=size.size)
    dropped = [{"volume_mm3": round(float(volumes[c]), 6), "area_mm2": round(float(areas[c]), 3),
                "faces": int(counts[c]), "why": str(why[c])} for c in order if drop[c]]
    small = [round(float(size[c]), 4) for c in order if not drop[c] and size[c] < SMALL_COMPONENT_MM3]
    if dropped:
        faces = m.faces[~drop[lab]]
        m.vertices, m.faces, m.normals, used = compact(m.vertices, faces, m.normals)
        if m.meta.get("vertex_ids") is not None:  # index into the SurfaceSet stays valid
            m.meta["vertex_ids"] = np.asarray(m.meta["vertex_ids"])[used]
    return {"dropped_components": dropped, "small_components_mm3": small}


def value_key(value) -> str:
    """Report key of a label value or isovalue (``5`` not ``5.0``)."""
    if value is None:
        return "None"
    v = float(value)
    return str(int(v)) if v.is_integer() else str(v)


# --- distance colouring ---------------------------------------------------------------
def distance_colors(meshes: List[Mesh], recipe: Recipe) -> Optional[Dict]:
    """Colour ``meshes`` in place by their distance to ``recipe.distance_to`` (a name or value)
    within ``recipe.margins`` mm (:func:`anatomesh.core.geometry.margins.color_by_distance`);
    returns its summary, or None when no target is set."""
    if recipe.distance_to is None:
        return None
    from ...core.geometry.margins import color_by_distance

    _, summary = color_by_distance(meshes, recipe.distance_to, recipe.margins)
    return summary


# -- segmentations with overlapping structures (masks, DICOM SEG, RTSTRUCT) -----------------------
def layers_of(volume: Union[Volume, Segmentation], recipe: Recipe) -> List[Tuple[Volume, Recipe]]:
    """The label-map layers to run the stages on, each with the recipe restricted to the
    structures it holds (``recipe.labels`` resolved against every layer's names). A Volume is
    one layer; layers holding none of the chosen structures are left out. With
    ``recipe.contours == "tile"`` and RT contours, one entry (extraction tiles the contours)."""
    layers = as_layers(volume)
    if recipe.fuse and len(layers) > 1:
        raise AnatomeshError("--fuse merges labels of one label map; these structures overlap and "
                             "lie in separate layers: mesh them without --fuse", volume.meta.get("source"))
    if len(layers) == 1 or (recipe.contours == CONTOURS_TILE and volume.meta.get("contours")):
        return [(layers[0], recipe)]
    whole = Volume(layers[0].data[:0, :0, :0], layers[0].affine, layers[0].space, dict(volume.meta),
                   volume.labels)
    wanted = select_labels(whole, recipe.labels)
    out = []
    for layer in layers:
        values = [v for v in (layer.labels or {}) if wanted is None or v in wanted]
        if values:
            out.append((layer, dataclasses.replace(recipe, labels=values)))
    return out


def tiled_surfaces(volume: Volume, recipe: Recipe) -> SurfaceSet:
    """RT contours tiled directly into one closed surface per ROI (:mod:`anatomesh.core.extract.contours`)
    as a set of independent surfaces."""
    from ...core.extract.contours import tile_rois

    rois = volume.meta["contours"]
    wanted = select_labels(Volume(volume.data[:0, :0, :0], volume.affine, volume.space, volume.meta,
                                  volume.labels), recipe.labels)
    meshes = tile_rois([r for r in rois if wanted is None or r.info.value in wanted], space=volume.space)
    return SurfaceSet.from_meshes(meshes, volume.affine, volume.space)


def merge_reports(smoothing: List[Dict], decimation: List[Optional[Dict]]) -> Tuple[Dict, Optional[Dict]]:
    """One smoothing report and one decimation summary for several layers (shells are keyed by
    their unique value; times and face counts add up; errors take the worst layer)."""
    if len(smoothing) == 1:
        return smoothing[0], decimation[0]
    sm = dict(smoothing[0], shells={}, warnings=[])
    for rep in smoothing:
        sm["shells"].update(rep.get("shells") or {})
        sm["warnings"] += list(rep.get("warnings") or [])
    if any("seconds" in rep for rep in smoothing):
        sm["seconds"] = sum(rep.get("seconds", 0.0) for rep in smoothing)
    decs = [d for d in decimation if d]
    if not decs:
        return sm, None
    dec = dict(decs[0], shells={})
    for key in ("faces_before", "faces_after", "seconds"):
        dec[key] = sum(d.get(key, 0) for d in decs)
    for key in ("hausdorff_mm", "mean_mm"):
        dec[key] = max(d[key] for d in decs)
    for flag in ("target_met", "error_bound_met"):
        if flag in dec:
            dec[flag] = all(d.get(flag, True) for d in decs)
    for d in decs:
        dec["shells"].update(d["shells"])
    return sm, dec
