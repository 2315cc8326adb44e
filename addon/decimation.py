"""Decimating a scan's objects with core (seams shared, error measured), and the preview with
Blender's Decimate modifier."""
from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

from . import bridge, live, scene


#: name of the preview modifier on each surface object
PREVIEW_MODIFIER = "Anatomesh Decimate (preview)"


#: custom properties set on each object by Apply (the report keys of ``anatomesh mesh``)
ERROR_PROPS = (
    "anatomesh_faces_before",                    # faces of the object before decimating
    "anatomesh_decimation_max_error_mm",         # symmetric Hausdorff distance to the input, mm
    "anatomesh_decimation_mean_error_mm",        # mean distance, mm
    "anatomesh_decimation_volume_change_pct",    # enclosed volume change, %
)


def surface_set_from_objects(objects, rest: bool = False) -> Tuple[object, List]:
    """Put shells that share vertex ids (``anatomesh_vid``) back together into a core SurfaceSet.

    Object ``k`` becomes label ``k + 1`` (background 0). A triangle found in two objects (an
    interface, once per orientation) is stored once, oriented as in its first object, with the
    two labels on its sides; a vertex id used by several vertices of one object (a pinch point,
    where a shell touches itself) gives split rows, so the shells come back 2-manifold.
    Positions are the objects' current ones (the shape shown), or with ``rest`` their unsmoothed
    ones (``anatomesh_rest``). No lattice (the live cache adds it). Returns ``(SurfaceSet, objects)``.
    """
    from ..core.model.errors import AnatomeshError
    from ..core.model.surfaceset import SurfaceSet

    parts = []
    for o in objects:
        vid = bridge.point_attribute(o.data, bridge.SHARED_INDEX_ATTRIBUTE, "int")
        pos = bridge.point_attribute(o.data, bridge.REST_ATTRIBUTE, "vector") if rest else None
        pos = bridge.positions(o.data) if pos is None else pos
        parts.append((o, pos, bridge.triangles(o.data), vid.astype(np.int64)))
    n = 1 + max(int(vid.max()) for _, _, _, vid in parts if vid.size)
    verts = np.zeros((n, 3), np.float32)
    occ_faces, occ_owner, occ_copy = [], [], []
    for k, (o, pos, tri, vid) in enumerate(parts):
        verts[vid] = pos
        occ_faces.append(vid[tri])
        occ_owner.append(np.full(len(tri), k + 1, np.int32))
        occ_copy.append(_copy_numbers(vid)[tri])
    g = np.concatenate(occ_faces)
    own = np.concatenate(occ_owner)
    copy = np.concatenate(occ_copy)
    _, first, inv = np.unique(np.sort(g, axis=1), axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(first)                 # stored faces in the order the objects list them
    slot = np.empty(len(first), np.int64)
    slot[order] = np.arange(len(first))
    face_of = slot[inv]                       # stored face of every occurrence
    faces = g[first[order]]
    inside = own[first[order]]
    outside = np.zeros(len(faces), np.int32)
    twin = own != inside[face_of]
    uses = np.bincount(face_of, minlength=len(faces))
    if uses.max(initial=0) > 2 or np.any(np.bincount(face_of[twin], minlength=len(faces)) != uses - 1):
        raise AnatomeshError("the scan's objects do not fit together as one surface set (a triangle "
                             "is used by more than two organs or twice by one); re-extract the scan")
    outside[face_of[twin]] = own[twin]
    # split rows: corners that use a vertex copy (copy >= 1) in their own shell
    occ, corner_in_occ = np.nonzero(copy > 0)
    rows = np.zeros((len(occ), 4), np.int32)
    if len(occ):
        fi = face_of[occ]
        vals = g[occ, corner_in_occ]
        rows[:, 0] = fi
        rows[:, 1] = np.where(twin[occ], 1, 0)
        rows[:, 2] = np.argmax(faces[fi] == vals[:, None], axis=1)
        rows[:, 3] = copy[occ, corner_in_occ]
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
    aff = objects[0].get("anatomesh_affine") if objects else None
    affine = np.asarray(list(aff), np.float64).reshape(4, 4) if aff is not None and len(aff) == 16 \
        else np.eye(4)
    ss = SurfaceSet(verts, faces, np.c_[inside, outside], None, affine,
                    space=str(objects[0].get("anatomesh_space", "RAS")), splits=rows, background=0)
    return ss, [o for o, _, _, _ in parts]


def _copy_numbers(vid: np.ndarray) -> np.ndarray:
    """For each vertex of one object: 0 for the first vertex with its id, 1, 2, ... for copies."""
    order = np.argsort(vid, kind="stable")
    s = vid[order]
    start = np.r_[0, np.flatnonzero(s[1:] != s[:-1]) + 1]
    run = np.repeat(start, np.diff(np.r_[start, len(s)]))
    out = np.empty(len(vid), np.int64)
    out[order] = np.arange(len(s)) - run
    return out


def _core_target(target: str, ratio: float, faces: int, max_error: float, total_faces: int) -> Dict:
    if target == "RATIO":
        return {"ratio": float(ratio)}
    if target == "FACES":
        return {"ratio": float(min(1.0, max(faces, 1) / max(total_faces, 1)))}
    return {"max_error": float(max_error)}


def decimate_collection(collection, target: str, ratio: float = 0.1, faces: int = 50000,
                        max_error: float = 1.0, progress=None) -> Dict[str, Dict]:
    """Decimate the scan's surfaces with core, write them back, store the measured errors.

    Shells that share vertices (a label map) are decimated together as one SurfaceSet; other
    surfaces (isosurfaces) one by one. Returns ``{object name: shell measures}`` (core's keys:
    ``faces_before``, ``faces_after``, ``hausdorff_mm``, ``mean_mm``, ``volume_change_pct``).
    """
    from ..core.decimate.qem import decimate_mesh, decimate_surfaces
    from ..core.model.errors import AnatomeshError
    from ..core.model.mesh import Mesh

    objs = scene.surface_objects(collection)
    if not objs:
        raise AnatomeshError(f"scan '{collection.name}' has no surface objects to decimate")
    total = sum(len(o.data.polygons) for o in objs)
    kwargs = _core_target(target, ratio, faces, max_error, total)
    shared = [o for o in objs if bridge.SHARED_INDEX_ATTRIBUTE in o.data.attributes]
    alone = [o for o in objs if o not in shared]
    results: Dict[str, Dict] = {}
    if shared:
        ss, members = surface_set_from_objects(shared)
        out, rep = decimate_surfaces(ss, progress=progress, **kwargs)
        shells = {int(m.value): m for m in out.shells()}
        for k, o in enumerate(members):
            m = shells[k + 1]
            _write(o, m.vertices, m.faces, m.meta["vertex_ids"])
            results[o.name] = rep["shells"][k + 1]
    for o in alone:
        v, f = bridge.arrays(o.data)
        out, rep = decimate_mesh(Mesh(v, f), **kwargs)
        _write(o, out.vertices, out.faces, None)
        results[o.name] = rep["shells"][None]
    for o in objs:
        r = results[o.name]
        o["anatomesh_faces_before"] = int(r["faces_before"])
        o["anatomesh_decimation_max_error_mm"] = float(r["hausdorff_mm"])
        o["anatomesh_decimation_mean_error_mm"] = float(r["mean_mm"])
        o["anatomesh_decimation_volume_change_pct"] = float(r["volume_change_pct"])
        if PREVIEW_MODIFIER in o.modifiers:
            o.modifiers.remove(o.modifiers[PREVIEW_MODIFIER])
    collection["anatomesh_decimation_max_error_mm"] = max(r["hausdorff_mm"] for r in results.values())
    # the decimated shape is the new rest shape of live smoothing
    live.forget(collection.name)
    live.set_scan_settings(collection, smooth_method="NONE")
    return results


def _write(obj, vertices, faces, vertex_ids) -> None:
    me = obj.data
    bridge.set_geometry(me, vertices, faces)
    bridge.set_point_attribute(me, bridge.REST_ATTRIBUTE, vertices, "vector")
    if live.LATTICE_ATTRIBUTE in me.attributes:  # decimated vertices left their lattice cells
        me.attributes.remove(me.attributes[live.LATTICE_ATTRIBUTE])
    if vertex_ids is not None:
        bridge.set_point_attribute(me, bridge.SHARED_INDEX_ATTRIBUTE, vertex_ids, "int")


def preview_ratios(objs, target, ratio, faces, max_error) -> Dict[str, float]:
    """Decimate-modifier ratio of each object: the ratio, face count / all faces, or (max error)
    each organ's faces after / before in a core run on the current shapes."""
    if target != "ERROR":
        total = sum(len(o.data.polygons) for o in objs)
        r = _core_target(target, ratio, faces, max_error, total)["ratio"]
        return {o.name: r for o in objs}
    from ..core.decimate.qem import decimate_mesh, decimate_surfaces
    from ..core.model.mesh import Mesh

    out = {}
    shared = [o for o in objs if bridge.SHARED_INDEX_ATTRIBUTE in o.data.attributes]
    if shared:
        ss, members = surface_set_from_objects(shared)
        _, rep = decimate_surfaces(ss, max_error=max_error)
        for k, o in enumerate(members):
            s = rep["shells"][k + 1]
            out[o.name] = s["faces_after"] / max(s["faces_before"], 1)
    for o in objs:
        if o.name not in out:
            v, f = bridge.arrays(o.data)
            _, rep = decimate_mesh(Mesh(v, f), max_error=max_error, measure=False)
            out[o.name] = rep["faces_after"] / max(rep["faces_before"], 1)
    return out


def set_preview(objs, ratios: Dict[str, float]) -> None:
    for o in objs:
        mod = o.modifiers.get(PREVIEW_MODIFIER) or o.modifiers.new(PREVIEW_MODIFIER, "DECIMATE")
        mod.decimate_type = "COLLAPSE"
        mod.use_collapse_triangulate = True
        mod.ratio = float(min(1.0, max(0.0, ratios[o.name])))


def clear_preview(objs) -> int:
    n = 0
    for o in objs:
        mod = o.modifiers.get(PREVIEW_MODIFIER)
        if mod is not None:
            o.modifiers.remove(mod)
            n += 1
    return n
