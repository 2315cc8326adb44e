"""Anatomesh add-on: the Decimate panel: targets, preview with Blender's Decimate modifier, Apply
with the core result, measured error per organ.

* Target (``Scene.anatomesh_decimate``): a ratio of faces to keep, a face count (all surfaces of
  the scan together) or a maximum error in mm.
* Preview (``anatomesh.decimate_preview``): a Decimate modifier (collapse) on every surface object
  of the scan — non-destructive, quick, but each organ on its own: seams may open in the preview.
  For a max-error target the ratio of each organ comes from a core run.
* Apply (``anatomesh.decimate_apply``): core's quadric decimation (:mod:`anatomesh.core.decimate.qem`)
  on the whole scan at once. For a label map the objects' shells are put back together into one
  SurfaceSet (shared vertices from the ``anatomesh_vid`` attribute, interface triangles once, pinch
  copies as split rows), so every interface is decimated once for both organs and seams stay
  shared; shells stay closed and manifold. The shown (possibly smoothed) shape is decimated and
  becomes the new rest shape (smoothing iterations go back to 0). The measured error of every
  organ is stored on its object (:data:`ERROR_PROPS`) and listed in the panel. Undo restores the
  objects.
"""
from __future__ import annotations

from typing import Dict, List, Tuple

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty
from bpy.types import Operator, Panel, PropertyGroup

from . import bridge, live, scene
from .operators import ProgressReporter, active_scan, guarded
from .panels import _Base

#: name of the preview modifier on each surface object
PREVIEW_MODIFIER = "Anatomesh Decimate (preview)"

#: custom properties set on each object by Apply (the report keys of ``anatomesh mesh``)
ERROR_PROPS = (
    "anatomesh_faces_before",                    # faces of the object before decimating
    "anatomesh_decimation_max_error_mm",         # symmetric Hausdorff distance to the input, mm
    "anatomesh_decimation_mean_error_mm",        # mean distance, mm
    "anatomesh_decimation_volume_change_pct",    # enclosed volume change, %
)

TARGET_ITEMS = (
    ("RATIO", "Ratio", "Keep this fraction of the faces"),
    ("FACES", "Face count", "Keep about this many faces, all surfaces of the scan together"),
    ("ERROR", "Max error", "Remove as many faces as possible while no point moves farther than "
                           "this from the surface, mm (measured: symmetric Hausdorff distance)"),
)


def _preview_update(self, context):
    """A target value changed: refresh a preview that is on (ratio and face count only; a max
    error needs a core run: press Preview again)."""
    if self.target == "ERROR":
        return
    coll = active_scan(context)
    if coll is None:
        return
    objs = [o for o in scene.surface_objects(coll) if PREVIEW_MODIFIER in o.modifiers]
    if objs:
        try:
            _set_preview(objs, _preview_ratios(objs, self.target, self.ratio, self.faces, 0.0))
        except Exception as exc:  # an update callback must never raise into the UI
            print(f"Anatomesh: decimate preview failed: {exc}")


class ANATOMESH_PG_decimate(PropertyGroup):
    """Decimation settings of the scene (``Scene.anatomesh_decimate``)."""

    target: EnumProperty(name="Target", items=TARGET_ITEMS, default="RATIO", update=_preview_update)
    ratio: FloatProperty(name="Ratio", default=0.1, min=0.001, max=1.0, subtype="FACTOR",
                         update=_preview_update, description="Fraction of the faces to keep")
    faces: IntProperty(name="Faces", default=50000, min=4, update=_preview_update,
                       description="Faces to keep, all surfaces of the scan together")
    max_error: FloatProperty(name="Max error", default=1.0, min=0.0, soft_max=5.0, unit="LENGTH",
                             description="Largest distance between the result and the surface "
                                         "before, mm")


# ---------------------------------------------------------------------------------------------
# the scan's surfaces as core arrays
# ---------------------------------------------------------------------------------------------
def surface_set_from_objects(objects) -> Tuple[object, List]:
    """Put shells that share vertex ids (``anatomesh_vid``) back together into a core SurfaceSet.

    Object ``k`` becomes label ``k + 1`` (background 0). A triangle found in two objects (an
    interface, once per orientation) is stored once, oriented as in its first object, with the
    two labels on its sides; a vertex id used by several vertices of one object (a pinch point,
    where a shell touches itself) gives split rows, so the shells come back 2-manifold.
    Positions are the objects' current ones (the shape shown). Returns ``(SurfaceSet, objects)``.
    """
    from ..core.model.errors import AnatomeshError
    from ..core.model.surfaceset import SurfaceSet

    parts = []
    for o in objects:
        vid = bridge.point_attribute(o.data, bridge.SHARED_INDEX_ATTRIBUTE, "int")
        parts.append((o, bridge.positions(o.data), bridge.triangles(o.data), vid.astype(np.int64)))
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
    ss = SurfaceSet(verts, faces, np.c_[inside, outside], np.zeros((n, 3), np.int32), affine,
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


# ---------------------------------------------------------------------------------------------
# apply and preview
# ---------------------------------------------------------------------------------------------
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
    live.set_scan_settings(collection, smooth_iterations=0)
    return results


def _write(obj, vertices, faces, vertex_ids) -> None:
    me = obj.data
    bridge.set_geometry(me, vertices, faces)
    bridge.set_point_attribute(me, bridge.REST_ATTRIBUTE, vertices, "vector")
    if vertex_ids is not None:
        bridge.set_point_attribute(me, bridge.SHARED_INDEX_ATTRIBUTE, vertex_ids, "int")


def _preview_ratios(objs, target, ratio, faces, max_error) -> Dict[str, float]:
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


def _set_preview(objs, ratios: Dict[str, float]) -> None:
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


def _scan(op, context):
    from ..core.model.errors import AnatomeshError

    coll = bpy.data.collections.get(op.collection) if op.collection else active_scan(context)
    if coll is None or not coll.anatomesh.is_scan:
        raise AnatomeshError("no scan collection to decimate: extract surfaces first, or pass "
                             "collection= with its name")
    return coll


class _TargetProps:
    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    target: EnumProperty(name="Target", items=TARGET_ITEMS, default="RATIO")
    ratio: FloatProperty(name="Ratio", default=0.1, min=0.001, max=1.0)
    faces: IntProperty(name="Faces", default=50000, min=4)
    max_error: FloatProperty(name="Max error", default=1.0, min=0.0, unit="LENGTH",
                             description="mm")

    def invoke(self, context, event):  # values not given come from the panel's settings
        s = context.scene.anatomesh_decimate
        for name in ("target", "ratio", "faces", "max_error"):
            if not self.properties.is_property_set(name):
                setattr(self, name, getattr(s, name))
        return self.execute(context)


class ANATOMESH_OT_decimate_preview(_TargetProps, Operator):
    """Preview the decimation with Blender's Decimate modifier on each surface (non-destructive;
    Apply uses core's result, which keeps the seams between organs shared)"""

    bl_idname = "anatomesh.decimate_preview"
    bl_label = "Preview Decimation"
    bl_options = {"REGISTER", "UNDO"}

    clear: bpy.props.BoolProperty(name="Clear", default=False, description="Remove the preview")

    @guarded
    def execute(self, context):
        coll = _scan(self, context)
        objs = scene.surface_objects(coll)
        if self.clear:
            self.report({"INFO"}, f"Removed the preview from {clear_preview(objs)} surface(s)")
            return {"FINISHED"}
        with ProgressReporter(context, "decimation preview"):
            _set_preview(objs, _preview_ratios(objs, self.target, self.ratio, self.faces,
                                               self.max_error))
        self.report({"INFO"}, f"Decimate preview on {len(objs)} surface(s) of '{coll.name}'")
        return {"FINISHED"}


class ANATOMESH_OT_decimate_apply(_TargetProps, Operator):
    """Decimate all surfaces of the scan at once with core's quadric decimation: shells stay
    closed, seams between organs stay shared, the error in mm is measured per organ"""

    bl_idname = "anatomesh.decimate_apply"
    bl_label = "Apply Decimation"
    bl_options = {"REGISTER", "UNDO"}

    @guarded
    def execute(self, context):
        import time

        coll = _scan(self, context)
        t0 = time.perf_counter()
        before = sum(len(o.data.polygons) for o in scene.surface_objects(coll))
        with ProgressReporter(context, "decimating") as progress:
            results = decimate_collection(coll, self.target, self.ratio, self.faces, self.max_error,
                                          progress=progress)
        after = sum(len(o.data.polygons) for o in scene.surface_objects(coll))
        worst = max(r["hausdorff_mm"] for r in results.values())
        self.report({"INFO"}, f"Decimated '{coll.name}': {before:,} → {after:,} faces, largest "
                              f"error {worst:.2f} mm ({time.perf_counter() - t0:.1f} s)")
        return {"FINISHED"}


class ANATOMESH_PT_decimate(_Base, Panel):
    bl_label = "Decimate"
    bl_idname = "ANATOMESH_PT_decimate"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        s = context.scene.anatomesh_decimate
        col = layout.column(align=True)
        col.prop(s, "target")
        col.prop(s, {"RATIO": "ratio", "FACES": "faces", "ERROR": "max_error"}[s.target])
        coll = active_scan(context)
        if coll is None:
            layout.label(text="Extract surfaces first")
            return
        objs = scene.surface_objects(coll)
        faces = sum(len(o.data.polygons) for o in objs)
        layout.label(text=f"{coll.name}: {faces:,} faces", icon="OUTLINER_COLLECTION")
        row = layout.row(align=True)
        previewing = any(PREVIEW_MODIFIER in o.modifiers for o in objs)
        op = row.operator("anatomesh.decimate_preview", text="Preview", icon="HIDE_OFF")
        self._fill(op, s, coll)
        if previewing:
            op = row.operator("anatomesh.decimate_preview", text="", icon="X")
            op.collection, op.clear = coll.name, True
        op = row.operator("anatomesh.decimate_apply", text="Apply", icon="CHECKMARK")
        self._fill(op, s, coll)
        measured = [o for o in objs if "anatomesh_decimation_max_error_mm" in o]
        if not measured:
            return
        box = layout.box()
        box.label(text="Measured error (max / mean mm)")
        obj = context.active_object
        shown = sorted(measured, key=lambda o: -o["anatomesh_decimation_max_error_mm"])
        if obj is not None and obj in measured:
            shown = [obj] + [o for o in shown if o != obj]
        for o in shown[:12]:
            row = box.row()
            row.label(text=o.get("anatomesh_name", o.name), icon="OBJECT_DATA" if o == obj else "NONE")
            row.label(text=f"{o['anatomesh_decimation_max_error_mm']:.2f} / "
                           f"{o['anatomesh_decimation_mean_error_mm']:.2f}")
            row.label(text=f"{o.get('anatomesh_faces_before', 0):,} → {len(o.data.polygons):,}")
        if len(shown) > 12:
            box.label(text=f"... {len(shown) - 12} more (largest error first)")

    @staticmethod
    def _fill(op, s, coll):
        op.collection, op.target, op.ratio = coll.name, s.target, s.ratio
        op.faces, op.max_error = s.faces, s.max_error


CLASSES = (ANATOMESH_PG_decimate, ANATOMESH_OT_decimate_preview, ANATOMESH_OT_decimate_apply,
           ANATOMESH_PT_decimate)


def register() -> None:
    """Register properties this module owns (classes are registered from CLASSES by the package)."""
    bpy.types.Scene.anatomesh_decimate = PointerProperty(type=ANATOMESH_PG_decimate)


def unregister() -> None:
    """Remove what :func:`register` added."""
    if hasattr(bpy.types.Scene, "anatomesh_decimate"):
        del bpy.types.Scene.anatomesh_decimate
