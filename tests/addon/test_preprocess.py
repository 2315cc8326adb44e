"""The Preprocess panel in Blender: extraction with preprocessing on the real scans,
fuzzy shells' opacity, the isovalue gallery image, the live isovalue, and the recipe round trip."""
from __future__ import annotations

import importlib
import json
import sys

import bpy
import numpy as np
import pytest
from conftest import shared  # tests/conftest.py

from anatomesh.core.extract.isosurface import isosurface


@pytest.fixture
def mods(addon):
    return (sys.modules[addon.__name__ + ".addon.scene.bridge"],
            importlib.import_module(addon.__name__ + ".addon.operators.isovalue"))


def _read(path, **kw):
    assert bpy.ops.anatomesh.import_scan(filepath=str(path), extract=False, **kw) == {"FINISHED"}


def test_interpolate_brain_label_map(empty_scene, mods):
    bridge, _ = mods
    path = shared("pyradiomics_brain1", "brain1_label.nrrd")
    _read(path)
    p = empty_scene.anatomesh_preprocess
    p.interpolate, p.difference_colors = True, True
    assert bpy.ops.anatomesh.preprocess_extract() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    (obj,) = coll.objects
    steps = json.loads(coll["anatomesh_preprocess"])["steps"]
    assert [s["step"] for s in steps] == ["interpolate"]
    assert steps[0]["grid"]["spacing"] == pytest.approx([0.78125] * 3, abs=1e-4)
    assert 0.1 < steps[0]["effect"]["mean_mm"] < steps[0]["effect"]["max_mm"] < 6.5  # within a slice
    assert obj.data.color_attributes.get("anatomesh_color") is not None  # the difference map
    # the object's vertices sit on the 0.78 mm lattice of the interpolated map, not 6.5 mm slices
    z = np.unique(np.round(bridge.positions(obj.data)[:, 2], 3))
    assert np.diff(z).max() < 0.8


def test_fuzzy_shells_get_their_opacity(empty_scene):
    _read(shared("slicer_ctheadaxial"))
    p = empty_scene.anatomesh_preprocess
    p.fuzzy, p.fuzzy_low, p.fuzzy_high, p.fuzzy_count = True, 400.0, 800.0, 5
    assert bpy.ops.anatomesh.preprocess_extract() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    objs = sorted(coll.objects, key=lambda o: o["anatomesh_value"])
    assert [o["anatomesh_value"] for o in objs] == [400, 500, 600, 700, 800]
    assert [round(o["anatomesh_alpha"], 2) for o in objs] == [0.33, 0.67, 1.0, 0.67, 0.33]
    counts = [len(o.data.polygons) for o in objs]
    assert all(c > 1000 for c in counts)


def test_gallery_image_in_the_import_panel(empty_scene):
    _read(shared("slicer_ctheadaxial"))
    assert bpy.ops.anatomesh.preview_gallery(levels="skin:500, bone:1150") == {"FINISHED"}
    img = bpy.data.images["Anatomesh Gallery"]
    w, h = img.size
    assert w > 2 * 192 and h > 192
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    rgb = px.reshape(h, w, 4)[..., :3]
    assert (rgb < 0.9).any(axis=2).mean() > 0.05  # surfaces drawn, not a blank sheet
    assert [lv["value"] for lv in json.loads(img["anatomesh_levels"])] == [500.0, 1150.0]


def test_live_isovalue_redraws(empty_scene, mods, addon):
    bridge, live_iso = mods
    load_ = importlib.import_module(addon.__name__ + ".core").load  # the add-on's own Volume class
    path = shared("itkelastix_chest_ct")
    _read(path)
    p = empty_scene.anatomesh_preprocess
    assert bpy.ops.anatomesh.live_isovalue(level=300.0) == {"FINISHED"}
    obj = bpy.data.objects[p.live_object]
    vol = load_(str(path))
    live_iso.update(obj, vol, 300.0, stride=1)
    assert len(obj.data.polygons) == isosurface(vol.data, 300.0, vol.affine, cap=True).n_faces
    p.live_level = -500.0  # the update callback re-extracts (coarse while a drag is slow)
    assert obj["anatomesh_value"] == -500.0
    stride = obj["anatomesh_live_stride"]
    m = live_iso.extract(vol, -500.0, stride)
    assert len(obj.data.polygons) == m.n_faces
    np.testing.assert_array_equal(bridge.triangles(obj.data), m.faces)
    assert not obj.data.validate()  # nothing to fix: edges and corners were written consistently


def test_recipe_round_trip_keeps_preprocess(empty_scene, addon, tmp_path):
    recipes = importlib.import_module(addon.__name__ + ".app.flow.recipe")
    _read(shared("pyradiomics_brain1", "brain1_label.nrrd"))
    p = empty_scene.anatomesh_preprocess
    p.interpolate, p.fill_cavities, p.close_handles = True, True, 4.0
    path = tmp_path / "r.toml"
    assert bpy.ops.anatomesh.recipe_save(filepath=str(path)) == {"FINISHED"}
    r = recipes.load_recipe(path)
    assert (r.interpolate, r.fill_cavities, r.close_handles) == (True, True, 4.0)
    assert "[preprocess]" in path.read_text()
    p.interpolate, p.fill_cavities, p.close_handles = False, False, 0.0
    assert bpy.ops.anatomesh.recipe_load(filepath=str(path)) == {"FINISHED"}
    assert (p.interpolate, p.fill_cavities, p.close_handles) == (True, True, 4.0)
