"""Live smoothing: re-smooth a scan's surfaces from their unsmoothed copy on every change.

Each scan collection keeps its unsmoothed surface twice:

* in a Python-side cache (:data:`_CACHE`, keyed by collection name): the shared vertex array of
  the surface set, its faces and, per object, which shared vertex each object vertex is — so
  neighbouring organs are smoothed together and their seams stay shared;
* on the objects themselves (the ``anatomesh_rest`` and ``anatomesh_vid`` vertex attributes), so
  the cache can be rebuilt after the file is saved and reopened or the collection renamed.

Smoothing never compounds: every change starts again from the unsmoothed copy and writes only
the positions (``bridge.set_positions``). ``apply`` makes the current shape the new rest shape.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import bpy
import numpy as np

from . import bridge, scene


@dataclass
class ScanSurface:
    """The unsmoothed surface of one scan collection.

    ``vertices`` (V, 3) float32 mm and ``faces`` (F, 3) int32 of the shared surface set;
    ``members`` lists ``(object name, index (N_obj,) into vertices)``. Optional:
    ``face_groups`` (F,) — which pair of structures each face separates (junction curves of three
    or more structures are then smoothed along the curve only); ``lattice`` (V, 3) — the voxel
    corner of each vertex (voxel-cell box constraint); ``affine`` — the volume's voxel → mm matrix.
    """

    vertices: np.ndarray
    faces: np.ndarray
    members: List[Tuple[str, np.ndarray]] = field(default_factory=list)
    face_groups: Optional[np.ndarray] = None
    lattice: Optional[np.ndarray] = None
    affine: Optional[np.ndarray] = None
    #: the constraint last built for this surface, by (max deviation, in cell): reused while
    #: other sliders move
    constraints: Dict[tuple, object] = field(default_factory=dict, repr=False)


#: collection name → its unsmoothed surface
_CACHE: Dict[str, ScanSurface] = {}
#: set while an operator writes several settings at once (one re-smooth at the end)
_SUSPENDED = False


def remember(collection: bpy.types.Collection, surface: ScanSurface) -> None:
    _CACHE[collection.name] = surface


def forget(collection_name: Optional[str] = None) -> None:
    if collection_name is None:
        _CACHE.clear()
    else:
        _CACHE.pop(collection_name, None)


def scan_surface(collection: bpy.types.Collection) -> ScanSurface:
    """The cached unsmoothed surface, rebuilt from the objects' attributes when missing/stale."""
    surf = _CACHE.get(collection.name)
    objs = scene.surface_objects(collection)
    names = {o.name for o in objs}
    if surf is not None and {n for n, _ in surf.members} == names and all(
            len(bpy.data.objects[n].data.vertices) == len(idx) for n, idx in surf.members):
        return surf
    surf = rebuild(objs)
    _CACHE[collection.name] = surf
    return surf


def rebuild(objects) -> ScanSurface:
    """Reassemble the shared surface from the objects' ``anatomesh_rest`` / ``anatomesh_vid``.

    Objects that share vertex ids (shells of one surface set) are merged back, so their seams are
    smoothed as one; objects without ids are appended as separate pieces. A face shared by two
    shells (an interface between two organs) is kept once, and each face's group is the pair of
    objects it belongs to.
    """
    rests, faces, vids = [], [], []
    affine = None
    for o in objects:
        me = o.data
        rest = bridge.point_attribute(me, bridge.REST_ATTRIBUTE, "vector")
        if rest is None:
            rest = bridge.positions(me)
        rests.append(rest)
        faces.append(bridge.triangles(me))
        vids.append(bridge.point_attribute(me, bridge.SHARED_INDEX_ATTRIBUTE, "int"))
        aff = o.get("anatomesh_affine")
        if affine is None and aff is not None and len(aff) == 16:
            affine = np.asarray(list(aff), np.float64).reshape(4, 4)
    shared_n = max([int(v.max()) + 1 for v in vids if v is not None and v.size] or [0])
    n_total = shared_n + sum(len(r) for r, v in zip(rests, vids) if v is None)
    verts = np.zeros((n_total, 3), np.float32)
    members, all_faces, owner = [], [], []
    offset = shared_n
    for k, (o, rest, f, vid) in enumerate(zip(objects, rests, faces, vids)):
        if vid is None:
            vid = np.arange(offset, offset + len(rest), dtype=np.int64)
            offset += len(rest)
        vid = vid.astype(np.int64)
        verts[vid] = rest
        members.append((o.name, vid))
        all_faces.append(vid[f])
        owner.append(np.full(len(f), k, np.int64))
    if not all_faces:
        return ScanSurface(verts, np.zeros((0, 3), np.int32), members, affine=affine)
    f = np.concatenate(all_faces)
    own = np.concatenate(owner)
    # an interface triangle belongs to both neighbouring shells (once per orientation): keep one
    _, first, inverse = np.unique(np.sort(f, axis=1), axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    lo = np.full(len(first), np.iinfo(np.int64).max)
    hi = np.full(len(first), -1)
    np.minimum.at(lo, inverse, own)
    np.maximum.at(hi, inverse, own)
    pair = np.where(lo == hi, -1, hi)  # -1: the face has one owner (outer surface)
    _, groups = np.unique(np.stack([lo, pair], 1), axis=0, return_inverse=True)
    keep = np.sort(first)
    order = np.argsort(first)
    groups = groups.ravel()[order]  # align with the kept faces (sorted by first occurrence)
    return ScanSurface(verts, f[keep].astype(np.int32), members, face_groups=groups.astype(np.int64),
                       affine=affine)


def smooth_collection(collection: bpy.types.Collection, method: str, iterations: int,
                      strength: float, max_deviation: float, in_cell: bool = True) -> ScanSurface:
    """Smooth ``collection``'s objects from their unsmoothed copy and move the vertices in place."""
    surf = scan_surface(collection)
    if method == "NONE" or iterations <= 0 or not len(surf.faces):
        new = surf.vertices
    else:
        new = smooth_vertices(surf, method, iterations, strength, max_deviation, in_cell)
    for name, idx in surf.members:
        obj = bpy.data.objects.get(name)
        if obj is not None and len(obj.data.vertices) == len(idx):
            bridge.set_positions(obj.data, new[idx])
    return surf


def warm_up(surf: ScanSurface) -> None:
    """Compile the live-smoothing kernels for this kind of surface (lattice box or voxel box,
    junction curves or not) on a tetrahedron, so the first slider move is as fast as the next
    (numba compiles once per install: ~10 s; later sessions read the cache)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]], np.int32)
    groups = None if surf.face_groups is None else np.zeros(4, surf.face_groups.dtype)
    lattice = None if surf.lattice is None else np.zeros((4, 3), surf.lattice.dtype)
    tiny = ScanSurface(v, f, face_groups=groups, lattice=lattice, affine=surf.affine)
    smooth_vertices(tiny, "TAUBIN", 1, 0.5, 0.0, True)


def smooth_vertices(surf: ScanSurface, method: str, iterations: int, strength: float,
                    max_deviation: float, in_cell: bool = True) -> np.ndarray:
    """Core's smoothing filter on the shared arrays; returns new (V, 3) float32 positions (mm).

    ``method``: the UI name (props.SMOOTH_ITEMS). ``strength`` is the step λ (Taubin's μ is
    −(λ + 0.03), pass-band 0.1 at λ = 0.5). ``in_cell`` keeps every vertex inside its voxel cell
    (Gibson 1998); ``max_deviation`` > 0 caps each vertex's displacement in mm.
    """
    from ..core.smooth import driver as S

    name = {"TAUBIN": "taubin", "LAPLACIAN": "laplacian", "HC": "hc",
            "MEAN_CURVATURE": "mean_curvature"}[method]
    lam = float(min(max(strength, 0.01), 0.95))
    params = {"iterations": int(iterations)}
    if name == "taubin":  # float32: the precision Blender keeps positions in, ~2x faster
        params.update(lam=lam, mu=-min(1.0, lam + 0.03), precision="float32")
    elif name == "laplacian":
        params.update(lam=lam, precision="float32")
    elif name == "mean_curvature":
        params.update(step=lam)
    md = float(max_deviation) if max_deviation and max_deviation > 0 else None
    key = (md, bool(in_cell))
    if key not in surf.constraints:
        constraint = None
        if in_cell and surf.affine is not None:
            if surf.lattice is not None:
                constraint = S.lattice_constraint(surf.affine, surf.lattice, max_deviation=md)
            else:
                constraint = S.voxel_constraint(surf.affine, max_deviation=md)
        elif md is not None:
            constraint = S.Constraint(max_deviation=md)
        surf.constraints.clear()  # keep one: a max-deviation slider would pile them up
        surf.constraints[key] = constraint
    constraint = surf.constraints[key]
    fn = {"taubin": S.taubin, "laplacian": S.laplacian, "hc": S.hc_laplacian,
          "mean_curvature": S.mean_curvature_flow}[name]
    out = fn(surf.vertices, surf.faces, constraint=constraint, face_groups=surf.face_groups, **params)
    return np.asarray(out, np.float32)


def apply(collection: bpy.types.Collection) -> None:
    """Make the current (smoothed) positions the new unsmoothed copy; iterations back to 0."""
    global _SUSPENDED
    for o in scene.surface_objects(collection):
        bridge.set_point_attribute(o.data, bridge.REST_ATTRIBUTE, bridge.positions(o.data), "vector")
    forget(collection.name)
    _SUSPENDED = True
    try:
        collection.anatomesh.smooth_iterations = 0
    finally:
        _SUSPENDED = False


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
# property update callbacks (props.py)
# ---------------------------------------------------------------------------------------------
def on_scan_settings_changed(settings, context) -> None:
    """A smoothing value of a scan collection changed: re-smooth it (unless suspended)."""
    if _SUSPENDED or not settings.live:
        return
    coll = settings.id_data
    try:
        smooth_collection(coll, settings.smooth_method, settings.smooth_iterations,
                          settings.smooth_strength, settings.smooth_max_deviation, settings.keep_in_cell)
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
