"""The add-on's operators on the real 41-label TotalSegmentator map, through ``bpy.ops``.

Expected values come from the label map itself with numpy: which labels are present, their names
in the label table, and each label's voxel extent mapped to mm by the affine (the extracted shell
runs along the outer voxel faces, so its bounding box is the voxel box grown by half a voxel).
"""
from __future__ import annotations

import itertools
import json
import os
import struct
import sys

import bpy
import numpy as np
import pytest

from anatomesh.core.geometry.pinches import PINCH_GAP_MM
from helpers.readback import pinch_vertices
from conftest import shared  # tests/conftest.py (pytest puts tests/ on sys.path)

from anatomesh.core import load  # the checkout's core, for expected values
from anatomesh.core.model.labels import linear_to_srgb, srgb_to_linear

TABLE_KEY = "total"


@pytest.fixture(scope="module")
def seg_path():
    return str(shared("totalsegmentator", "example_seg.nii.gz"))


@pytest.fixture(scope="module")
def table_path():
    return str(shared("totalsegmentator", "label_names_total_and_total_mr.json"))


@pytest.fixture(scope="module")
def volume(seg_path, table_path):
    return load(seg_path, labels=table_path)


@pytest.fixture
def mods(addon):
    name = addon.__name__
    return sys.modules[name + ".addon.scene.bridge"], sys.modules[name + ".addon.operators.smooth"]


@pytest.fixture
def scan(empty_scene, seg_path, table_path):
    """A fresh file with the 41-label map imported and extracted (RAS)."""
    bpy.ops.ed.undo_push(message="empty")
    assert bpy.ops.anatomesh.import_scan(filepath=seg_path, label_table=table_path, extract=True) == {"FINISHED"}
    return bpy.data.collections[empty_scene.anatomesh.last_collection]


def expected_box(volume, value):
    """(2, 3) mm bounding box of the voxels of ``value``, grown by half a voxel."""
    idx = np.argwhere(np.asarray(volume.data) == value)
    lo, hi = idx.min(0) - 0.5, idx.max(0) + 0.5
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    mm = corners @ volume.affine.T
    return np.stack([mm[:, :3].min(0), mm[:, :3].max(0)])


def object_box(bridge, obj):
    """Bounding box of the surface as extracted (the rest positions live smoothing starts from)."""
    v = bridge.point_attribute(obj.data, "anatomesh_rest")
    return np.stack([v.min(0), v.max(0)])


# ---------------------------------------------------------------------------------------------
def test_objects_names_materials_and_properties(scan, volume, table_path, seg_path):
    names = json.load(open(table_path))[TABLE_KEY]
    present = [int(v) for v in np.unique(np.asarray(volume.data)) if v != 0]
    assert len(present) == 41
    objs = {o["anatomesh_value"]: o for o in scan.objects}
    assert sorted(objs) == present
    for v in present:
        o = objs[v]
        assert o.name == names[str(v)] == o["anatomesh_name"]
        assert o["anatomesh_space"] == "RAS" and o["anatomesh_units"] == "mm"
        assert os.path.samefile(o["anatomesh_source"], seg_path)
        np.testing.assert_allclose(np.reshape(list(o["anatomesh_affine"]), (4, 4)), volume.affine)
        mat = o.data.materials[0]
        colour = tuple(mat.node_tree.nodes["Anatomesh Tissue"].inputs["Base Color"].default_value)[:3]
        assert colour == pytest.approx(tuple(srgb_to_linear(volume.labels[v].color)), abs=1e-6)
        assert mat.surface_render_method == "DITHERED"
    # anatomical colours, not one grey: the liver is brown-red, a vertebra ivory
    liver = linear_to_srgb(objs[5].data.materials[0].diffuse_color[:3])
    assert liver[0] > liver[2] + 0.2
    us = bpy.context.scene.unit_settings
    assert (us.length_unit, us.scale_length) == ("MILLIMETERS", pytest.approx(0.001))
    assert scan.anatomesh.is_scan and scan.name == "example_seg"


def test_bounding_boxes_match_voxel_extents_ras(scan, volume, mods):
    bridge, _ = mods
    for o in scan.objects:  # within the pinch gap: a part touching itself may move that far out
        np.testing.assert_allclose(object_box(bridge, o), expected_box(volume, o["anatomesh_value"]),
                                   atol=PINCH_GAP_MM + 1e-4, err_msg=o.name)


def test_lps_flips_x_and_y(empty_scene, seg_path, table_path, volume, mods):
    bridge, _ = mods
    assert bpy.ops.anatomesh.extract(filepath=seg_path, label_table=table_path, space="LPS",
                                     labels="liver, spleen") == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    assert sorted(o.name for o in coll.objects) == ["liver", "spleen"]
    lps = volume.in_space("LPS")
    for o in coll.objects:
        assert o["anatomesh_space"] == "LPS"
        box = object_box(bridge, o)
        np.testing.assert_allclose(box, expected_box(lps, o["anatomesh_value"]), atol=1e-3)
        ras = expected_box(volume, o["anatomesh_value"])
        np.testing.assert_allclose(box[:, :2], -ras[::-1, :2], atol=1e-3)


def rest_of(bridge, obj):
    return bridge.point_attribute(obj.data, "anatomesh_rest")


def assert_shown_is_rest(bridge, objs):
    """The shape shown is the rest shape (the set's positions) but at pinch points, whose parts
    are shown moved apart by at most the pinch gap each."""
    objs = list(objs)
    pinch = pinch_vertices([bridge.point_attribute(o.data, "anatomesh_vid", "int") for o in objs])
    apart = np.concatenate([np.linalg.norm(bridge.positions(o.data) - rest_of(bridge, o), axis=1)
                            for o in objs])
    assert not apart[~pinch].any()
    assert apart.max(initial=0) <= 2 * PINCH_GAP_MM + 1e-4


def test_extraction_is_smoothed_with_the_command_lines_default(scan, mods):
    bridge, _ = mods
    assert scan.anatomesh.smooth_method == "ORGAN"
    moved = [np.abs(bridge.positions(o.data) - rest_of(bridge, o)).max() for o in scan.objects]
    assert max(moved) > 0.5  # not the raw staircase ...
    # ... and one click from it
    scan.anatomesh.smooth_method = "NONE"
    assert_shown_is_rest(bridge, scan.objects)


def test_live_smoothing_stays_in_voxel_and_keeps_seams(scan, mods):
    bridge, _ = mods
    objs = list(scan.objects)
    scan.anatomesh.smooth_iterations = 40  # the update callback re-smooths in place, all guards on
    moved = np.concatenate([bridge.positions(o.data) - rest_of(bridge, o) for o in objs])
    pinch = pinch_vertices([bridge.point_attribute(o.data, "anatomesh_vid", "int") for o in objs])
    assert np.abs(moved).max() > 0.5
    # the organ preset keeps every vertex inside its 3 mm voxel cell (half a voxel per axis);
    # where a part touches itself, the parts are moved apart by the pinch gap (0.05 mm) besides
    assert np.abs(moved[~pinch]).max() <= 1.5 + 1e-3
    assert np.abs(moved[pinch]).max(initial=0) <= 1.5 + 2 * PINCH_GAP_MM + 1e-3
    # seams stay shared: a vertex used by several organs has one position in all of them
    vid = np.concatenate([bridge.point_attribute(o.data, "anatomesh_vid", "int") for o in objs])
    pos = np.concatenate([bridge.positions(o.data) for o in objs])
    order = np.argsort(vid, kind="stable")
    same = (vid[order][1:] == vid[order][:-1]) & ~pinch[order][1:]
    assert same.sum() > 1000  # organs do touch in this map
    np.testing.assert_array_equal(pos[order][1:][same], pos[order][:-1][same])


def test_smooth_operator_undo_and_apply(scan, mods):
    bridge, live = mods
    name = scan.name
    shown = bridge.positions(bpy.data.objects["liver"].data).copy()
    bpy.ops.ed.undo_push(message="extracted")
    assert bpy.ops.anatomesh.smooth(collection=name, smooth_method="TAUBIN", smooth_iterations=8) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="smoothed")
    smoothed = bridge.positions(bpy.data.objects["liver"].data).copy()
    assert np.abs(smoothed - shown).max() > 0.1
    bpy.ops.ed.undo()
    np.testing.assert_array_equal(bridge.positions(bpy.data.objects["liver"].data), shown)
    # the add-on keeps working on the restored data (its cache is keyed by collection name)
    live.forget()  # and rebuilds the cache from the objects' attributes when it is gone
    assert bpy.ops.anatomesh.smooth(collection=name, smooth_method="TAUBIN", smooth_iterations=8,
                                    apply=True) == {"FINISHED"}
    liver = bpy.data.objects["liver"]
    np.testing.assert_allclose(bridge.positions(liver.data), smoothed, atol=1e-4)
    assert_shown_is_rest(bridge, bpy.data.collections[name].objects)
    assert bpy.data.collections[name].anatomesh.smooth_method == "NONE"


def test_smoothing_survives_save_and_reopen(scan, mods, tmp_path):
    bridge, _ = mods
    rest = rest_of(bridge, bpy.data.objects["liver"]).copy()
    scan.anatomesh.smooth_iterations = 6
    smoothed = bridge.positions(bpy.data.objects["liver"].data).copy()
    path = str(tmp_path / "scan.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    coll = bpy.data.collections["example_seg"]
    assert coll.anatomesh.smooth_iterations == 6 and coll.anatomesh.is_scan
    np.testing.assert_array_equal(bridge.positions(bpy.data.objects["liver"].data), smoothed)
    coll.anatomesh.smooth_method = "NONE"  # re-smoothed from the attributes stored in the file
    np.testing.assert_array_equal(rest_of(bridge, bpy.data.objects["liver"]), rest)
    assert_shown_is_rest(bridge, coll.all_objects)
    coll.anatomesh.smooth_method = "ORGAN"  # the lattice cells came back from the file too
    np.testing.assert_allclose(bridge.positions(bpy.data.objects["liver"].data), smoothed, atol=1e-3)


def test_max_deviation_is_a_hard_bound(scan, mods):
    bridge, _ = mods
    assert bpy.ops.anatomesh.smooth(collection=scan.name, smooth_method="LAPLACIAN", smooth_iterations=30,
                                    smooth_strength=0.9, smooth_max_deviation=0.4) == {"FINISHED"}
    objs = list(scan.objects)
    moved = np.concatenate([np.linalg.norm(bridge.positions(o.data) - rest_of(bridge, o), axis=1)
                            for o in objs])
    pinch = pinch_vertices([bridge.point_attribute(o.data, "anatomesh_vid", "int") for o in objs])  # parts touching themselves: moved apart besides
    assert 0.2 < moved[~pinch].max() <= 0.4 + 1e-4
    assert moved[pinch].max(initial=0) <= 0.4 + 2 * PINCH_GAP_MM + 1e-4



def test_export_files_reimport_with_same_counts_and_extents(scan, mods, volume, tmp_path):
    bridge, _ = mods
    liver = bpy.data.objects["liver"]
    v_liver = bridge.positions(liver.data)
    box = np.stack([v_liver.min(0), v_liver.max(0)])
    for fmt in ("STL", "PLY", "OBJ"):
        out = tmp_path / fmt
        assert bpy.ops.anatomesh.export(directory=str(out), format=fmt, collection=scan.name) == {"FINISHED"}
        files = sorted(p.name for p in out.iterdir())
        assert len(files) == 41 and f"liver.{fmt.lower()}" in files
    head = (tmp_path / "STL" / "liver.stl").read_bytes()[:84]
    assert b"SPACE=RAS" in head[:80] and struct.unpack("<I", head[80:84])[0] == len(liver.data.polygons)
    importers = {"STL": bpy.ops.wm.stl_import, "PLY": bpy.ops.wm.ply_import, "OBJ": bpy.ops.wm.obj_import}
    for fmt, importer in importers.items():
        before = set(bpy.data.objects)
        kwargs = {"forward_axis": "Y", "up_axis": "Z"}
        importer(filepath=str(tmp_path / fmt / f"liver.{fmt.lower()}"), **kwargs)
        new = next(o for o in bpy.data.objects if o not in before)
        v, f = bridge.world_arrays(new)
        assert len(f) == len(liver.data.polygons), fmt
        # STL stores triangles only: its importer merges equal positions
        n_expected = len(np.unique(v_liver, axis=0)) if fmt == "STL" else len(v_liver)
        assert len(v) == n_expected, fmt
        np.testing.assert_allclose(np.stack([v.min(0), v.max(0)]), box, atol=1e-3, err_msg=fmt)
    # 3MF: one print file, every organ a part with its label colour, unit mm
    from anatomesh.core.export.threemf import read_3mf

    assert bpy.ops.anatomesh.export(directory=str(tmp_path / "3MF"), format="3MF", collection=scan.name) == {"FINISHED"}
    parts = {m.name: m for m in read_3mf(tmp_path / "3MF" / "example_seg.3mf")}
    assert len(parts) == 41 and len(parts["liver"].faces) == len(liver.data.polygons)
    np.testing.assert_allclose(np.stack([parts["liver"].vertices.min(0), parts["liver"].vertices.max(0)]), box, atol=1e-3)
    assert parts["liver"].color[:3] == pytest.approx(tuple(volume.labels[5].color)[:3], abs=1 / 255)
    # glTF: one file, metres, Y up, the front facing +Z as the CLI's GLB; the importer brings
    # it back Z up, in LPS
    from anatomesh.core.export.gltf import AXES

    out = tmp_path / "GLB"
    assert bpy.ops.anatomesh.export(directory=str(out), format="GLB", collection=scan.name) == {"FINISHED"}
    assert liver.matrix_world == liver.matrix_world.Identity(4)  # the scene is left as it was
    glb = (out / "example_seg.glb").read_bytes()
    (length,) = struct.unpack("<I", glb[12:16])
    doc = json.loads(glb[20:20 + length])
    node = next(n for n in doc["nodes"] if n["name"] == "liver")
    # one primitive per material slot (the cut faces have their own): the box of them all
    accs = [doc["accessors"][p["attributes"]["POSITION"]] for p in doc["meshes"][node["mesh"]]["primitives"]]
    acc = {"min": np.min([a["min"] for a in accs], axis=0), "max": np.max([a["max"] for a in accs], axis=0)}
    assert node["scale"] == pytest.approx([0.001] * 3) and node["extras"]["anatomesh_space"] == "RAS"
    # in glTF's world (node rotation and scale on the Y-up vertex data) the liver lies where
    # the CLI's GLB puts it: glTF = AXES["RAS"] @ RAS / 1000
    x, y, z, w = node["rotation"]
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    corners = np.array(list(itertools.product(*zip(acc["min"], acc["max"]))))  # 8 box corners
    world = corners @ (0.001 * R).T
    expect = box @ AXES["RAS"].T * 0.001
    np.testing.assert_allclose(np.sort(np.stack([world.min(0), world.max(0)]), axis=0),
                               np.sort(np.stack([expect.min(0), expect.max(0)]), axis=0), atol=1e-5)
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=str(out / "example_seg.glb"))  # converts metres to the scene's mm
    new = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    assert len(new) == 41
    g = next(o for o in new if o.name.startswith("liver"))
    v, f = bridge.world_arrays(g)
    assert len(f) == len(liver.data.polygons)
    lps_box = np.sort(box * [-1, -1, 1], axis=0)  # RAS → LPS: x and y change sign
    np.testing.assert_allclose(np.stack([v.min(0), v.max(0)]), lps_box, atol=1e-2)


def test_export_refuses_to_overwrite(scan, tmp_path):
    out = tmp_path / "stl"
    assert bpy.ops.anatomesh.export(directory=str(out), format="STL", collection=scan.name) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="already exist"):
        bpy.ops.anatomesh.export(directory=str(out), format="STL", collection=scan.name)
    assert bpy.ops.anatomesh.export(directory=str(out), format="STL", collection=scan.name,
                                    overwrite=True) == {"FINISHED"}


def test_reimport_adds_alongside(scan, seg_path, table_path, mods):
    bridge, _ = mods
    first = {o.name: bridge.positions(o.data).copy() for o in scan.objects}
    assert bpy.ops.anatomesh.import_scan(filepath=seg_path, label_table=table_path, extract=True) == {"FINISHED"}
    assert "example_seg.001" in bpy.data.collections
    second = bpy.data.collections["example_seg.001"]
    assert len(second.objects) == 41 and "liver.001" in second.objects
    old = bpy.data.collections["example_seg"]
    assert sorted(o.name for o in old.objects) == sorted(first)
    for o in old.objects:
        np.testing.assert_array_equal(bridge.positions(o.data), first[o.name])


def test_bad_input_reports_error_and_changes_nothing(empty_scene, tmp_path, seg_path, table_path):
    bad = tmp_path / "broken.nii.gz"
    bad.write_bytes(b"this is not a NIfTI file")
    n_before = len(bpy.data.objects)
    for kwargs in ({"filepath": str(bad)}, {"filepath": str(tmp_path / "missing.nii.gz")}):
        with pytest.raises(RuntimeError) as err:
            bpy.ops.anatomesh.import_scan(**kwargs)
        msg = str(err.value)
        assert msg.startswith("Error: ") and "Traceback" not in msg and kwargs["filepath"] in msg
    with pytest.raises(RuntimeError, match="no label named 'no_such_organ'"):
        bpy.ops.anatomesh.extract(filepath=seg_path, label_table=table_path, labels="no_such_organ")
    with pytest.raises(RuntimeError, match="no scan collection"):
        bpy.ops.anatomesh.smooth(collection="nothing here")
    assert len(bpy.data.objects) == n_before


def test_scalar_ct_gives_preset_isosurfaces(empty_scene, mods):
    bridge, _ = mods
    ct = str(shared("totalsegmentator", "example_ct_sm.nii.gz"))
    assert bpy.ops.anatomesh.import_scan(filepath=ct, extract=False) == {"FINISHED"}
    s = empty_scene.anatomesh
    assert s.kind == "LEVELS"
    levels = {lv.name: (lv.value, lv.include) for lv in s.levels}
    assert levels["Bone"] == (300.0, True) and levels["Skin"] == (-500.0, True)
    assert bpy.ops.anatomesh.extract(levels="300") == {"FINISHED"}
    coll = bpy.data.collections[s.last_collection]
    (bone,) = coll.objects
    assert bone["anatomesh_value"] == 300 and len(bone.data.polygons) > 1000
    vol = load(ct)
    v = bridge.point_attribute(bone.data, "anatomesh_rest")  # as extracted (shown: smoothed)
    corners = np.array([[x, y, z, 1] for x in (0, vol.shape[0] - 1) for y in (0, vol.shape[1] - 1)
                        for z in (0, vol.shape[2] - 1)]) @ vol.affine.T
    # capped at the volume's border as on the command line (cap vertices sit 1e-3 of a voxel out)
    tol = 1e-3 * max(vol.spacing) + 1e-4
    assert np.all(v.min(0) >= corners[:, :3].min(0) - tol) and np.all(v.max(0) <= corners[:, :3].max(0) + tol)


def test_dicom_series_raw_values_get_histogram_presets(empty_scene, mods):
    """A CT series stored without the HU rescale (0..3926): presets from its histogram."""
    bridge, _ = mods
    head = str(shared("slicer_ctheadaxial"))
    assert bpy.ops.anatomesh.import_scan(filepath=head, extract=True) == {"FINISHED"}
    s = empty_scene.anatomesh
    assert s.modality == "CT" and s.levels[0].name == "Body outline"
    assert 300 < s.levels[0].value < 900  # between background and soft tissue (skin ~500)
    (skin,) = bpy.data.collections[s.last_collection].objects
    vol = load(head)
    assert skin["anatomesh_series_uid"] == vol.meta["series_uid"] != ""
    assert skin["anatomesh_space"] == "RAS"
    assert len(skin.data.polygons) > 10000


def test_look_settings_reach_every_object(scan):
    scan.anatomesh.alpha = 0.3
    scan.anatomesh.oriented = True
    scan.anatomesh.render_method = "BLENDED"
    for o in scan.objects:
        assert o["anatomesh_alpha"] == pytest.approx(0.3) and o["anatomesh_oriented"] == 1.0
        assert o.data.materials[0].surface_render_method == "BLENDED"


class _Layout:
    """Stands in for a panel's layout: records what is drawn and checks every name exists."""

    def __init__(self, log):
        self.log = log

    def __getattr__(self, name):  # row(), column(), box() ... return a layout; attributes are free
        return lambda *a, **k: self

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)

    def prop(self, data, name, **k):
        if name.startswith('["'):
            assert name[2:-2] in data, name
        else:
            assert hasattr(data, name), name
        self.log.append(name)

    def operator(self, idname, **k):
        mod, op = idname.split(".")
        assert op in dir(getattr(bpy.ops, mod)), idname
        self.log.append(idname)
        return _Props(idname)

    def template_list(self, listtype, list_id, data, propname, active_data, active_propname, **k):
        assert hasattr(bpy.types, listtype) and hasattr(data, propname) and hasattr(active_data, active_propname)
        self.log.append(listtype)

    def label(self, *a, **k):
        self.log.append("label")


class _Props:
    """An operator's properties as a panel sets them: only existing names are accepted."""

    def __init__(self, idname):
        mod, op = idname.split(".")
        object.__setattr__(self, "names", set(getattr(getattr(bpy.ops, mod), op).get_rna_type().properties.keys()))

    def __setattr__(self, name, value):
        assert name in self.names, name


@pytest.mark.parametrize("state", ["empty", "extracted"])
def test_panels_draw_with_existing_properties(addon, empty_scene, seg_path, table_path, state):
    if state == "extracted":
        bpy.ops.anatomesh.import_scan(filepath=seg_path, label_table=table_path, extract=True)
        bpy.context.view_layer.objects.active = bpy.data.objects["liver"]
    panels = sys.modules[addon.__name__ + ".addon.ui.panels"]
    drawn = []
    for cls in panels.CLASSES:
        if cls.__name__.startswith("ANATOMESH_PT"):
            log = []
            cls.draw(type("Panel", (), {"layout": _Layout(log)})(), bpy.context)
            assert log, cls.__name__
            drawn += log
    if state == "extracted":
        assert "ANATOMESH_UL_labels" in drawn and "anatomesh.export" in drawn and '["anatomesh_alpha"]' in drawn
        row = bpy.context.scene.anatomesh.labels[0]
        log = []
        panels.ANATOMESH_UL_labels.draw_item(None, bpy.context, _Layout(log), None, row, 0, None, "", 0)
        assert log[:2] == ["include", "color"]
