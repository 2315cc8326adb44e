"""``--format blend,png``: the pipeline's result saved as a .blend (built as the UI builds it) and
rendered, checked by reopening the saved file.

The pipeline and the add-on are the enabled add-on's own copies (``bl_ext...anatomesh``), as in
Blender; expected values come from the report and the label table.
"""
from __future__ import annotations

import importlib
import json
import struct

import bpy
import numpy as np
import pytest
from conftest import shared  # tests/conftest.py

from anatomesh.core.model.labels import srgb_to_linear

LABELS = ["liver", "gallbladder", "spleen", "lung_lower_lobe_left"]


@pytest.fixture(scope="module")
def core(addon):
    return importlib.import_module(addon.__name__ + ".app.flow.run")


@pytest.fixture(scope="module")
def made(addon, core, tmp_path_factory):
    """One run writing stl + blend + a tiny png of four organs (decimated)."""
    out = tmp_path_factory.mktemp("headless")
    recipe = core.Recipe(input=str(shared("totalsegmentator", "example_seg.nii.gz")), out_dir=str(out),
                         labels=LABELS, decimate=0.5, formats=["stl", "blend", "png"],
                         render_samples=1, render_size=[64, 48])
    result = core.run(recipe)
    return result, out


def test_blend_holds_the_scene_the_ui_builds(made, addon):
    result, out = made
    rep = result.report
    assert rep["files"]["blend"] == "example_seg.blend"
    table = json.loads(shared("totalsegmentator", "label_names_total_and_total_mr.json").read_text())["total"]
    bpy.ops.wm.open_mainfile(filepath=str(out / "example_seg.blend"))
    coll = bpy.data.collections["example_seg"]
    assert coll.anatomesh.is_scan and coll.anatomesh.space == "RAS"
    assert coll.anatomesh.smooth_method == "NONE"  # the pipeline smoothed already: no second pass
    assert "[decimation]" in coll["anatomesh_recipe"]
    objs = {o.name: o for o in coll.objects}
    assert sorted(objs) == sorted(LABELS)
    for s in rep["surfaces"]:
        o = objs[s["name"]]
        assert table[str(o["anatomesh_value"])] == s["name"] == o["anatomesh_name"]
        assert (len(o.data.vertices), len(o.data.polygons)) == (s["vertices"], s["faces"])
        assert o["anatomesh_space"] == "RAS" and o["anatomesh_units"] == "mm"
        tissue = o.data.materials[0].node_tree.nodes["Anatomesh Tissue"]  # its class's shared group
        linear = tuple(srgb_to_linear(s["color"][:3]))  # label colours are sRGB; Blender holds linear
        assert tuple(tissue.inputs["Base Color"].default_value)[:3] == pytest.approx(linear, abs=1e-6)
        assert tuple(o.color)[:3] == pytest.approx(linear, abs=1e-6)
    # the lung is drawn see-through, the others opaque
    assert objs["lung_lower_lobe_left"]["anatomesh_alpha"] < 0.5 <= objs["liver"]["anatomesh_alpha"]
    us = bpy.context.scene.unit_settings
    assert (us.length_unit, us.scale_length) == ("MILLIMETERS", pytest.approx(0.001))
    assert bpy.context.scene.camera is not None


def test_blend_vertices_are_the_written_surfaces(made, addon):
    """Reopened objects have exactly the vertices of the STL files (mm, same space)."""
    from anatomesh.core.io.mesh_files import read_stl

    result, out = made
    bridge = importlib.import_module(addon.__name__ + ".addon.scene.bridge")
    bpy.ops.wm.open_mainfile(filepath=str(out / "example_seg.blend"))
    for s in result.report["surfaces"]:
        o = bpy.data.objects[s["name"]]
        v, f = bridge.arrays(o.data)
        tri = read_stl(out / s["files"]["stl"])["triangles"]
        np.testing.assert_allclose(v[f], tri, atol=1e-5)
    # seams: the liver and the gallbladder share vertex ids with identical positions
    liver, gall = bpy.data.objects["liver"].data, bpy.data.objects["gallbladder"].data
    ids_l = bridge.point_attribute(liver, "anatomesh_vid", "int")
    ids_g = bridge.point_attribute(gall, "anatomesh_vid", "int")
    common, il, ig = np.intersect1d(ids_l, ids_g, return_indices=True)
    assert len(common) > 20
    np.testing.assert_array_equal(bridge.positions(liver)[il], bridge.positions(gall)[ig])


def test_png_rendered(made):
    _, out = made
    data = (out / "example_seg.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert struct.unpack(">II", data[16:24]) == (64, 48)
