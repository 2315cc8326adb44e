"""numpy ↔ Blender mesh bridge and scene helpers, on analytic meshes with known answers."""
from __future__ import annotations

import bpy
import numpy as np
import pytest

from anatomesh.core.model.labels import srgb_to_linear


def torus(n=24, m=16, R=40.0, r=10.0):
    u = np.linspace(0, 2 * np.pi, n, endpoint=False)
    w = np.linspace(0, 2 * np.pi, m, endpoint=False)
    U, W = np.meshgrid(u, w, indexing="ij")
    v = np.stack([(R + r * np.cos(W)) * np.cos(U), (R + r * np.cos(W)) * np.sin(U), r * np.sin(W)], -1)
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    a, b = i * m + j, ((i + 1) % n) * m + j
    c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return v.reshape(-1, 3).astype(np.float32), f.astype(np.int32)


@pytest.fixture
def bridge(addon):
    from importlib import import_module

    return import_module(addon.__name__ + ".addon.scene.bridge")


@pytest.fixture
def scn(addon):
    from importlib import import_module

    return import_module(addon.__name__ + ".addon.scene.objects")


def test_round_trip_keeps_arrays_and_derives_edges(bridge, empty_scene):
    v, f = torus()
    me = bridge.new_mesh("torus", v, f)
    assert len(me.vertices) == len(v) and len(me.polygons) == len(f)
    assert len(me.edges) == 3 * len(f) // 2  # closed surface: every edge shared by two triangles
    assert me.validate(verbose=False) is False  # nothing to fix
    v2, f2 = bridge.arrays(me)
    np.testing.assert_array_equal(v2, v)
    np.testing.assert_array_equal(f2, f)
    # Euler characteristic of a torus is 0
    assert len(me.vertices) - len(me.edges) + len(me.polygons) == 0


def test_set_positions_in_place(bridge, empty_scene):
    v, f = torus()
    me = bridge.new_mesh("torus", v, f)
    n_edges = len(me.edges)
    bridge.set_positions(me, v * 2.0)
    np.testing.assert_allclose(bridge.positions(me), v * 2.0)
    assert len(me.edges) == n_edges
    with pytest.raises(ValueError):
        bridge.set_positions(me, v[:-1])


def test_bad_face_index_is_refused(bridge, empty_scene):
    v, f = torus()
    with pytest.raises(ValueError, match="out of range"):
        bridge.new_mesh("bad", v, np.r_[f, [[0, 1, len(v)]]])


def test_quads_are_read_as_fans(bridge, empty_scene):
    me = bpy.data.meshes.new("quads")
    verts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0), (3, 0.5, 0)]
    me.from_pydata(verts, [], [(0, 1, 2, 3), (1, 4, 5, 2), (4, 6, 5)])
    tri = bridge.triangles(me)
    assert tri.shape == (5, 3)
    # same covered area as the polygons
    v = np.asarray(verts, float)
    area = 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]]), axis=1)
    assert area.sum() == pytest.approx(1 + 1 + 0.5)


def test_point_attributes_round_trip(bridge, empty_scene):
    v, f = torus()
    me = bridge.new_mesh("torus", v, f)
    bridge.set_point_attribute(me, "rest", v, "vector")
    ids = np.arange(len(v), dtype=np.int32) * 3
    bridge.set_point_attribute(me, "ids", ids, "int")
    np.testing.assert_array_equal(bridge.point_attribute(me, "rest"), v)
    np.testing.assert_array_equal(bridge.point_attribute(me, "ids", "int"), ids)
    assert bridge.point_attribute(me, "missing") is None


def test_world_arrays_apply_the_object_transform(bridge, empty_scene):
    v, f = torus()
    obj = bpy.data.objects.new("t", bridge.new_mesh("torus", v, f))
    empty_scene.collection.objects.link(obj)
    obj.location = (10.0, -5.0, 2.0)
    bpy.context.view_layer.update()
    w, wf = bridge.world_arrays(obj, bpy.context.evaluated_depsgraph_get())
    np.testing.assert_allclose(w, v + np.array([10.0, -5.0, 2.0], np.float32), atol=1e-4)
    np.testing.assert_array_equal(wf, f)


def test_units_collections_and_materials(scn, empty_scene):
    scn.setup_units(empty_scene)
    us = empty_scene.unit_settings
    assert (us.system, us.length_unit, us.scale_length) == ("METRIC", "MILLIMETERS", pytest.approx(0.001))
    first = scn.new_collection("scan")
    second = scn.new_collection("scan")
    assert (first.name, second.name) == ("scan", "scan.001")
    v, f = torus()
    obj = scn.add_surface(second, "liver", v, f, {"anatomesh_value": 5, "anatomesh_space": "RAS"},
                          color=(0.5, 0.25, 0.1), render_method="BLENDED")
    assert obj.name == "liver" and obj["anatomesh_value"] == 5 and obj["anatomesh_alpha"] == 1.0
    mat = obj.data.materials[0]
    tissue = mat.node_tree.nodes["Anatomesh Tissue"]  # the tissue class's shared group
    assert tissue.node_tree.name == "Anatomesh Other" and obj["anatomesh_tissue"] == "other"
    # the label colour is sRGB; Blender's shader sockets hold linear values
    linear = tuple(srgb_to_linear(np.array([0.5, 0.25, 0.1])))
    assert tuple(tissue.inputs["Base Color"].default_value)[:3] == pytest.approx(linear, abs=1e-6)
    assert linear[0] == pytest.approx(0.2140, abs=1e-4)
    assert tissue.inputs["Alpha"].is_linked  # opacity comes from the object property
    assert mat.surface_render_method == "BLENDED"
    attrs = {n.attribute_name for n in mat.node_tree.nodes if n.type == "ATTRIBUTE"}
    assert attrs == {"anatomesh_alpha", "anatomesh_oriented"}
    np.testing.assert_array_equal(scn.bridge.point_attribute(obj.data, "anatomesh_rest"), v)
    # a second surface with the same name never replaces the first
    obj2 = scn.add_surface(second, "liver", v, f, {"anatomesh_value": 5}, color=(0, 0, 1))
    assert obj2.name == "liver.001" and obj.name == "liver"
    assert obj.data.materials[0] is not obj2.data.materials[0]


def test_oriented_alpha_group_is_shared(scn, empty_scene):
    g1 = scn.oriented_alpha_group()
    g2 = scn.oriented_alpha_group()
    assert g1 is g2
    assert [s.name for s in g1.interface.items_tree if s.in_out == "INPUT"] == ["Alpha", "Edge Alpha", "Blend"]


def test_vertex_colors_become_the_active_colour_attribute(addon, empty_scene):
    import numpy as np
    from importlib import import_module

    scene = import_module(addon.__name__ + ".addon.scene.objects")
    v = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]], np.float32)
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]], np.int32)
    srgb = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0.5]], np.float32)
    coll = scene.new_collection("painted")
    obj = scene.add_surface(coll, "tet", v, f, {}, vertex_colors=srgb)
    attr = obj.data.color_attributes.active_color
    assert attr.name == scene.COLOR_ATTRIBUTE and attr.domain == "POINT"
    got = np.zeros(16, np.float32)
    attr.data.foreach_get("color", got)
    lin = got.reshape(4, 4)
    assert np.allclose(lin[:3, :3], np.eye(3)) and abs(lin[3, 0] - 0.214) < 0.01  # sRGB 0.5 -> linear
