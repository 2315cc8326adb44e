"""The Print panel through ``bpy.ops``: phantoms with known answers (a 0.5 mm plate, two blocks
0.3 mm apart, a thick block) checked together; problems listed with their values and places;
selecting a problem selects its object and puts the cursor there; selection-only checks; the
profile fills in its limits; heat maps painted from the panel."""
from __future__ import annotations

import sys

import bpy
import numpy as np
import pytest

from anatomesh.core.printing.profiles import PROFILES

from helpers.meshes import box


@pytest.fixture
def mods(addon):
    name = addon.__name__
    return sys.modules[name + ".addon.scene.objects"], sys.modules[name + ".addon.operators.print_check"]


@pytest.fixture
def phantoms(empty_scene, mods):
    """Anatomesh objects: plate (0.5 mm thick), left/right blocks 0.3 mm apart, far block."""
    scene_mod, _ = mods
    coll = scene_mod.new_collection("phantoms")
    objs = {}
    for name, lo, hi, n in (("plate", (0, 0, 0), (12, 10, 0.5), 6),
                            ("left", (0, 20, 0), (6, 26, 6), 4),
                            ("right", (6.3, 20, 0), (12, 26, 6), 4),
                            ("far", (40, 0, 0), (46, 6, 6), 4)):
        v, f = box(lo, hi, n)
        objs[name] = scene_mod.add_surface(coll, name, v, f, {"anatomesh_value": len(objs) + 1,
                                                              "anatomesh_name": name})
    bpy.context.view_layer.update()
    return objs


def test_check_lists_thin_plate_and_close_blocks_with_values_and_places(phantoms, mods):
    s = bpy.context.scene.anatomesh_print
    assert (s.min_wall, s.min_gap) == pytest.approx((0.8, 0.5))
    assert bpy.ops.anatomesh.print_check() == {"FINISHED"}
    assert s.checked and not s.passed
    rows = [(p.part, p.other, p.kind, p.value, tuple(p.location)) for p in s.problems]
    thin = [r for r in rows if r[2] == "thin sheet"]
    assert {r[0] for r in thin} == {"plate"} and len(thin) == 1  # top and bottom: one sheet
    assert min(r[3] for r in thin) == pytest.approx(0.5, abs=0.15)
    assert 0 <= thin[0][4][0] <= 12 and 0 <= thin[0][4][1] <= 10 and 0 <= thin[0][4][2] <= 0.5
    gaps = [r for r in rows if r[2] == "gap below minimum"]
    assert len(gaps) == 1 and {gaps[0][0], gaps[0][1]} == {"left", "right"}
    assert gaps[0][3] == pytest.approx(0.3, abs=0.01) and 6.0 <= gaps[0][4][0] <= 6.3
    assert not any(r[0] == "far" or r[1] == "far" for r in rows)
    assert phantoms["far"]["anatomesh_print_passed"] == 1
    assert phantoms["plate"]["anatomesh_print_passed"] == 0
    assert phantoms["plate"]["anatomesh_min_wall_mm"] == pytest.approx(0.5, abs=0.15)


def test_select_problem_selects_object_and_moves_cursor(phantoms):
    s = bpy.context.scene.anatomesh_print
    bpy.ops.anatomesh.print_check()
    i = next(k for k, p in enumerate(s.problems) if p.kind == "gap below minimum")
    assert bpy.ops.anatomesh.print_select_problem(index=i) == {"FINISHED"}
    prob = s.problems[i]
    assert bpy.context.view_layer.objects.active.name == prob.part
    assert {o.name for o in bpy.context.selected_objects} == {"left", "right"}
    assert tuple(bpy.context.scene.cursor.location) == pytest.approx(tuple(prob.location))
    assert s.problem_index == i
    assert bpy.ops.anatomesh.print_select_problem(index=99) == {"CANCELLED"}  # no such row


def test_resin_profile_and_selection_only(phantoms):
    s = bpy.context.scene.anatomesh_print
    s.profile = "RESIN"
    assert (s.min_wall, s.min_gap) == pytest.approx((PROFILES["resin"]["min_wall"], PROFILES["resin"]["min_gap"]))
    assert bpy.ops.anatomesh.print_check() == {"FINISHED"}
    assert s.passed and len(s.problems) == 0  # 0.5 mm plate and 0.3 mm gap are fine for resin
    s.profile = "FDM"
    for o in bpy.context.scene.objects:
        o.select_set(o.name in ("left", "far"))
    s.selected_only = True
    assert bpy.ops.anatomesh.print_check() == {"FINISHED"}
    assert s.passed and "2/2" in s.summary  # the plate and the close neighbour are not checked


def test_heat_maps_from_the_panel(phantoms):
    for o in bpy.context.scene.objects:
        o.select_set(o.name in ("plate", "left", "right"))
    assert bpy.ops.anatomesh.paint(mode="THICKNESS", min_wall=0.8) == {"FINISHED"}
    me = phantoms["plate"].data
    assert me.color_attributes.active_color.name == "anatomesh_thickness"
    rgba = np.empty(len(me.vertices) * 4, np.float32)
    me.color_attributes["anatomesh_thickness"].data.foreach_get("color", rgba)
    rgba = rgba.reshape(-1, 4)
    v = np.array([p.co for p in me.vertices])
    inner = (v[:, 0] > 0) & (v[:, 0] < 12) & (v[:, 1] > 0) & (v[:, 1] < 10)  # top and bottom
    assert inner.sum() > 40 and np.all(rgba[inner, 0] > rgba[inner, 2])  # thin: red over blue
    me = phantoms["left"].data  # a 6 mm block: thick (blue) away from its edges
    rgba = np.empty(len(me.vertices) * 4, np.float32)
    me.color_attributes["anatomesh_thickness"].data.foreach_get("color", rgba)
    assert np.median(rgba.reshape(-1, 4)[:, 2]) > 0.8
    assert bpy.ops.anatomesh.paint(mode="GAP") == {"FINISHED"}
    me = phantoms["left"].data
    v = np.array([p.co for p in me.vertices])
    rgba = np.empty(len(me.vertices) * 4, np.float32)
    me.color_attributes["anatomesh_gap"].data.foreach_get("color", rgba)
    rgba = rgba.reshape(-1, 4)
    near = v[:, 0] == pytest.approx(6.0)
    assert np.all(rgba[near, 0] > 0.7) and np.all(rgba[v[:, 0] == 0.0, 2] > 0.5)
