"""Operators: thin — read the settings, call core on arrays, put the result in the scene.

Every operator is usable from scripts with the same parameters as the UI, e.g.::

    bpy.ops.anatomesh.import_scan(filepath="seg.nii.gz", label_table="labels.json", extract=True)
    bpy.ops.anatomesh.smooth(iterations=20)
    bpy.ops.anatomesh.export(directory="/tmp/out", format="STL")

Errors caused by the input (a bad file, a missing label) are reported as ``ERROR`` and the
operator returns ``{'CANCELLED'}``; no exception escapes into Blender.
"""

import functools
import os
import time
import traceback
from collections import OrderedDict
from typing import List, Optional, Sequence, Tuple

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import bridge, live, presets, props, scene

#: loaded volumes, newest last: (path, series, label table, space) → Volume
_VOLUMES: "OrderedDict[tuple, object]" = OrderedDict()
_MAX_VOLUMES = 2
_KERNELS_WARM = False


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def guarded(execute):
    """Wrap ``execute``: user errors → ERROR report + CANCELLED; never let an exception escape."""

    @functools.wraps(execute)
    def wrapper(self, context):
        from ..core.model.errors import AnatomeshError, Cancelled

        try:
            return execute(self, context)
        except AnatomeshError as exc:
            self.report({"ERROR"}, str(exc))
        except Cancelled:
            self.report({"WARNING"}, "Cancelled")
        except MemoryError:
            self.report({"ERROR"}, "Out of memory: crop or downsample the scan, or extract fewer labels")
        except Exception as exc:  # a bug: say so, keep Blender alive, details to the console
            traceback.print_exc()
            self.report({"ERROR"}, f"Anatomesh failed unexpectedly ({type(exc).__name__}: {exc}); "
                                   "details in the system console")
        return {"CANCELLED"}

    return wrapper


class ProgressReporter:
    """A core ``progress(fraction, text)`` callback showing Blender's progress cursor and status."""

    def __init__(self, context, title: str):
        self.wm = context.window_manager
        self.workspace = getattr(context, "workspace", None)
        self.has_window = bool(getattr(self.wm, "windows", None)) and not bpy.app.background
        self.title = title

    def __enter__(self):
        if self.has_window:
            self.wm.progress_begin(0, 1000)
        self(0.0, "")
        return self

    def __call__(self, fraction: float, text: str = "") -> None:
        if self.has_window:
            self.wm.progress_update(int(1000 * min(1.0, max(0.0, fraction))))
            if self.workspace is not None:
                self.workspace.status_text_set(f"Anatomesh: {self.title} {int(100 * fraction)}% {text}")

    def __exit__(self, *exc):
        if self.has_window:
            self.wm.progress_end()
            if self.workspace is not None:
                self.workspace.status_text_set(None)
        return False


def _abspath(path: str) -> str:
    return os.path.normpath(bpy.path.abspath(path)) if path else ""


def load_volume(filepath: str, series: str = "", label_table: str = "", space: str = "RAS", progress=None):
    """core.load with a small cache (re-extracting the same scan does not read it again)."""
    from ..core import load

    key = (_abspath(filepath), series or None, _abspath(label_table) or None, space)
    vol = _VOLUMES.get(key)
    if vol is None:
        vol = load(key[0], series=key[1], labels=key[2], space=space, progress=progress)
        _VOLUMES[key] = vol
        while len(_VOLUMES) > _MAX_VOLUMES:
            _VOLUMES.popitem(last=False)
    else:
        _VOLUMES.move_to_end(key)
    return vol


def fill_lists(settings, volume) -> None:
    """Put the volume's labels (present ones) or its isovalue presets into the scene settings."""
    settings.labels.clear()
    settings.levels.clear()
    settings.modality = str(volume.meta.get("modality", ""))
    shape = "x".join(str(s) for s in volume.shape)
    spacing = "x".join(f"{s:.3g}" for s in volume.spacing)
    settings.info = f"{shape} voxels, {spacing} mm, {volume.orientation()} ({volume.space})"
    if volume.is_label_map:
        from ..core.io.describe import label_facts

        settings.kind = "LABELS"
        for fact in label_facts(volume):
            if fact["voxels"] <= 0:
                continue
            item = settings.labels.add()
            item.name = fact["name"]
            item.value = int(fact["value"])
            info = (volume.labels or {}).get(int(fact["value"]))
            item.color = tuple(info.color if info is not None else (fact["color"] or (0.8, 0.8, 0.8)))[:3]
            item.voxels = int(fact["voxels"])
            item.volume_mm3 = float(fact["volume_mm3"])
            item.include = True
    else:
        settings.kind = "LEVELS"
        for name, value, color, include in presets.level_presets(volume):
            item = settings.levels.add()
            item.name, item.value, item.color, item.include = name, value, color, include


def _parse_list(text: str) -> List[str]:
    return [t.strip() for t in text.replace(";", ",").split(",") if t.strip()]


def chosen_labels(settings, volume, text: str) -> List[Tuple[int, str, Tuple[float, float, float]]]:
    """(value, name, colour) of the labels to extract.

    ``text``: "" → the included rows of the label list; "all" → every label present; else values
    and/or names separated by commas (names match case-insensitively).
    """
    from ..core.model.labels import select_labels

    rows = {item.value: item for item in settings.labels}
    table = volume.labels or {}
    if text.strip().lower() == "all" or (not text.strip() and not rows):
        present = np.unique(np.asarray(volume.data))
        values = [int(v) for v in present if v != 0]
    elif text.strip():
        values = select_labels(volume, _parse_list(text))
    else:
        values = [v for v, item in rows.items() if item.include]
    out = []
    for v in values:
        if v in rows:
            out.append((v, rows[v].name, tuple(rows[v].color)))
        elif v in table:
            out.append((v, table[v].name, tuple(table[v].color)))
        else:
            out.append((v, f"label_{v}", (0.8, 0.8, 0.8)))
    return out


def chosen_levels(settings, text: str) -> List[Tuple[float, str, Tuple[float, float, float]]]:
    """(isovalue, name, colour): ``text`` "" → the included rows of the level list; else numbers."""
    if text.strip():
        out = []
        for t in _parse_list(text):
            try:
                v = float(t)
            except ValueError:
                from ..core.model.errors import AnatomeshError

                raise AnatomeshError(f"isovalue {t!r} is not a number; give levels like '300, -500'")
            out.append((v, f"level {v:g}", (0.9, 0.85, 0.75)))
        return out
    return [(item.value, item.name, tuple(item.color)) for item in settings.levels if item.include]


def active_scan(context) -> Optional[bpy.types.Collection]:
    """The scan collection the user is working on: active collection, active object's, or last made."""
    alc = getattr(context.view_layer, "active_layer_collection", None)
    if alc is not None and alc.collection.anatomesh.is_scan:
        return alc.collection
    obj = context.active_object
    if obj is not None:
        for c in obj.users_collection:
            if c.anatomesh.is_scan:
                return c
    name = context.scene.anatomesh.last_collection
    coll = bpy.data.collections.get(name) if name else None
    return coll if coll is not None and coll.anatomesh.is_scan else None


def _object_props(volume, value, name) -> dict:
    return {
        "anatomesh_value": float(value) if not float(value).is_integer() else int(value),
        "anatomesh_name": str(name),
        "anatomesh_source": str(volume.meta.get("source", "")),
        "anatomesh_series_uid": str(volume.meta.get("series_uid", "") or ""),
        "anatomesh_space": volume.space,
        "anatomesh_affine": [float(x) for x in np.asarray(volume.affine).ravel()],
        "anatomesh_units": "mm",
    }


def _frame_viewports(context, collection) -> None:
    """Make the scan visible in every 3D view: far clip plane, then View All (UI only)."""
    if bpy.app.background or context.window_manager is None:
        return
    box = scene.bounds(scene.surface_objects(collection))
    size = float((box[1] - box[0]).max()) if box is not None else 1000.0
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            space = area.spaces.active
            space.clip_start = min(space.clip_start, 0.1)
            space.clip_end = max(space.clip_end, 20.0 * size)
            region = next((r for r in area.regions if r.type == "WINDOW"), None)
            if region is not None:
                try:
                    with context.temp_override(window=window, area=area, region=region):
                        bpy.ops.view3d.view_all(center=False)
                except RuntimeError:
                    pass


def extract_to_scene(context, volume, *, labels: Sequence = (), levels: Sequence = (),
                     render_method: str = "DITHERED", progress=None) -> bpy.types.Collection:
    """Extract surfaces (label shells or isosurfaces) and add them as objects in a new collection."""
    from ..core.model.errors import AnatomeshError

    global _KERNELS_WARM
    if not _KERNELS_WARM:
        note = "first run: compiling kernels once (numba), later runs are fast"
        print(f"Anatomesh: {note}")
        if progress is not None:
            progress(0.0, note)
    items = []  # (core Mesh, value, name, colour, shared index or None)
    warnings = []
    if volume.is_label_map:
        if not labels:
            raise AnatomeshError("no labels chosen; tick at least one label in the list",
                                 volume.meta.get("source"))
        from ..core.extract.multilabel import label_surfaces

        sset = label_surfaces(volume, values=[v for v, _, _ in labels], progress=progress)
        shells = {int(round(float(m.value))): m for m in sset.shells()}
        surface = set_surface(sset)
        warnings += list(sset.warnings)
        for v, name, color in labels:
            m = shells.get(int(v))
            if m is not None and m.n_faces:
                items.append((m, v, name, color, _shared_index(m)))
    else:
        if not levels:
            raise AnatomeshError("no isovalue chosen; tick or add a level", volume.meta.get("source"))
        from ..core.extract.isosurface import isosurfaces

        meshes = isosurfaces(volume, [lv for lv, _, _ in levels], progress=progress)
        surface = None
        for (lv, name, color), m in zip(levels, meshes):
            if m.n_faces:
                items.append((m, lv, name, color, None))
            else:
                warnings.append(f"isovalue {lv:g} ({name}) gives no surface: it is outside the data range")
    coll = scan_to_scene(context, volume, items, surface, warnings, render_method)
    if not _KERNELS_WARM:  # so the first slider move is as fast as the next
        if progress is not None:
            progress(1.0, "first run: compiling the live smoothing kernels once")
        live.warm_up(live.scan_surface(coll))
    _KERNELS_WARM = True
    return coll


def scan_to_scene(context, volume, items: Sequence, surface: Optional["live.ScanSurface"],
                  warnings: Sequence[str] = (), render_method: str = "DITHERED") -> bpy.types.Collection:
    """Add extracted surfaces to the scene: a new collection named after the scan, one object
    per item, and the live-smoothing cache.

    ``items``: ``(core Mesh, value, name, colour, shared index or None)``; ``surface``: the
    label map's shared :class:`live.ScanSurface` (None: independent isosurfaces, stacked here).
    Used by :func:`extract_to_scene` and by the headless pipeline (``addon/headless.py``).
    """
    from ..core.model.errors import AnatomeshError

    if not items:
        raise AnatomeshError("nothing to show: the chosen labels/levels give no surface",
                             volume.meta.get("source"))

    scene.setup_units(context.scene)
    src = volume.meta.get("source", "") or "scan"
    coll = scene.new_collection(scene.scan_name(src))
    coll.anatomesh.is_scan = True
    coll.anatomesh.source = str(src)
    coll.anatomesh.space = volume.space
    coll.anatomesh.render_method = render_method
    coll["anatomesh_space"] = volume.space
    coll["anatomesh_units"] = "mm"
    coll["anatomesh_warnings"] = list(warnings)
    members, offsets = [], 0
    pieces_v, pieces_f = [], []
    for m, value, name, color, shared in items:
        obj = scene.add_surface(coll, name, m.vertices, m.faces, _object_props(volume, value, name),
                                color, render_method, shared_index=shared)
        if shared is None:  # independent surfaces: stack them into one array set for smoothing
            shared = np.arange(offsets, offsets + m.n_vertices)
            pieces_v.append(m.vertices)
            pieces_f.append(m.faces + offsets)
            offsets += m.n_vertices
        members.append((obj.name, np.asarray(shared, np.int64)))
    if surface is None:
        surface = live.ScanSurface(np.concatenate(pieces_v), np.concatenate(pieces_f).astype(np.int32),
                                   affine=np.asarray(volume.affine))
    surface.members = members
    live.remember(coll, surface)
    context.scene.anatomesh.last_collection = coll.name
    return coll


def set_surface(sset) -> "live.ScanSurface":
    """The live-smoothing surface of a core SurfaceSet (face groups: the pair of structures)."""
    fl = np.sort(sset.face_labels.astype(np.int64), axis=1)  # the unordered pair of structures
    _, groups = np.unique(fl[:, 0] * (int(fl.max(initial=0)) + 1) + fl[:, 1], return_inverse=True)
    return live.ScanSurface(sset.vertices, sset.faces, face_groups=groups.ravel().astype(np.int64),
                            lattice=sset.lattice, affine=np.asarray(sset.affine))


def _shared_index(mesh) -> np.ndarray:
    """Index of each shell vertex in its surface set's vertex array (``Mesh.meta["vertex_ids"]``)."""
    idx = mesh.meta.get("vertex_ids")
    if idx is None or len(idx) != mesh.n_vertices:
        raise RuntimeError(f"shell {mesh.name!r} lacks meta['vertex_ids'] (core SurfaceSet changed?)")
    return np.asarray(idx, np.int64)


# ---------------------------------------------------------------------------------------------
# operators
# ---------------------------------------------------------------------------------------------
class ANATOMESH_OT_import_scan(bpy.types.Operator, ImportHelper):
    """Read a scan or label map (NIfTI, NRRD, DICOM folder) and list its labels or isovalues"""

    bl_idname = "anatomesh.import_scan"
    bl_label = "Import Scan (Anatomesh)"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.nii;*.nii.gz;*.gz;*.nrrd;*.nhdr;*.dcm;*.ima;*", options={"HIDDEN"})
    filepath: StringProperty(name="File", subtype="FILE_PATH",
                             description="NIfTI/NRRD file, a DICOM folder or one file in it")
    series: StringProperty(name="Series", description="DICOM series UID or number, when several")
    label_table: StringProperty(name="Label table", subtype="FILE_PATH",
                                description="Label names/colours file (optional; sidecars are found)")
    space: EnumProperty(name="Space", items=props.SPACE_ITEMS, default="RAS")
    extract: BoolProperty(name="Extract now", default=True,
                          description="Create the surfaces of every label (or the default isovalues) now")
    render_method: EnumProperty(name="Transparency", items=props.RENDER_METHOD_ITEMS, default="DITHERED")

    @guarded
    def execute(self, context):
        settings = context.scene.anatomesh
        t0 = time.perf_counter()
        with ProgressReporter(context, "reading") as progress:
            vol = load_volume(self.filepath, self.series, self.label_table, self.space, progress=progress)
        settings.filepath = self.filepath
        settings.series = self.series
        settings.label_table = self.label_table
        settings.space = self.space
        fill_lists(settings, vol)
        for w in vol.warnings:
            self.report({"WARNING"}, w)
        if not self.extract:
            n = len(settings.labels) if vol.is_label_map else len(settings.levels)
            what = "labels" if vol.is_label_map else "isovalue presets"
            self.report({"INFO"}, f"Read {os.path.basename(self.filepath)}: {n} {what}")
            return {"FINISHED"}
        with ProgressReporter(context, "extracting") as progress:
            coll = extract_to_scene(context, vol, labels=chosen_labels(settings, vol, ""),
                                    levels=chosen_levels(settings, ""), render_method=self.render_method,
                                    progress=progress)
        return _finish_extraction(self, context, coll, t0)


def _finish_extraction(op, context, coll, t0: float):
    """Frame the new surfaces, pass the reader's warnings on, report count and time."""
    _frame_viewports(context, coll)
    for w in coll.get("anatomesh_warnings", []):
        op.report({"WARNING"}, w)
    op.report({"INFO"}, f"{len(coll.objects)} surfaces in '{coll.name}' ({time.perf_counter() - t0:.1f} s)")
    return {"FINISHED"}


class ANATOMESH_OT_extract(bpy.types.Operator):
    """Extract the chosen labels (or isovalues) of the scan as surface objects in a new collection"""

    bl_idname = "anatomesh.extract"
    bl_label = "Extract Surfaces"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="File", subtype="FILE_PATH",
                             description="Scan to read (default: the one in the Import panel)")
    series: StringProperty(name="Series")
    label_table: StringProperty(name="Label table", subtype="FILE_PATH")
    space: EnumProperty(name="Space", items=(("SETTINGS", "As set", "The Import panel's space"),)
                        + props.SPACE_ITEMS, default="SETTINGS")
    labels: StringProperty(name="Labels", description="'' = ticked rows of the list, 'all', or "
                                                      "values/names separated by commas")
    levels: StringProperty(name="Levels", description="'' = ticked isovalues, or numbers separated "
                                                      "by commas (scalar scans)")
    smooth_method: EnumProperty(name="Smoothing", items=props.SMOOTH_ITEMS, default="TAUBIN")
    smooth_iterations: IntProperty(name="Iterations", default=-1, min=-1, max=1000,
                                   description="-1: the Smooth panel's default")
    smooth_strength: FloatProperty(name="Strength", default=-1.0, min=-1.0, max=1.0)
    smooth_max_deviation: FloatProperty(name="Max deviation", default=-1.0, min=-1.0, unit="LENGTH")
    keep_in_cell: EnumProperty(name="Stay in voxel", items=(("SETTINGS", "As set", ""), ("YES", "Yes", ""),
                                                           ("NO", "No", "")), default="SETTINGS")

    @guarded
    def execute(self, context):
        settings = context.scene.anatomesh
        path = self.filepath or settings.filepath
        if not path:
            from ..core.model.errors import AnatomeshError

            raise AnatomeshError("no scan chosen: set the file in the Import panel or pass filepath=")
        space = settings.space if self.space == "SETTINGS" else self.space
        series = self.series or (settings.series if not self.filepath else "")
        table = self.label_table or (settings.label_table if not self.filepath else "")
        t0 = time.perf_counter()
        with ProgressReporter(context, "extracting") as progress:
            vol = load_volume(path, series, table, space, progress=None)
            if self.filepath and _abspath(self.filepath) != _abspath(settings.filepath):
                settings.filepath, settings.series, settings.label_table = self.filepath, series, table
                fill_lists(settings, vol)
            elif (vol.is_label_map and not len(settings.labels)) or (
                    not vol.is_label_map and not len(settings.levels)):
                fill_lists(settings, vol)
            coll = extract_to_scene(
                context, vol, labels=chosen_labels(settings, vol, self.labels) if vol.is_label_map else (),
                levels=chosen_levels(settings, self.levels) if not vol.is_label_map else (),
                render_method=settings.render_method, progress=progress)
        iters = settings.smooth_iterations if self.smooth_iterations < 0 else self.smooth_iterations
        strength = settings.smooth_strength if self.smooth_strength < 0 else self.smooth_strength
        maxdev = settings.smooth_max_deviation if self.smooth_max_deviation < 0 else self.smooth_max_deviation
        method = self.smooth_method if self.properties.is_property_set("smooth_method") else settings.smooth_method
        in_cell = settings.keep_in_cell if self.keep_in_cell == "SETTINGS" else self.keep_in_cell == "YES"
        live.set_scan_settings(coll, smooth_method=method, smooth_iterations=iters, smooth_strength=strength,
                               smooth_max_deviation=maxdev, keep_in_cell=in_cell)
        if iters > 0 and method != "NONE":
            with ProgressReporter(context, "smoothing"):
                live.smooth_collection(coll, method, iters, strength, maxdev, in_cell)
        return _finish_extraction(self, context, coll, t0)


class ANATOMESH_OT_smooth(bpy.types.Operator):
    """Smooth a scan's surfaces from their extracted shape (seams between organs stay shared)"""

    bl_idname = "anatomesh.smooth"
    bl_label = "Smooth Surfaces"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    method: EnumProperty(name="Method", items=props.SMOOTH_ITEMS, default="TAUBIN")
    iterations: IntProperty(name="Iterations", default=10, min=0, soft_max=100, max=1000)
    strength: FloatProperty(name="Strength", default=0.5, min=0.0, max=1.0)
    max_deviation: FloatProperty(name="Max deviation", default=0.0, min=0.0, soft_max=5.0, unit="LENGTH",
                                 description="mm; 0: no cap")
    keep_in_cell: BoolProperty(name="Stay in voxel", default=True,
                               description="Keep every vertex inside its voxel cell (Gibson 1998)")
    apply: BoolProperty(name="Apply", default=False,
                        description="Bake: the smoothed shape becomes the new extracted shape")

    def invoke(self, context, event):  # values not given start from the scan's current ones
        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is not None and coll.anatomesh.is_scan:
            s = coll.anatomesh
            for mine, theirs in (("method", "smooth_method"), ("iterations", "smooth_iterations"),
                                 ("strength", "smooth_strength"), ("max_deviation", "smooth_max_deviation"),
                                 ("keep_in_cell", "keep_in_cell")):
                if not self.properties.is_property_set(mine):
                    setattr(self, mine, getattr(s, theirs))
        return self.execute(context)

    @guarded
    def execute(self, context):
        from ..core.model.errors import AnatomeshError

        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None or not coll.anatomesh.is_scan:
            raise AnatomeshError("no scan collection to smooth: extract surfaces first, or pass "
                                 "collection= with its name")
        live.set_scan_settings(coll, smooth_method=self.method, smooth_iterations=self.iterations,
                               smooth_strength=self.strength, smooth_max_deviation=self.max_deviation,
                               keep_in_cell=self.keep_in_cell)
        t0 = time.perf_counter()
        live.smooth_collection(coll, self.method, self.iterations, self.strength, self.max_deviation,
                               self.keep_in_cell)
        if self.apply:
            live.apply(coll)
        self.report({"INFO"}, f"Smoothed '{coll.name}' ({time.perf_counter() - t0:.2f} s)"
                              + (", applied" if self.apply else ""))
        return {"FINISHED"}


class ANATOMESH_OT_export(bpy.types.Operator):
    """Write the surfaces to files in millimetres, recording their patient space"""

    bl_idname = "anatomesh.export"
    bl_label = "Export Surfaces"
    bl_options = {"REGISTER"}

    directory: StringProperty(name="Folder", subtype="DIR_PATH")
    format: EnumProperty(name="Format", items=props.EXPORT_FORMAT_ITEMS, default="STL")
    selection: EnumProperty(name="What", items=props.EXPORT_SELECTION_ITEMS, default="COLLECTION")
    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    overwrite: BoolProperty(name="Overwrite", default=False, description="Replace existing files")

    @guarded
    def execute(self, context):
        from ..core.model.errors import AnatomeshError

        settings = context.scene.anatomesh
        folder = _abspath(self.directory or settings.export_dir)
        if not folder:
            raise AnatomeshError("no output folder; set one in the Export panel or pass directory=")
        objs, stem = self._objects(context)
        if not objs:
            raise AnatomeshError("nothing to export: select surface objects or choose a scan collection")
        os.makedirs(folder, exist_ok=True)
        if self.format == "3MF":
            from ..core.export.threemf import write_3mf

            path = os.path.join(folder, _slug(stem) + ".3mf")
            self._refuse([path])
            write_3mf(object_meshes(context, objs), path, title=stem)
            written = [path]
        elif self.format in ("GLB", "GLTF"):
            path = os.path.join(folder, _slug(stem) + (".glb" if self.format == "GLB" else ".gltf"))
            self._refuse([path])
            export_gltf(context, objs, path, self.format)
            written = [path]
        else:
            written = export_meshes(context, objs, folder, self.format.lower(), self._refuse)
        self.report({"INFO"}, f"Wrote {len(written)} file(s) to {folder}")
        return {"FINISHED"}

    def _objects(self, context):
        if self.selection == "SELECTED":
            objs = [o for o in context.selected_objects if o.type == "MESH"]
            return objs, (objs[0].users_collection[0].name if objs else "surfaces")
        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None:
            return [], ""
        return scene.surface_objects(coll), coll.name

    def _refuse(self, paths):
        from ..core.model.errors import AnatomeshError

        existing = [p for p in paths if os.path.exists(p)]
        if existing and not self.overwrite:
            raise AnatomeshError(f"{len(existing)} file(s) exist already (e.g. {existing[0]}); tick "
                                 "Overwrite or choose another folder")


def _slug(name: str) -> str:
    import re

    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_") or "surface"


def object_meshes(context, objects) -> list:
    """Core :class:`Mesh` copies of ``objects`` as evaluated (modifiers applied), world mm, with
    name, label value, space and the label colour (sRGB, as the label table gives it)."""
    from ..core.model.labels import linear_to_srgb
    from ..core.model.mesh import Mesh

    depsgraph = context.evaluated_depsgraph_get()
    out = []
    for o in objects:
        v, f = bridge.world_arrays(o, depsgraph)
        out.append(Mesh(v, f, name=o.get("anatomesh_name", o.name), value=o.get("anatomesh_value"),
                        color=tuple(float(c) for c in linear_to_srgb(o.color[:3])),
                        space=str(o.get("anatomesh_space", "RAS"))))
    return out


def export_meshes(context, objects, folder: str, fmt: str, refuse=None) -> List[str]:
    """One file per object through core's writers (mm, ``SPACE=`` recorded); returns the paths."""
    from ..core.export.mesh_files import write_mesh

    plans, used = [], set()
    for o in objects:
        stem = _slug(o.get("anatomesh_name", o.name))
        if stem in used:
            stem = _slug(o.name)
        used.add(stem)
        plans.append(os.path.join(folder, f"{stem}.{fmt}"))
    if refuse is not None:
        refuse(plans)
    for m, path in zip(object_meshes(context, objects), plans):
        write_mesh(m, path, fmt)
    return plans


def export_gltf(context, objects, path: str, fmt: str) -> None:
    """glTF/GLB through Blender's exporter, converted to metres (glTF's unit) and Y-up, facing
    +Z (glTF's front) as ``anatomesh mesh --format glb`` does.

    Blender's exporter maps (x, y, z) to glTF (x, z, −y): LPS data (y = posterior) then faces
    +Z, RAS data would face −Z, so RAS objects are first turned 180° about the body axis
    (``core.export_gltf.AXES``). The objects are scaled by 0.001 (and turned) for the export
    and restored exactly afterwards, and the selection is restored; nothing in the scene
    changes. Re-imported into Blender, the surfaces arrive in LPS (like the CLI's GLB).
    """
    sel = [o for o in context.view_layer.objects if o.select_get()]
    active = context.view_layer.objects.active
    saved = {o.name: o.matrix_basis.copy() for o in objects}
    names = set(saved)
    from mathutils import Matrix

    to_gltf = {"RAS": Matrix.Scale(0.001, 4) @ Matrix.Rotation(np.pi, 4, "Z"),
               "LPS": Matrix.Scale(0.001, 4)}
    try:
        for o in context.view_layer.objects:
            o.select_set(o.name in names)
        for o in objects:
            if o.parent is None or o.parent.name not in names:
                # objects not made by Anatomesh keep Blender's own front (−Y → glTF +Z)
                space = str(o.get("anatomesh_space", ""))
                o.matrix_world = to_gltf.get(space, to_gltf["LPS"]) @ o.matrix_world
        context.view_layer.update()
        bpy.ops.export_scene.gltf(filepath=path, export_format="GLB" if fmt == "GLB" else "GLTF_SEPARATE",
                                  use_selection=True, export_yup=True, export_apply=True,
                                  export_extras=True)
    finally:
        for o in objects:
            o.matrix_basis = saved[o.name]
        for o in context.view_layer.objects:
            o.select_set(o in sel)
        context.view_layer.objects.active = active
        context.view_layer.update()


class ANATOMESH_OT_labels_select(bpy.types.Operator):
    """Tick or untick every label (or isovalue) in the list"""

    bl_idname = "anatomesh.labels_select"
    bl_label = "Select Labels"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    action: EnumProperty(items=(("ALL", "All", ""), ("NONE", "None", ""), ("INVERT", "Invert", "")))

    def execute(self, context):
        settings = context.scene.anatomesh
        rows = settings.labels if settings.kind == "LABELS" else settings.levels
        for r in rows:
            r.include = {"ALL": True, "NONE": False}.get(self.action, not r.include)
        return {"FINISHED"}


class ANATOMESH_OT_level_add(bpy.types.Operator):
    """Add an isovalue to the list"""

    bl_idname = "anatomesh.level_add"
    bl_label = "Add Isovalue"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    value: FloatProperty(name="Isovalue", default=0.0)

    def execute(self, context):
        settings = context.scene.anatomesh
        item = settings.levels.add()
        item.value = self.value
        item.name = f"level {self.value:g}"
        settings.level_index = len(settings.levels) - 1
        return {"FINISHED"}


class ANATOMESH_OT_level_remove(bpy.types.Operator):
    """Remove the active isovalue from the list"""

    bl_idname = "anatomesh.level_remove"
    bl_label = "Remove Isovalue"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    def execute(self, context):
        settings = context.scene.anatomesh
        if 0 <= settings.level_index < len(settings.levels):
            settings.levels.remove(settings.level_index)
            settings.level_index = max(0, settings.level_index - 1)
        return {"FINISHED"}


class ANATOMESH_OT_frame_camera(bpy.types.Operator):
    """Point the scene camera at the scan from the patient's front, framing every surface"""

    bl_idname = "anatomesh.frame_camera"
    bl_label = "Frame Camera"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan")
    view: EnumProperty(name="View", items=(("ANTERIOR", "Front", "From the patient's front"),
                                           ("POSTERIOR", "Back", "From the patient's back")))
    elevation: FloatProperty(name="Elevation", default=0.0, min=-89.0, max=89.0,
                             description="Degrees above the horizontal plane (toward the head)")
    azimuth: FloatProperty(name="Azimuth", default=0.0, min=-180.0, max=180.0,
                           description="Degrees around the patient's long axis")

    @guarded
    def execute(self, context):
        from ..core.model.errors import AnatomeshError

        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None:
            raise AnatomeshError("no scan collection to frame")
        scene.frame_camera(context.scene, scene.surface_objects(coll), coll.anatomesh.space, self.view,
                           self.elevation, self.azimuth)
        return {"FINISHED"}


CLASSES = (
    ANATOMESH_OT_import_scan,
    ANATOMESH_OT_extract,
    ANATOMESH_OT_smooth,
    ANATOMESH_OT_export,
    ANATOMESH_OT_labels_select,
    ANATOMESH_OT_level_add,
    ANATOMESH_OT_level_remove,
    ANATOMESH_OT_frame_camera,
)
