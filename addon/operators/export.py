"""Exporting objects through core's writers (STL, PLY, OBJ, 3MF; mm, space recorded) or Blender's
glTF exporter (metres, Y up, facing +Z as the CLI's GLB)."""
from __future__ import annotations

import os
from typing import List

import bpy
import numpy as np

from ...core.export.common import file_stem
from ..scene import bridge
from ..scene.render_gap import left_out


def object_meshes(context, objects) -> list:
    """Core :class:`Mesh` copies of ``objects`` as evaluated (modifiers applied), world mm, with
    name, label value, space and the label colour (sRGB, as the label table gives it)."""
    from ...core.model.labels import linear_to_srgb
    from ...core.model.mesh import Mesh

    objects = list(objects)
    out = []
    for o, (v, f) in zip(objects, bridge.shapes(context, objects)):
        out.append(Mesh(v, f, name=o.get("anatomesh_name", o.name), value=o.get("anatomesh_value"),
                        color=tuple(float(c) for c in linear_to_srgb(o.color[:3])),
                        space=str(o.get("anatomesh_space", "RAS"))))
    return out


def export_meshes(context, objects, folder: str, fmt: str, refuse=None) -> List[str]:
    """One file per object through core's writers (mm, ``SPACE=`` recorded); returns the paths."""
    from ...core.export.mesh_files import write_mesh

    plans, used = [], set()
    for o in objects:
        stem = file_stem(o.get("anatomesh_name", o.name))
        if stem in used:
            stem = file_stem(o.name)
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
    changes. Re-imported into Blender, the surfaces arrive in LPS (like the CLI's GLB). The
    drawn gap between touching structures (:mod:`..scene.render_gap`) is left out.
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
        with left_out(objects):  # the shapes, not the drawn gap between touching structures
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
