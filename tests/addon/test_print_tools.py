"""The Print panel's tools through ``bpy.ops`` give the command line's results on the
41-label sample: Fuse (liver + gallbladder re-extracted as one solid: the faces and volume of
``anatomesh mesh --fuse``), Hollow (the liver at 2 mm: the volume saved within 1 % of
``--hollow 2``), Clearance and Connectors (L1/L2: what ``--clearance`` / ``--connectors`` do);
names and materials stay, each result is recorded on the object."""
from __future__ import annotations

import importlib
import json
import sys

import bpy
import numpy as np
import pytest
from conftest import SAMPLE
from helpers.selection import select_only

from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import signed_volume

SEG = str(SAMPLE / "example_seg.nii.gz")
TABLE = str(SAMPLE / "label_names_total_and_total_mr.json")


@pytest.fixture
def bridge(addon):
    return sys.modules[addon.__name__ + ".addon.scene.bridge"]


def _cli(addon, tmp_path, **settings):
    """The command line's run for these settings (the add-on's own copy of app)."""
    app_run = importlib.import_module(addon.__name__ + ".app.flow.run")
    Recipe = importlib.import_module(addon.__name__ + ".app.flow.recipe").Recipe
    return app_run.run(Recipe(input=SEG, label_table=TABLE, out_dir=str(tmp_path), formats=["stl"], **settings))


def _extract(scene, labels):
    assert bpy.ops.anatomesh.import_scan(filepath=SEG, label_table=TABLE, extract=False) == {"FINISHED"}
    assert bpy.ops.anatomesh.extract(labels=labels) == {"FINISHED"}
    return bpy.data.collections[scene.anatomesh.last_collection]


def test_fuse_gives_the_cli_solid(addon, empty_scene, tmp_path, bridge):
    coll = _extract(empty_scene, "liver,gallbladder")
    liver, gall = coll.objects["liver"], coll.objects["gallbladder"]
    material = liver.data.materials[0]
    select_only(liver, gall)
    assert bpy.ops.anatomesh.print_fuse() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    assert [o.name for o in coll.objects] == ["liver+gallbladder"]
    obj = coll.objects["liver+gallbladder"]
    assert obj.data.materials[0] == material  # the first label's material stays
    assert json.loads(obj["anatomesh_fixes"])[0]["fix"] == "fuse"
    cli = _cli(addon, tmp_path, labels=["liver", "gallbladder"], fuse=[["liver", "gallbladder"]])
    (m,) = cli.surfaces
    v, f = bridge.arrays(obj.data)
    assert len(f) == m.n_faces and len(v) == m.n_vertices
    assert signed_volume(v, f) == pytest.approx(signed_volume(m.vertices, m.faces), rel=1e-3)
    assert float(np.abs(v - m.vertices).max()) <= 1e-3
    t = topology(v, f)
    assert t.closed and t.manifold and t.components == topology(m.vertices, m.faces).components


def test_thicken_gives_the_cli_surfaces(addon, empty_scene, tmp_path, bridge):
    coll = _extract(empty_scene, "rib_left_12,vertebrae_L1")
    select_only(*coll.objects)
    empty_scene.anatomesh_print.min_wall = 7.0  # over two of the 3 mm voxels: the rib is thin
    assert bpy.ops.anatomesh.print_thicken() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    cli = _cli(addon, tmp_path, labels=["rib_left_12", "vertebrae_L1"], thicken=True, min_wall=7.0)
    (fix,) = [x for x in cli.fixes if x["fix"] == "thicken"]
    assert sum(fix["labels"].values()) > 0  # the rib grew
    for m in cli.surfaces:
        obj = coll.objects[m.name]
        v, f = bridge.arrays(obj.data)
        assert len(f) == m.n_faces
        assert signed_volume(v, f) == pytest.approx(signed_volume(m.vertices, m.faces), rel=1e-3)
        assert json.loads(obj["anatomesh_fixes"])[0]["labels"] == {str(k): n for k, n in fix["labels"].items()}


def test_hollow_saves_the_cli_volume(addon, empty_scene, tmp_path, bridge):
    coll = _extract(empty_scene, "liver")
    liver = coll.objects["liver"]
    materials = [m.name for m in liver.data.materials]  # its tissue, and its cut faces' material
    select_only(liver)
    assert bpy.ops.anatomesh.print_hollow(wall=2.0) == {"FINISHED"}
    (entry,) = json.loads(liver["anatomesh_fixes"])
    cli = _cli(addon, tmp_path, labels=["liver"], hollow=2.0)
    (ref,) = [x for x in cli.fixes if x["fix"] == "hollow"]
    assert entry["saved_mm3"] == pytest.approx(ref["saved_mm3"], rel=0.01)
    assert entry["saved_pct"] > 80 and len(entry["drain_holes"]) == 2
    v, f = bridge.arrays(liver.data)
    assert signed_volume(v, f) == pytest.approx(entry["volume_after_mm3"], rel=1e-3)
    t = topology(v, f)
    assert t.closed and t.manifold
    assert liver.name == "liver" and [m.name for m in liver.data.materials] == materials


def test_clearance_and_connectors_on_touching_vertebrae(addon, empty_scene, tmp_path, bridge):
    coll = _extract(empty_scene, "vertebrae_L1,vertebrae_L2")
    l1, l2 = coll.objects["vertebrae_L1"], coll.objects["vertebrae_L2"]
    select_only(l1, l2)
    assert bpy.ops.anatomesh.print_connectors() == {"FINISHED"}  # pins on the active: L1
    (pins,) = json.loads(l1["anatomesh_fixes"])
    cli = _cli(addon, tmp_path / "c", labels=["vertebrae_L1", "vertebrae_L2"],
               connectors=[["vertebrae_L1", "vertebrae_L2"]])
    (ref,) = [x for x in cli.fixes if x["fix"] == "connectors"]
    assert [p["diameter_mm"] for p in pins["pins"]] == pytest.approx([p["diameter_mm"] for p in ref["pins"]], abs=1e-3)
    for o in (l1, l2):
        t = topology(*bridge.arrays(o.data))
        assert t.closed and t.manifold
    # clearance on a fresh extraction: the same vertices move as with --clearance
    coll = _extract(empty_scene, "vertebrae_L1,vertebrae_L2")
    objs = {o.name.split(".")[0]: o for o in coll.objects}
    select_only(*objs.values())  # the active object's scan is the one pulled apart
    assert bpy.ops.anatomesh.print_clearance(clearance=0.3) == {"FINISHED"}
    (entry,) = json.loads(objs["vertebrae_L1"]["anatomesh_fixes"])
    cli = _cli(addon, tmp_path / "s", labels=["vertebrae_L1", "vertebrae_L2"], clearance=0.3)
    (ref,) = [x for x in cli.fixes if x["fix"] == "clearance"]
    assert entry["moved_vertices"] == ref["moved_vertices"] > 0
    va, _ = bridge.arrays(objs["vertebrae_L1"].data)
    vb, _ = bridge.arrays(objs["vertebrae_L2"].data)
    shared = set(map(tuple, np.round(va, 4).tolist())) & set(map(tuple, np.round(vb, 4).tolist()))
    assert not shared  # no position in both parts any more


def test_print_tool_operators_can_be_undone():
    for op in ("print_fuse", "print_thicken", "print_clearance", "print_hollow", "print_connectors"):
        assert "UNDO" in getattr(bpy.types, "ANATOMESH_OT_" + op).bl_options
