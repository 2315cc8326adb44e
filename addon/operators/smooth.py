"""Live smoothing: the core smoothing driver on a scan's objects, for every change of a setting.

One driver in every door: the Smooth panel, its sliders, the ``anatomesh.smooth`` operator and
``blender -b`` run :class:`anatomesh.core.smooth.session.SmoothingSession` — the same driver,
defaults and guards (fold guard, volumes restored, untangle) as ``anatomesh mesh`` — with the
settings the recipe would hold (:func:`anatomesh.addon.operators.recipe.smoothing_recipe` →
:func:`anatomesh.app.flow.stages.smoothing`). The same settings give the same vertices as the CLI.

Each scan collection keeps its unsmoothed surfaces twice:

* in a Python-side cache (:data:`_CACHE`, keyed by collection name): one
  :class:`~anatomesh.core.model.surfaceset.SurfaceSet` per layer (a label map has one; overlapping
  structures several, smoothed apart) with a session each, and which set vertex each object
  vertex is — so neighbouring organs are smoothed together and their seams stay shared;
* on the objects themselves (the ``anatomesh_rest``, ``anatomesh_vid`` and, for label maps,
  ``anatomesh_lattice`` vertex attributes and the ``anatomesh_layer`` property), so the cache can
  be rebuilt after the file is saved and reopened, undone or the collection renamed.

Smoothing never compounds: every change starts again from the unsmoothed copy and writes only
the positions (``bridge.set_positions``). ``apply`` makes the current shape the new rest shape.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import bpy
import numpy as np

from ..scene import bridge
from . import warmup
from ..scene import objects as scene
from ..scene.reassemble import surface_set_from_objects

LATTICE_ATTRIBUTE = "anatomesh_lattice"
LAYER_PROPERTY = "anatomesh_layer"


@dataclass
class LiveScan:
    """The unsmoothed surfaces of one scan collection.

    ``layers``: one SurfaceSet per layer (vertices float32 mm, as extracted); ``members``:
    ``(object name, layer, index (N_obj,) into that layer's vertices, the set label it shows)``;
    ``sessions``: the smoothing session of each layer, made on first use; ``shown``: each
    layer's set positions last shown (before the pinch points are moved apart)."""

    layers: List[object]
    members: List[Tuple[str, int, np.ndarray, int]] = field(default_factory=list)
    sessions: Dict[int, object] = field(default_factory=dict, repr=False)
    shown: Optional[List[np.ndarray]] = field(default=None, repr=False)

    def pinches_resolved(self, positions: List[np.ndarray]) -> Dict[str, np.ndarray]:
        """Each object's positions gathered from its layer's set at ``positions`` (one (N, 3)
        array per layer), the pinch points resolved as the pipeline's files show them
        (:func:`anatomesh.core.geometry.pinches.pinch_moves`)."""
        from ...core.geometry.pinches import apply_moves, copy_numbers, pinch_gap_mm, pinch_moves

        moves = [pinch_moves(sset.copy_with_vertices(pos), pinch_gap_mm(sset.affine))
                 if len(sset.splits) else None for sset, pos in zip(self.layers, positions)]
        out = {}
        for name, k, idx, label in self.members:
            pos = positions[k][idx]
            out[name] = pos if moves[k] is None else apply_moves(pos, idx, copy_numbers(idx),
                                                                  label, moves[k])
        return out

    def session(self, k: int):
        if k not in self.sessions:
            from ...core.smooth.session import SmoothingSession

            self.sessions[k] = SmoothingSession(self.layers[k])
        return self.sessions[k]


#: collection name → its unsmoothed surfaces
_CACHE: Dict[str, LiveScan] = {}
#: set while an operator writes several settings at once (one re-smooth at the end)
_SUSPENDED = False
#: (scan collection, warm-up step) waiting for the first run's smoothing kernels
#: (:func:`smooth_when_ready`)
_PENDING: set = set()


def remember(collection: bpy.types.Collection, scan: LiveScan) -> None:
    _CACHE[collection.name] = scan


def forget(collection_name: Optional[str] = None) -> None:
    if collection_name is None:
        _CACHE.clear()
    else:
        _CACHE.pop(collection_name, None)


def live_scan(collection: bpy.types.Collection) -> LiveScan:
    """The cached unsmoothed surfaces, rebuilt from the objects' attributes when missing/stale."""
    scan = _CACHE.get(collection.name)
    objs = scene.surface_objects(collection)
    if scan is not None and {m[0] for m in scan.members} == {o.name for o in objs} and all(
            len(bpy.data.objects[n].data.vertices) == len(idx) for n, _, idx, _ in scan.members):
        return scan
    scan = rebuild(objs)
    _CACHE[collection.name] = scan
    return scan


def rebuild(objects) -> LiveScan:
    """Reassemble each layer's SurfaceSet from its objects' rest positions, shared vertex ids and
    lattice points (:func:`anatomesh.addon.scene.reassemble.surface_set_from_objects`)."""
    by_layer: Dict[int, list] = {}
    for o in objects:
        by_layer.setdefault(int(o.get(LAYER_PROPERTY, 0)), []).append(o)
    layers, members = [], []
    for k, (_, objs) in enumerate(sorted(by_layer.items())):
        sset, order = surface_set_from_objects(objs, rest=True)
        lattice = [bridge.point_attribute(o.data, LATTICE_ATTRIBUTE, "vector") for o in order]
        if all(lat is not None for lat in lattice):
            full = np.zeros((sset.n_vertices, 3), np.int32)
            for o, lat in zip(order, lattice):
                full[_ids(o)] = np.round(lat).astype(np.int32)
            sset.lattice = full
        layers.append(sset)
        members += [(o.name, k, _ids(o), i + 1) for i, o in enumerate(order)]  # object i: label i + 1
    return LiveScan(layers, members)


def _ids(obj) -> np.ndarray:
    return bridge.point_attribute(obj.data, bridge.SHARED_INDEX_ATTRIBUTE, "int").astype(np.int64)


def store(objects_and_ids, layer: int, sset) -> None:
    """Record on each new object (with its ids into ``sset``) what :func:`rebuild` needs."""
    for obj, ids in objects_and_ids:
        obj[LAYER_PROPERTY] = int(layer)
        if sset.lattice is not None:
            bridge.set_point_attribute(obj.data, LATTICE_ATTRIBUTE,
                                       sset.lattice[ids].astype(np.float32), "vector")


def smooth_collection(collection: bpy.types.Collection) -> float:
    """Smooth ``collection``'s objects with its settings (from their unsmoothed copy), in place;
    returns the seconds the driver took."""
    from .recipe import smoothing_recipe
    from ...app.flow.stages import smoothing

    scan = live_scan(collection)
    method, settings = smoothing(smoothing_recipe(collection.anatomesh))
    t0 = time.perf_counter()
    positions = [sset.vertices if method == "none" or not sset.n_faces
                 else scan.session(k).run(method, **settings)[0] for k, sset in enumerate(scan.layers)]
    seconds = time.perf_counter() - t0
    scan.shown = positions
    shown = scan.pinches_resolved(positions)
    for name, k, idx, _ in scan.members:
        obj = bpy.data.objects.get(name)
        if obj is not None and len(obj.data.vertices) == len(idx):
            bridge.set_positions(obj.data, shown[name])
    return seconds


def smoothing_step(collection: bpy.types.Collection) -> str:
    """The warm-up step whose kernels ``collection``'s next smoothing needs: "label smoothing"
    for the first run of a label map's sessions (extracted organs), "smoothing" otherwise
    (isosurfaces; a slider's later runs list the candidate pairs)."""
    scan = live_scan(collection)
    first = all(k not in scan.sessions or not scan.sessions[k].runs for k in range(len(scan.layers)))
    labels = all(sset.lattice is not None for sset in scan.layers)
    return "label smoothing" if first and labels else "smoothing"


def smooth_when_ready(collection: bpy.types.Collection) -> Optional[float]:
    """Smooth ``collection`` now, or — first run, its kernels still compiling in the background —
    once they are ready, with the settings it has then (one pending smoothing per collection and
    step, however often a slider moves meanwhile), so Blender never freezes compiling. Returns
    the driver's seconds when it smoothed now, else None."""
    step = smoothing_step(collection)
    if warmup.ready(step):
        return smooth_collection(collection)
    key = (collection.name, step)
    if key not in _PENDING:
        _PENDING.add(key)

        def smooth_later():  # now, or (a later run than planned) when that step is ready
            _PENDING.discard(key)
            coll = bpy.data.collections.get(key[0])
            if coll is not None:
                smooth_when_ready(coll)

        warmup.when_ready(step, smooth_later)
    return None


def apply(collection: bpy.types.Collection) -> None:
    """Make the current (smoothed) positions the new unsmoothed copy; smoothing back to none."""
    scan = live_scan(collection)
    if scan.shown is not None:  # the set's positions, before the pinch points are moved apart
        for name, k, idx, _ in scan.members:
            obj = bpy.data.objects.get(name)
            if obj is not None and len(obj.data.vertices) == len(idx):
                bridge.set_point_attribute(obj.data, bridge.REST_ATTRIBUTE, scan.shown[k][idx], "vector")
    for o in scene.surface_objects(collection):
        if LATTICE_ATTRIBUTE in o.data.attributes:  # the vertices left their lattice cells' centres
            o.data.attributes.remove(o.data.attributes[LATTICE_ATTRIBUTE])
    forget(collection.name)
    bake(collection)


def bake(collection: bpy.types.Collection) -> None:
    """The shown shape became the scan's unsmoothed copy: remember the smoothing settings that
    made it (:data:`.recipe.BAKED_PROPERTY`, which a saved recipe smooths with; the first
    bake's: the flow smooths once, before decimating) and set the smoothing back to none."""
    from .properties import smoothing_properties
    from .recipe import BAKED_PROPERTY

    if BAKED_PROPERTY not in collection and collection.anatomesh.smooth_method != "NONE":
        collection[BAKED_PROPERTY] = json.dumps({k: getattr(collection.anatomesh, k)
                                                 for k in smoothing_properties()})
    set_scan_settings(collection, smooth_method="NONE")


def set_scan_settings(collection: bpy.types.Collection, **values) -> None:
    """Write several smoothing settings without re-smoothing after each one."""
    global _SUSPENDED
    _SUSPENDED = True
    try:
        for k, v in values.items():
            setattr(collection.anatomesh, k, v)
    finally:
        _SUSPENDED = False


# ---------------------------------------------------------------------------------------------
# property update callbacks (ui/props.py)
# ---------------------------------------------------------------------------------------------
def on_scan_settings_changed(settings, context) -> None:
    """A smoothing value of a scan collection changed: re-smooth it (unless suspended)."""
    if _SUSPENDED or not settings.live:
        return
    coll = settings.id_data
    try:
        seconds = smooth_when_ready(coll)
        if seconds is None:  # first run: smoothed once its kernels are compiled
            _status(context, f"Anatomesh: '{coll.name}' is smoothed with these settings once its "
                             f"kernels are compiled (first run, {int(100 * warmup.STATE['fraction'])}%)")
        else:
            _status(context, f"Anatomesh: smoothed '{coll.name}' in {seconds * 1000:.0f} ms")
    except Exception as exc:  # an update callback must never raise into the UI
        _status(context, f"Anatomesh: smoothing failed: {exc}")
        print(f"Anatomesh: smoothing {coll.name} failed: {exc}")


def on_look_changed(settings, context) -> None:
    coll = settings.id_data
    objs = scene.surface_objects(coll)
    scene.set_alpha(objs, settings.alpha, settings.oriented)
    scene.set_render_method(objs, settings.render_method)


@bpy.app.handlers.persistent
def _reset_cache(*_args) -> None:
    """After loading a file, undo or redo the objects' attributes are the truth: drop the cache."""
    forget()


_HANDLERS = ("load_post", "undo_post", "redo_post")


def register_handlers() -> None:
    for name in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if _reset_cache not in handlers:
            handlers.append(_reset_cache)


def unregister_handlers() -> None:
    for name in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        while _reset_cache in handlers:
            handlers.remove(_reset_cache)


def _status(context, text: str) -> None:
    ws = getattr(context, "workspace", None)
    if ws is not None:
        try:
            ws.status_text_set(text)
        except Exception:  # pragma: no cover - no window
            pass
