"""Blender's own glTF importer reads our GLB: one object per surface, names, real size, upright."""
from __future__ import annotations

import bpy
import numpy as np
import pytest
from conftest import SAMPLE  # tests/conftest.py

from anatomesh.core import label_surfaces, load
from anatomesh.core.model.labels import srgb_to_linear
from anatomesh.core.export.gltf import write_glb

ORGANS = ("liver", "kidney_left", "gallbladder", "aorta")


@pytest.fixture(scope="module")
def organs():
    shells = label_surfaces(load(SAMPLE / "example_seg.nii.gz", space="LPS")).shells()
    return [m for m in shells if m.name in ORGANS]


def _world_box(obj):
    me = obj.data
    v = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", v)
    v = v.reshape(-1, 3).astype(np.float64)
    M = np.array(obj.matrix_world)
    w = v @ M[:3, :3].T + M[:3, 3]
    return np.stack([w.min(0), w.max(0)])


@pytest.mark.parametrize("space", ["LPS", "RAS"])
def test_blender_imports_names_sizes_colours(organs, space, tmp_path):
    meshes = []
    for m in organs:  # the same anatomy written in either space
        if space == "RAS":
            m = type(m)(m.vertices * np.float32([-1, -1, 1]), m.faces, name=m.name, value=m.value,
                        color=m.color, space="RAS")
        meshes.append(m)
    p = write_glb(meshes, tmp_path / f"organs_{space}.glb", title="organs")
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    assert scene.unit_settings.scale_length == 1.0  # so the importer keeps glTF's metres
    assert bpy.ops.import_scene.gltf(filepath=str(p)) == {"FINISHED"}
    objs = {o.name: o for o in scene.objects if o.type == "MESH"}
    assert sorted(objs) == sorted(ORGANS)
    for m in organs:  # organs are in LPS
        o = objs[m.name]
        assert len(o.data.vertices) == m.n_vertices and len(o.data.polygons) == m.n_faces
        # Blender is Z up like the patient; our root node puts any space into LPS, in metres
        expect = np.stack([m.vertices.min(0), m.vertices.max(0)]).astype(np.float64) * 0.001
        np.testing.assert_allclose(_world_box(o), expect, atol=1e-6, err_msg=m.name)
        base = o.active_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value
        np.testing.assert_allclose(base[:3], srgb_to_linear(m.color), atol=1e-5)
