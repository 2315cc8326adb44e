"""Helpers every operator shares: error guard, progress, paths, the active scan, a small
volume cache (re-extracting the same scan does not read it again)."""
from __future__ import annotations

import functools
import os
import traceback
from collections import OrderedDict
from typing import List, Optional

import bpy


#: loaded volumes, newest last: (path, series, label table, space) → Volume
_VOLUMES: "OrderedDict[tuple, object]" = OrderedDict()
_MAX_VOLUMES = 2


def guarded(execute):
    """Wrap ``execute``: user errors → ERROR report + CANCELLED; never let an exception escape."""

    @functools.wraps(execute)
    def wrapper(self, context):
        from ...core.model.errors import AnatomeshError, Cancelled

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


def abspath(path: str) -> str:
    return os.path.normpath(bpy.path.abspath(path)) if path else ""


def load_volume(filepath: str, series: str = "", label_table: str = "", space: str = "RAS", progress=None,
                grid: str = "", volume_index=None):
    """The command line's reading (:func:`anatomesh.app.flow.stages.read`) with a small cache
    (re-extracting the same scan does not read it again). Mask folders, DICOM SEG and RTSTRUCT
    may give a Segmentation (overlapping structures as layers)."""
    from ...app.flow.recipe import Recipe
    from ...app.flow.stages import read

    key = (abspath(filepath), series or None, abspath(label_table) or None, space, grid or None, volume_index)
    vol = _VOLUMES.get(key)
    if vol is None:
        vol = read(Recipe(input=key[0], series=key[1], label_table=key[2], space=space, grid=key[4],
                          volume_index=volume_index), progress)
        _VOLUMES[key] = vol
        while len(_VOLUMES) > _MAX_VOLUMES:
            _VOLUMES.popitem(last=False)
    else:
        _VOLUMES.move_to_end(key)
    return vol


def parse_list(text: str) -> List[str]:
    return [t.strip() for t in text.replace(";", ",").split(",") if t.strip()]


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


def forget_volumes() -> None:
    """Drop the cached volumes (unregistering, or to free memory)."""
    _VOLUMES.clear()
