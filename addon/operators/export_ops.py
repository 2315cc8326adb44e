"""Export operator: the surfaces to files in millimetres, recording their patient space."""
from __future__ import annotations

import os

import bpy
from bpy.props import (BoolProperty, EnumProperty, StringProperty)

from ...core.export.common import file_stem, refuse_overwrite
from ...core.export.threemf import write_3mf
from ...core.model.errors import AnatomeshError
from ..scene import objects as scene
from . import warmup
from .common import abspath, active_scan, guarded
from .export import export_gltf, export_meshes, object_meshes
from . import properties as props


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
        settings = context.scene.anatomesh
        folder = abspath(self.directory or settings.export_dir)
        if not folder:
            raise AnatomeshError("no output folder; set one in the Export panel or pass directory=")
        objs, stem = self._objects(context)
        if not objs:
            raise AnatomeshError("nothing to export: select surface objects or choose a scan collection")
        if warmup.defer(self, warmup.DECIMATION_STEP):  # first run: the writers' kernels compile there
            return {"FINISHED"}
        os.makedirs(folder, exist_ok=True)
        if self.format == "3MF":
            path = os.path.join(folder, file_stem(stem) + ".3mf")
            self._refuse([path])
            write_3mf(object_meshes(context, objs), path, title=stem)
            written = [path]
        elif self.format in ("GLB", "GLTF"):
            path = os.path.join(folder, file_stem(stem) + (".glb" if self.format == "GLB" else ".gltf"))
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
        refuse_overwrite(paths, self.overwrite, "tick Overwrite or choose another folder")
