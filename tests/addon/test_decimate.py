"""The Decimate panel's operators on the real 41-label TotalSegmentator map, through ``bpy.ops``:
Apply decimates every organ with core (seams stay shared, shells closed, errors stored), the
preview adds Blender's Decimate modifier, undo restores the objects."""
from __future__ import annotations

import sys

import bpy
import numpy as np
import pytest
from conftest import shared
from helpers.readback import pinch_vertices

from anatomesh.core.geometry.topology import topology


@pytest.fixture
def mods(addon):
    name = addon.__name__
    return sys.modules[name + ".addon.scene.bridge"], sys.modules[name + ".addon.operators.decimate"]


@pytest.fixture
def scan(empty_scene):
    seg = str(shared("totalsegmentator", "example_seg.nii.gz"))
    table = str(shared("totalsegmentator", "label_names_total_and_total_mr.json"))
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=True) == {"FINISHED"}
    return bpy.data.collections[empty_scene.anatomesh.last_collection]


def _faces(coll):
    return {o.name: len(o.data.polygons) for o in coll.objects}


def _shared_positions_agree(bridge, objs):
    """Vertices with the same shared id (seams between organs) sit at one position in every
    object, but at pinch points, where the parts touching there move at most the pinch gap
    (0.05 mm) each; returns how many vertices are shared by two or more objects."""
    vid = np.concatenate([bridge.point_attribute(o.data, "anatomesh_vid", "int") for o in objs])
    own = np.concatenate([np.full(len(o.data.vertices), k) for k, o in enumerate(objs)])
    pos = np.concatenate([bridge.positions(o.data) for o in objs])
    order = np.lexsort((own, vid))
    same = vid[order][1:] == vid[order][:-1]
    apart = np.linalg.norm(pos[order][1:][same] - pos[order][:-1][same], axis=1)
    twice = same & (own[order][1:] == own[order][:-1])  # a copy in one object: a pinch point
    pinch_ids = np.unique(vid[order][1:][twice])
    assert apart.max(initial=0) <= 2 * 0.05 + 1e-4
    assert np.isin(vid[order][1:][same][apart > 0], pinch_ids).all()
    cross = same & (own[order][1:] != own[order][:-1])
    return int(cross.sum())


def _interface_faces(bridge, objs):
    """Triangles (as sorted shared-id triples) used by two objects, per object pair."""
    seen = {}
    for k, o in enumerate(objs):
        vid = bridge.point_attribute(o.data, "anatomesh_vid", "int")
        for tri in map(tuple, np.sort(vid[bridge.triangles(o.data)], axis=1).tolist()):
            seen.setdefault(tri, []).append(k)
    return {t: ks for t, ks in seen.items() if len(ks) > 1}


def test_apply_fewer_faces_seams_shared_errors_stored_and_undo(scan, mods):
    bridge, ui = mods
    objs = list(scan.objects)
    name = scan.name
    before = _faces(scan)
    shared_before = _shared_positions_agree(bridge, objs)
    assert shared_before > 1000                          # organs touch in this map
    bpy.ops.ed.undo_push(message="extracted")
    # smoothed at extraction (the default): Apply decimates the shape shown and bakes it
    assert bpy.ops.anatomesh.decimate_apply(collection=scan.name, target="RATIO",
                                            ratio=0.2) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="decimated")
    after = _faces(scan)
    assert all(after[n] < before[n] for n in before)
    assert sum(after.values()) < 0.35 * sum(before.values())
    assert scan.anatomesh.smooth_method == "NONE"
    # seams: shared vertices identical, and each interface triangle used by exactly two organs
    assert _shared_positions_agree(bridge, objs) > 100
    inter = _interface_faces(bridge, objs)
    assert len(inter) > 100 and all(len(ks) == 2 and ks[0] != ks[1] for ks in inter.values())
    vids = [bridge.point_attribute(o.data, "anatomesh_vid", "int") for o in objs]
    points = np.split(pinch_vertices(vids), np.cumsum([len(v) for v in vids])[:-1])
    for o, pinch in zip(objs, points):
        v, f = bridge.arrays(o.data)
        t = topology(v, f)
        assert t.closed and t.manifold and t.oriented, (o.name, t)
        # the rest shape is the decimated set's; the shape shown moves the pinch points apart
        apart = np.linalg.norm(bridge.point_attribute(o.data, "anatomesh_rest") - v, axis=1)
        assert not apart[~pinch].any() and apart.max(initial=0) <= 2 * 0.05 + 1e-4
        assert o["anatomesh_faces_before"] == before[o.name]
        assert 0.0 < o["anatomesh_decimation_mean_error_mm"] <= o["anatomesh_decimation_max_error_mm"] < 6.0
        assert "anatomesh_decimation_volume_change_pct" in o
    # undo brings the extracted (smoothed) objects back
    bpy.ops.ed.undo()
    assert _faces(bpy.data.collections[name]) == before


def test_max_error_target_is_honoured_per_organ(scan, mods):
    bridge, _ = mods
    before = _faces(scan)
    assert bpy.ops.anatomesh.decimate_apply(collection=scan.name, target="ERROR",
                                            max_error=1.5) == {"FINISHED"}
    for o in scan.objects:
        assert o["anatomesh_decimation_max_error_mm"] <= 1.5
        assert len(o.data.polygons) <= before[o.name]
    assert sum(_faces(scan).values()) < 0.8 * sum(before.values())
    assert scan["anatomesh_decimation_max_error_mm"] <= 1.5
    # the live cache was rebuilt from the decimated objects: smoothing still works on them
    scan.anatomesh.smooth_method = "LIGHT"
    assert _shared_positions_agree(bridge, list(scan.objects)) > 100


def test_preview_modifier_then_apply_removes_it(scan, mods):
    _, ui = mods
    settings = bpy.context.scene.anatomesh_decimate
    assert bpy.ops.anatomesh.decimate_preview(collection=scan.name, target="FACES",
                                              faces=20000) == {"FINISHED"}
    objs = list(scan.objects)
    total = sum(len(o.data.polygons) for o in objs)
    before = {o.name: len(o.data.polygons) for o in objs}
    mods_ = {o.name: o.modifiers[ui.PREVIEW_MODIFIER] for o in objs}
    assert all(m.type == "DECIMATE" and 0 < m.ratio < 1 for m in mods_.values())
    # each organ's ratio is what Apply will give it (the run of `anatomesh mesh --target-faces`)
    planned = {n: round(m.ratio * before[n]) for n, m in mods_.items()}
    assert 20000 <= sum(planned.values()) <= 1.2 * 20000  # capped at one voxel's error: stops short
    deps = bpy.context.evaluated_depsgraph_get()
    shown = sum(len(o.evaluated_get(deps).data.polygons) for o in objs)
    assert shown < 0.5 * total                         # non-destructive: the data is untouched
    assert sum(len(o.data.polygons) for o in objs) == total
    # with a preview on, changing the ratio in the panel settings updates the modifiers
    bpy.context.view_layer.active_layer_collection = \
        bpy.context.view_layer.layer_collection.children[scan.name]
    settings.target, settings.ratio = "RATIO", 0.3
    assert objs[0].modifiers[ui.PREVIEW_MODIFIER].ratio == pytest.approx(0.3)  # instant, uniform
    settings.target, settings.faces = "FACES", 20000
    assert bpy.ops.anatomesh.decimate_apply(collection=scan.name, target="FACES", faces=20000) == {"FINISHED"}
    assert not any(ui.PREVIEW_MODIFIER in o.modifiers for o in objs)
    assert {o.name: len(o.data.polygons) for o in objs} == planned


def test_errors_are_reported_not_raised(empty_scene):
    with pytest.raises(RuntimeError, match="no scan collection"):
        bpy.ops.anatomesh.decimate_apply(collection="nope")


def test_objects_reassemble_into_the_extracted_surface_set(scan, mods):
    """The shells on the objects give back core's SurfaceSet: same faces (interfaces once), same
    pinch-point split rows; the panel class is registered in the sidebar tab."""
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.io import load

    _, ui = mods
    ss, members = ui.surface_set_from_objects(list(scan.objects))
    core = label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))
    assert ss.n_faces == core.n_faces and ss.n_vertices == core.n_vertices
    assert len(ss.splits) == len(core.splits) > 0
    for value, shell in zip(ss.values(), ss.shells()):
        t = topology(shell.vertices, shell.faces)
        assert t.closed and t.manifold and t.oriented, (members[value - 1].name, t)
        assert shell.n_faces == len(members[value - 1].data.polygons)
    assert bpy.types.ANATOMESH_PT_decimate.bl_category == "Anatomesh"
