"""Edit Mode print tools through ``bpy.ops`` on constructed meshes with known answers:
a cube with a deleted face is closed again by Fill Holes; a tiny extra shell is removed and the
big one kept; Relax moves only the selected vertices and never farther than the maximum
deviation; the selector selects exactly the non-manifold edges of a fin, the rim of a hole, and
the faces of two crossing boxes."""
from __future__ import annotations

import sys

import bmesh
import bpy
import numpy as np
import pytest

from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import signed_volume

from helpers.meshes import box


@pytest.fixture
def mods(addon):
    name = addon.__name__
    return sys.modules[name + ".addon.scene.objects"], sys.modules[name + ".addon.scene.bridge"]


def _object(mods, name, v, f):
    scene_mod, _ = mods
    coll = scene_mod.new_collection("edit")
    obj = scene_mod.add_surface(coll, name, v, f, {"anatomesh_value": 1, "anatomesh_name": name})
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj


def _edit(obj):
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    return bmesh.from_edit_mesh(obj.data)


def _object_mode():
    bpy.ops.object.mode_set(mode="OBJECT")


def _arrays(mods, obj):
    return mods[1].arrays(obj.data)


def test_fill_holes_closes_a_cube_with_a_deleted_face(empty_scene, mods):
    v, f = box((0, 0, 0), (10, 10, 10), 4)
    top = np.flatnonzero(np.all(v[f][:, :, 2] > 9.999, axis=1))
    assert top.size == 32
    obj = _object(mods, "cube", v, np.delete(f, top, axis=0))
    bm = _edit(obj)
    bm.verts.ensure_lookup_table()
    for x in bm.verts:
        x.select_set(False)
    assert bpy.ops.anatomesh.edit_fill_holes(max_edges=15) == {"FINISHED"}  # the rim has 16 edges
    _object_mode()
    vv, ff = _arrays(mods, obj)
    assert not topology(vv, ff).closed
    _edit(obj)
    assert bpy.ops.anatomesh.edit_fill_holes(max_edges=16) == {"FINISHED"}
    _object_mode()
    vv, ff = _arrays(mods, obj)
    t = topology(vv, ff)
    assert t.closed and t.manifold and t.oriented
    assert signed_volume(vv, ff) == pytest.approx(1000.0, rel=1e-6)


def test_remove_tiny_shells_keeps_the_big_one(empty_scene, mods):
    v1, f1 = box((0, 0, 0), (10, 10, 10), 3)
    v2, f2 = box((20, 0, 0), (20.5, 0.5, 0.5), 1)  # 0.125 mm³
    v3, f3 = box((30, 0, 0), (32, 2, 2), 1)  # 8 mm³
    v = np.concatenate([v1, v2, v3])
    f = np.concatenate([f1, f2 + len(v1), f3 + len(v1) + len(v2)])
    obj = _object(mods, "parts", v, f)
    _edit(obj)
    assert bpy.ops.anatomesh.edit_remove_tiny(min_volume=1.0) == {"FINISHED"}
    _object_mode()
    vv, ff = _arrays(mods, obj)
    assert len(vv) == len(v1) + len(v3) and len(ff) == len(f1) + len(f3)
    assert topology(vv, ff).components == 2
    assert signed_volume(vv, ff) == pytest.approx(1008.0, rel=1e-6)
    assert vv[:, 0].max() == pytest.approx(32.0)  # the 8 mm³ box stays, the tiny one is gone


def test_relax_moves_only_selected_vertices_within_the_max_deviation(empty_scene, mods):
    rng = np.random.default_rng(3)
    v, f = box((0, 0, 0), (10, 10, 10), 8)
    noisy = v + rng.normal(0, 0.3, v.shape)
    obj = _object(mods, "noisy", noisy, f)
    bm = _edit(obj)
    bm.verts.ensure_lookup_table()
    inner = (v[:, 0] > 0) & (v[:, 0] < 10) & (v[:, 1] > 0) & (v[:, 1] < 10)
    chosen = np.flatnonzero((v[:, 2] == 10) & inner)  # the top's inner vertices
    for i, x in enumerate(bm.verts):
        x.select_set(bool(i in set(chosen.tolist())))
    bm.select_flush_mode()
    assert bpy.ops.anatomesh.edit_relax(max_deviation=0.1, iterations=20) == {"FINISHED"}
    _object_mode()
    after, _ = _arrays(mods, obj)
    d = np.linalg.norm(after - noisy.astype(np.float32), axis=1)
    mask = np.zeros(len(v), bool)
    mask[chosen] = True
    assert np.all(d[~mask] == 0.0)
    assert d[mask].max() <= 0.1 + 1e-5
    assert np.count_nonzero(d[mask] > 1e-3) > 0.8 * mask.sum()  # they did move
    # the top got flatter: its spread in z shrank
    assert np.std(after[mask, 2]) < np.std(noisy[mask, 2])


def test_selector_selects_exactly_the_nonmanifold_edges_of_a_fin(empty_scene, mods):
    # a closed box with a fin (two triangles) hanging off one of its edges
    v, f = box((0, 0, 0), (10, 10, 10), 1)
    e0 = (0, 1)  # an edge of the box
    a, b = v[e0[0]], v[e0[1]]
    out = (a + b) / 2 + np.array([0.0, -5.0, -5.0])
    vv = np.concatenate([v, out[None]])
    ff = np.concatenate([f, [[e0[0], e0[1], len(v)]]])
    assert np.any(np.all(np.sort(f[:, :2], 1) == sorted(e0), 1) | np.all(np.sort(f[:, 1:], 1) == sorted(e0), 1)
                  | np.all(np.sort(f[:, [0, 2]], 1) == sorted(e0), 1))
    obj = _object(mods, "fin", vv, ff)
    _edit(obj)
    assert bpy.ops.anatomesh.edit_select_problem(kind="NON_MANIFOLD") == {"FINISHED"}
    bm = bmesh.from_edit_mesh(obj.data)
    sel = [tuple(sorted(x.index for x in e.verts)) for e in bm.edges if e.select]
    assert sel == [tuple(sorted(e0))]
    # the fin's two other edges are its rim: boundary edges
    assert bpy.ops.anatomesh.edit_select_problem(kind="BOUNDARY") == {"FINISHED"}
    bm = bmesh.from_edit_mesh(obj.data)
    sel = sorted(tuple(sorted(x.index for x in e.verts)) for e in bm.edges if e.select)
    assert sel == sorted([(e0[0], len(v)), (e0[1], len(v))])
    _object_mode()


def test_selector_selects_the_faces_of_crossing_boxes(empty_scene, mods):
    v1, f1 = box((0, 0, 0), (10, 10, 10), 1)
    v2, f2 = box((5, 4, 3), (15, 14, 13), 1)  # off the diagonal: no mere touching
    obj = _object(mods, "crossing", np.concatenate([v1, v2]), np.concatenate([f1, f2 + len(v1)]))
    _edit(obj)
    assert bpy.ops.anatomesh.edit_select_problem(kind="INTERSECTING") == {"FINISHED"}
    bm = bmesh.from_edit_mesh(obj.data)
    sel = np.array([x.index for x in bm.faces if x.select])
    # each box crosses the other on the three faces facing it, two triangles each
    assert len(sel) == 12 and (sel < len(f1)).sum() == 6
    _object_mode()


def test_edit_operators_need_edit_mode(empty_scene, mods):
    v, f = box((0, 0, 0), (1, 1, 1), 1)
    _object(mods, "cube", v, f)
    assert not bpy.ops.anatomesh.edit_fill_holes.poll()
    assert bpy.ops.anatomesh.edit_relax.get_rna_type().bl_rna.identifier
    for op in ("edit_select_problem", "edit_fill_holes", "edit_remove_tiny", "edit_relax"):
        assert "UNDO" in getattr(bpy.types, "ANATOMESH_OT_" + op).bl_options


def test_volumes_are_measured_in_world_mm(empty_scene, mods):
    # a 1 mm cube scaled by 2 encloses 8 mm³ in the scene: kept at 4 mm³, removed at 10 mm³
    v, f = box((0, 0, 0), (1, 1, 1), 1)
    obj = _object(mods, "scaled", v, f)
    obj.scale = (2.0, 2.0, 2.0)
    bpy.context.view_layer.update()
    _edit(obj)
    assert bpy.ops.anatomesh.edit_remove_tiny(min_volume=4.0) == {"FINISHED"}
    _object_mode()
    assert len(obj.data.polygons) == len(f)
    _edit(obj)
    assert bpy.ops.anatomesh.edit_remove_tiny(min_volume=10.0) == {"FINISHED"}
    _object_mode()
    assert len(obj.data.polygons) == 0


def test_selector_selects_thin_faces_below_the_minimum_wall(empty_scene, mods):
    # a 0.5 mm plate beside a 6 mm block, one mesh: the plate's faces are thin at 0.8 mm
    vp, fp = box((0, 0, 0), (12, 10, 0.5), 6)
    vb, fb = box((20, 0, 0), (26, 6, 6), 4)
    obj = _object(mods, "plate_block", np.concatenate([vp, vb]), np.concatenate([fp, fb + len(vp)]))
    empty_scene.anatomesh_print.min_wall = 0.8
    _edit(obj)
    assert bpy.ops.anatomesh.edit_select_problem(kind="THIN") == {"FINISHED"}
    bm = bmesh.from_edit_mesh(obj.data)
    sel = np.array([x.index for x in bm.faces if x.select])
    z = vp[fp][:, :, 2]
    flat = np.flatnonzero(np.all(z == 0.0, axis=1) | np.all(z == 0.5, axis=1))  # top and bottom
    assert set(flat.tolist()) <= set(sel.tolist())
    assert np.all(sel < len(fp))  # the plate, never the block
    _object_mode()
