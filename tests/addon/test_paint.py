"""Colour attributes from per-vertex values: colormap ends, NaN grey, active/default attribute,
the range kept on the object; curvature of a sphere and distance to the unsmoothed surface."""
from __future__ import annotations

import sys

import bpy
import numpy as np
import pytest

from helpers.meshes import icosphere


@pytest.fixture
def mods(addon):
    name = addon.__name__
    return sys.modules[name + ".addon.scene.objects"], sys.modules[name + ".addon.operators.paint"], \
        sys.modules[name + ".addon.scene.bridge"]


@pytest.fixture
def sphere(empty_scene, mods):
    scene_mod, _, _ = mods
    coll = scene_mod.new_collection("spheres")
    v, f = icosphere(3, 10.0)
    obj = scene_mod.add_surface(coll, "ball", v, f, {"anatomesh_value": 1, "anatomesh_name": "ball"})
    return obj


def _colors(obj, name):
    me = obj.data
    out = np.empty(len(me.vertices) * 4, np.float32)
    me.color_attributes[name].data.foreach_get("color", out)
    return out.reshape(-1, 4)


def test_paint_values_maps_range_and_nan(sphere, mods):
    _, paint, _ = mods
    n = len(sphere.data.vertices)
    vals = np.linspace(0.0, 1.0, n)
    vals[0] = np.nan
    lo, hi = paint.paint_values(sphere, vals, "test_values", 0.0, 1.0, colormap="heat")
    assert (lo, hi) == (0.0, 1.0)
    assert (sphere["test_values_min"], sphere["test_values_max"]) == (0.0, 1.0)
    me = sphere.data
    assert me.color_attributes.active_color.name == "test_values"
    assert me.color_attributes.default_color_name == "test_values"
    c = _colors(sphere, "test_values")
    assert np.allclose(c[0], paint.NO_VALUE)
    assert np.allclose(c[-1, :3], paint.COLORMAPS["heat"][-1, 1:], atol=1e-6)  # vmax: last colour
    assert np.allclose(c[1, :3], paint.COLORMAPS["heat"][0, 1:], atol=1e-2)  # ~vmin: first colour
    with pytest.raises(ValueError):
        paint.paint_values(sphere, vals[:-1], "test_values")
    lo, hi = paint.paint_values(sphere, np.full(n, 3.0), "flat")  # auto range, constant values
    assert lo == hi == 3.0 and np.all(np.isfinite(_colors(sphere, "flat")))


def test_curvature_of_a_sphere_is_uniform_and_one_over_r(sphere, mods):
    _, paint, _ = mods
    h = paint.curvature_values(sphere)
    assert np.median(h) == pytest.approx(0.1, rel=0.05)
    sphere.select_set(True)
    assert bpy.ops.anatomesh.paint(mode="CURVATURE") == {"FINISHED"}
    c = _colors(sphere, "anatomesh_curvature")
    assert np.ptp(c[:, :3], axis=0).max() < 0.2  # one colour all over


def test_distance_to_the_unsmoothed_surface(sphere, mods):
    _, paint, bridge = mods
    v = bridge.positions(sphere.data)
    moved = v * (10.5 / 10.0)  # "smoothing" pushed every vertex 0.5 mm outward
    bridge.set_positions(sphere.data, moved)
    d = paint.distance_values(sphere)
    assert np.allclose(d, 0.5, atol=0.02)
    sphere.select_set(True)
    assert bpy.ops.anatomesh.paint(mode="DISTANCE") == {"FINISHED"}
    assert sphere.data.color_attributes.active_color.name == "anatomesh_distance"
    assert sphere["anatomesh_distance_max"] == pytest.approx(0.5, abs=0.02)
