"""The scene's Anatomesh settings as a :class:`~anatomesh.app.flow.recipe.Recipe` and back: the
same settings ``anatomesh mesh --recipe`` reads."""
from __future__ import annotations

import json

import bpy

from .common import abspath, active_scan, load_volume
from .setting_props import group_to_recipe, recipe_to_group

#: the recipe settings the hand-made panels hold (Import, Smooth, Decimate, Print, Print Tools,
#: Cut to Fit, Export, Preprocess); every other one is a generated property in the Settings
#: panel (``Scene.anatomesh_recipe``, :mod:`.setting_props`) unless it is in :data:`NOT_IN_BLENDER`
PANEL_FIELDS = ("input", "series", "label_table", "labels", "levels", "level_names", "space", "grid",
                "smooth", "iterations", "lam", "mu", "max_deviation", "damping_distance", "staircase",
                "decimate", "target_faces", "max_error", "check", "profile", "min_wall", "min_gap",
                "fuse", "thicken", "clearance", "hollow", "drain_holes", "drain_diameter", "connectors",
                "fit", "fit_connectors", "out_dir", "formats",
                "resample", "resample_method", "roi", "smooth_volume", "interpolate", "fuzzy_boundary",
                "fill_cavities", "close_handles", "fuzzy", "precise", "difference_colors")
#: settings of the command line's written files that Blender's objects do not have: where its
#: report goes, replacing files, and dropping components from the files (the objects keep all)
NOT_IN_BLENDER = ("report", "overwrite", "keep_largest", "min_component_mm3")

#: UI export format → core output format
_EXPORT_TO_CORE = {"STL": "stl", "PLY": "ply", "OBJ": "obj", "GLB": "glb", "GLTF": "glb"}


def recipe_from_scene(context):
    """A core ``Recipe`` holding the scene's current Anatomesh settings."""
    s = context.scene.anatomesh
    r = scene_recipe(context.scene)
    r.input, r.series = abspath(s.filepath), s.series or None
    r.label_table, r.space, r.grid = abspath(s.label_table) or None, s.space, s.grid or None
    if s.kind == "LABELS" and len(s.labels):
        chosen = [int(item.value) for item in s.labels if item.include]
        r.labels = "all" if len(chosen) == len(s.labels) else chosen
    elif s.kind == "LEVELS":
        r.levels = [float(item.value) for item in s.levels if item.include]
        r.level_names = [item.name for item in s.levels if item.include]
    coll = active_scan(context)
    st = coll.anatomesh if coll is not None else s
    smoothing_recipe(_smoothing_shown(coll, st), r)
    d = getattr(context.scene, "anatomesh_decimate", None)  # the Decimate panel (decimate_ui)
    if d is not None and coll is not None and "anatomesh_decimation_max_error_mm" in coll:
        # the scan was decimated: the recipe decimates to the panel's target too
        if d.target == "RATIO":
            r.decimate = float(d.ratio)
        elif d.target == "FACES":
            r.target_faces = int(d.faces)
        elif d.max_error > 0:
            r.max_error = float(d.max_error)
    _print_to_recipe(r, getattr(context.scene, "anatomesh_print", None))
    r.out_dir = abspath(s.export_dir) or "anatomesh_out"
    r.formats = [_EXPORT_TO_CORE.get(s.export_format, "stl")]
    pre = getattr(context.scene, "anatomesh_preprocess", None)  # the Preprocess panel
    if pre is not None:
        preprocess_to_recipe(pre, r)
    return r


def scene_recipe(scene):
    """A Recipe holding the scene's generated settings (the Settings panel), the rest default."""
    from ...app.flow.recipe import Recipe

    r = Recipe()
    group = getattr(scene, "anatomesh_recipe", None)
    if group is not None:
        group_to_recipe(group, r)
    return r


#: custom property of a scan collection (JSON): the smoothing settings of the shape that became
#: its unsmoothed copy (Apply, decimation, the print tools: :func:`.smooth.bake`)
BAKED_PROPERTY = "anatomesh_smoothing_baked"


def _smoothing_shown(coll, st):
    """The smoothing settings of the shape the scan shows: ``st``, or — when its smoothed shape
    became its unsmoothed copy (Apply, decimation, print tools) and it is not smoothed again —
    those that made it (:data:`BAKED_PROPERTY`), which the run smooths with before
    decimating."""
    from types import SimpleNamespace

    baked = coll.get(BAKED_PROPERTY) if coll is not None else None
    if baked and st.smooth_method == "NONE":
        return SimpleNamespace(**json.loads(baked))
    return st


def _print_to_recipe(r, p) -> None:
    """The Print panel's settings, when its check was run: check on, profile, overridden limits."""
    from ...core.printing.profiles import PROFILES

    if p is None or not p.checked:
        return
    r.check, r.profile = True, p.profile.lower()
    prof = PROFILES.get(r.profile, {})
    if abs(p.min_wall - prof.get("min_wall", -1.0)) > 1e-6:
        r.min_wall = float(p.min_wall)
    if abs(p.min_gap - prof.get("min_gap", -1.0)) > 1e-6 and p.min_gap > 0:
        r.min_gap = float(p.min_gap)


def smoothing_recipe(st, recipe=None):
    """The smoothing settings ``st`` (the scene's defaults or a scan's, see
    :func:`anatomesh.addon.operators.properties.smoothing_properties`) as a Recipe's smoothing fields, in
    ``recipe`` (default: a new Recipe). 0 means "the method's own"; the same settings give the
    same surfaces as ``anatomesh mesh`` with them."""
    r = recipe if recipe is not None else scene_recipe(bpy.context.scene)
    r.smooth = st.smooth_method.lower()
    r.iterations = int(st.smooth_iterations) if st.smooth_iterations > 0 else None
    r.lam = float(st.smooth_strength) if st.smooth_strength > 0 else None
    r.mu = float(st.smooth_mu) if st.smooth_mu < 0 else None
    r.max_deviation = float(st.smooth_max_deviation) if st.smooth_max_deviation > 0 else None
    r.damping_distance = float(st.smooth_damping) if st.smooth_damping > 0 else None
    r.staircase = st.smooth_staircase.lower()
    return r


def smoothing_to_ui(recipe) -> dict:
    """The smoothing settings of the panels for a recipe's ``[smoothing]`` (the inverse of
    :func:`smoothing_recipe`)."""
    return dict(smooth_method=(recipe.smooth or "none").upper(),
                smooth_iterations=int(recipe.iterations or 0), smooth_strength=float(recipe.lam or 0.0),
                smooth_mu=float(recipe.mu or 0.0), smooth_max_deviation=float(recipe.max_deviation or 0.0),
                smooth_damping=float(recipe.damping_distance or 0.0),
                smooth_staircase=(recipe.staircase or "auto").upper())


def apply_recipe(context, recipe, extract: bool = False) -> None:
    """Put a recipe's settings into the scene; read its scan and tick its labels / levels."""
    from ...core.model.labels import select_labels

    s = context.scene.anatomesh
    inp = recipe.input[0] if isinstance(recipe.input, list) else recipe.input
    s.filepath, s.series = inp, recipe.series or ""
    s.label_table, s.space, s.grid = recipe.label_table or "", recipe.space, recipe.grid or ""
    group = getattr(context.scene, "anatomesh_recipe", None)
    if group is not None:
        recipe_to_group(recipe, group)
    for key, value in smoothing_to_ui(recipe).items():
        setattr(s, key, value)
    d = getattr(context.scene, "anatomesh_decimate", None)
    if d is not None:
        for target, key, value in (("RATIO", "ratio", recipe.decimate), ("FACES", "faces", recipe.target_faces),
                                   ("ERROR", "max_error", recipe.max_error)):
            if value is not None:
                d.target = target
                setattr(d, key, value)
    p = getattr(context.scene, "anatomesh_print", None)
    if p is not None and recipe.check:
        p.profile = recipe.profile.upper()  # fills in the profile's limits
        if recipe.min_wall is not None:
            p.min_wall = recipe.min_wall
        if recipe.min_gap is not None:
            p.min_gap = recipe.min_gap
    pre = getattr(context.scene, "anatomesh_preprocess", None)  # the Preprocess panel
    if pre is not None:
        preprocess_from_recipe(pre, recipe)
    s.export_dir = recipe.out_dir
    fmt = next((f for f in recipe.formats if f in ("stl", "ply", "obj", "glb")), "stl")
    s.export_format = fmt.upper()
    res = bpy.ops.anatomesh.import_scan(filepath=inp, series=s.series, label_table=s.label_table,
                                        space=s.space, extract=False)
    if res != {"FINISHED"}:
        return
    vol = load_volume(inp, s.series, s.label_table, s.space, grid=s.grid, volume_index=recipe.volume_index)
    if vol.is_label_map:
        wanted = select_labels(vol, recipe.labels)
        for item in s.labels:
            item.include = wanted is None or int(item.value) in wanted
    elif recipe.levels:
        s.levels.clear()
        names = recipe.level_names or [f"level {lv:g}" for lv in recipe.levels]
        for lv, name in zip(recipe.levels, names):
            item = s.levels.add()
            item.value, item.name = float(lv), name
    if extract:
        bpy.ops.anatomesh.extract()


# -- the Preprocess panel ------------------------------------------------------------
#: UI smoothing filter → recipe filter name
SMOOTH_FILTERS = {"GAUSSIAN": "gaussian", "MEDIAN": "median", "DIFFUSION": "diffusion"}


def preprocess_to_recipe(p, recipe) -> None:
    """Copy the Preprocess panel's settings ``p`` into ``recipe`` (in place)."""
    recipe.resample = [float(p.resample)] if p.resample > 0 else None
    recipe.resample_method = p.resample_method.lower()
    recipe.roi = [float(x) for x in p.roi.replace(";", ",").split(",") if x.strip()] if p.roi.strip() else None
    if p.smooth_volume in SMOOTH_FILTERS:
        value = int(round(p.smooth_value)) if p.smooth_volume == "DIFFUSION" else float(p.smooth_value)
        recipe.smooth_volume = f"{SMOOTH_FILTERS[p.smooth_volume]}:{value:g}"
    else:
        recipe.smooth_volume = None
    for name in ("interpolate", "fuzzy_boundary", "fill_cavities", "precise", "difference_colors"):
        setattr(recipe, name, bool(getattr(p, name)))
    recipe.close_handles = float(p.close_handles) if p.close_handles > 0 else None
    recipe.fuzzy = [float(p.fuzzy_low), float(p.fuzzy_high), float(p.fuzzy_count)] if p.fuzzy else None
    if recipe.fuzzy is not None:
        recipe.levels, recipe.level_names = [], []


def preprocess_from_recipe(p, recipe) -> None:
    """Put a recipe's ``[preprocess]`` settings into the Preprocess panel ``p``."""
    p.resample = float(recipe.resample[0]) if recipe.resample else 0.0
    p.resample_method = str(recipe.resample_method).upper()
    p.roi = ",".join(f"{x:g}" for x in recipe.roi) if recipe.roi else ""
    p.smooth_volume, p.smooth_value = "NONE", p.smooth_value
    if recipe.smooth_volume:
        name, _, arg = str(recipe.smooth_volume).partition(":")
        p.smooth_volume = {v: k for k, v in SMOOTH_FILTERS.items()}.get(name.lower(), "NONE")
        p.smooth_value = float(arg.split(",")[0]) if arg else p.smooth_value
    for name in ("interpolate", "fuzzy_boundary", "fill_cavities", "precise", "difference_colors"):
        setattr(p, name, bool(getattr(recipe, name)))
    p.close_handles = float(recipe.close_handles or 0.0)
    p.fuzzy = recipe.fuzzy is not None
    if recipe.fuzzy:
        p.fuzzy_low, p.fuzzy_high = recipe.fuzzy[:2]
        p.fuzzy_count = int(recipe.fuzzy[2]) if len(recipe.fuzzy) == 3 else 5
