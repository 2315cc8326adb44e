"""One smoothing in every door: the Blender operators give the command line's surfaces.

The same settings through ``bpy.ops.anatomesh`` (extraction with the default, the Smooth operator
with overrides) and through :func:`anatomesh.app.flow.run.run` give the same vertices (1e-3 mm), on the
41- and 61-label TotalSegmentator maps; after smoothing in Blender the print checks find no face
crossing another, within a part or between parts.
"""
from __future__ import annotations

import importlib
import sys

import bpy
import numpy as np
import pytest
from conftest import shared

TABLE = ("totalsegmentator", "label_names_total_and_total_mr.json")
MAPS = {41: ("totalsegmentator", "example_seg.nii.gz"),
        61: ("totalsegmentator", "example_seg_fast_force_split.nii.gz")}


def _cli(addon, seg, table, tmp_path, **smoothing):
    """The command line's surfaces for these settings, by name (the add-on's own copy of app)."""
    app_run = importlib.import_module(addon.__name__ + ".app.flow.run")
    Recipe = importlib.import_module(addon.__name__ + ".app.flow.recipe").Recipe
    res = app_run.run(Recipe(input=seg, label_table=table, out_dir=str(tmp_path), formats=["stl"],
                             **smoothing))
    return {m.name: m.vertices for m in res.surfaces}


def _ui(bridge, coll):
    return {o.name: bridge.positions(o.data) for o in coll.objects}


@pytest.mark.parametrize("labels", [41, 61])
def test_extraction_default_equals_the_cli_default(addon, empty_scene, tmp_path, labels):
    bridge = sys.modules[addon.__name__ + ".addon.scene.bridge"]
    seg, table = str(shared(*MAPS[labels])), str(shared(*TABLE))
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    ui, cli = _ui(bridge, coll), _cli(addon, seg, table, tmp_path)
    assert sorted(ui) == sorted(cli) and len(ui) == labels
    worst = max(float(np.abs(ui[n] - cli[n]).max()) for n in ui)
    assert worst <= 1e-3, worst


def test_smooth_operator_overrides_equal_the_cli_flags(addon, empty_scene, tmp_path):
    bridge = sys.modules[addon.__name__ + ".addon.scene.bridge"]
    seg, table = str(shared(*MAPS[41])), str(shared(*TABLE))
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    assert bpy.ops.anatomesh.smooth(collection=coll.name, smooth_method="STRONG", smooth_iterations=30,
                                    smooth_strength=0.55, smooth_max_deviation=1.0) == {"FINISHED"}
    cli = _cli(addon, seg, table, tmp_path, smooth="strong", iterations=30, lam=0.55, max_deviation=1.0)
    ui = _ui(bridge, coll)
    assert max(float(np.abs(ui[n] - cli[n]).max()) for n in ui) <= 1e-3


def test_no_crossing_faces_after_smoothing_in_blender(addon, empty_scene):
    bridge = sys.modules[addon.__name__ + ".addon.scene.bridge"]
    Mesh = importlib.import_module(addon.__name__ + ".core.model.mesh").Mesh
    check_parts = importlib.import_module(addon.__name__ + ".core.printing.checks").check_parts
    seg, table = str(shared(*MAPS[61])), str(shared(*TABLE))
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    coll.anatomesh.smooth_iterations = 50  # a live slider move: the full guarded driver again
    meshes = [Mesh(*bridge.arrays(o.data), name=o.name) for o in coll.objects]
    rep = check_parts(meshes)
    assert sum(p["self_intersections"] for p in rep["parts"]) == 0
    assert rep["intersections"] == []


@pytest.mark.parametrize("labels, target", [(41, dict(target="RATIO", ratio=0.3)),
                                            (61, dict(target="FACES", faces=40000))])
def test_decimate_apply_equals_the_cli_decimation(addon, empty_scene, tmp_path, labels, target):
    """Apply at a ratio or a face count gives the faces and vertices of ``anatomesh mesh
    --decimate`` / ``--target-faces`` (capped at one voxel's error like the command)."""
    from scipy.spatial import cKDTree

    bridge = sys.modules[addon.__name__ + ".addon.scene.bridge"]
    seg, table = str(shared(*MAPS[labels])), str(shared(*TABLE))
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    assert bpy.ops.anatomesh.decimate_apply(collection=coll.name, **target) == {"FINISHED"}
    flags = dict(decimate=target["ratio"]) if "ratio" in target else dict(target_faces=target["faces"])
    app_run = importlib.import_module(addon.__name__ + ".app.flow.run")
    Recipe = importlib.import_module(addon.__name__ + ".app.flow.recipe").Recipe
    res = app_run.run(Recipe(input=seg, label_table=table, out_dir=str(tmp_path), formats=["stl"], **flags))
    cli = {m.name: m for m in res.surfaces}
    ui = {o.name: o for o in coll.objects}
    assert sorted(ui) == sorted(cli)
    faces = {n: (len(ui[n].data.polygons), cli[n].n_faces) for n in ui}
    assert all(a == b for a, b in faces.values()), {n: f for n, f in faces.items() if f[0] != f[1]}
    worst = max(float(cKDTree(cli[n].vertices).query(bridge.positions(ui[n].data))[0].max()) for n in ui)
    assert worst <= 1e-3, worst
