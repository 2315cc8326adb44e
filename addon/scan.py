"""A scan in Blender: fill the Labels panel from a volume, extract its surfaces with the same stage
functions as the command line, and add them to the scene (collection, objects, live-smoothing cache)."""
from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

import bpy
import numpy as np

from . import live, scene
from .common import parse_list
from .ui import presets


_KERNELS_WARM = False


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
        values = select_labels(volume, parse_list(text))
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
        for t in parse_list(text):
            try:
                v = float(t)
            except ValueError:
                from ..core.model.errors import AnatomeshError

                raise AnatomeshError(f"isovalue {t!r} is not a number; give levels like '300, -500'")
            out.append((v, f"level {v:g}", (0.9, 0.85, 0.75)))
        return out
    return [(item.value, item.name, tuple(item.color)) for item in settings.levels if item.include]


def object_props(volume, value, name) -> dict:
    return {
        "anatomesh_value": float(value) if not float(value).is_integer() else int(value),
        "anatomesh_name": str(name),
        "anatomesh_source": str(volume.meta.get("source", "")),
        "anatomesh_series_uid": str(volume.meta.get("series_uid", "") or ""),
        "anatomesh_space": volume.space,
        "anatomesh_affine": [float(x) for x in np.asarray(volume.affine).ravel()],
        "anatomesh_units": "mm",
    }


def frame_viewports(context, collection) -> None:
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
                items.append((m, v, name, color, shared_index(m)))
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
    from . import warmup

    if not warmup.ready("smoothing"):  # speed (first run): they compile in the background
        return coll
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
        obj = scene.add_surface(coll, name, m.vertices, m.faces, object_props(volume, value, name),
                                color, render_method, shared_index=shared, vertex_colors=m.vertex_colors)
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


def shared_index(mesh) -> np.ndarray:
    """Index of each shell vertex in its surface set's vertex array (``Mesh.meta["vertex_ids"]``)."""
    idx = mesh.meta.get("vertex_ids")
    if idx is None or len(idx) != mesh.n_vertices:
        raise RuntimeError(f"shell {mesh.name!r} lacks meta['vertex_ids'] (core SurfaceSet changed?)")
    return np.asarray(idx, np.int64)
