"""Blender side of the web page: distance colours to the active object, Export Web."""
from __future__ import annotations

import json
import sys

import bpy
import numpy as np
import pytest

from helpers.meshes import icosphere

RED = (0.9, 0.1, 0.08)


@pytest.fixture
def organs(empty_scene, addon):
    scene_mod = sys.modules[addon.__name__ + ".addon.scene.objects"]
    coll = scene_mod.new_collection("phantom")
    v, f = icosphere(3, 20.0)
    tumour = scene_mod.add_surface(coll, "tumour", v, f, {"anatomesh_value": 1, "anatomesh_name": "tumour"},
                                   color=(0.1, 0.9, 0.2))
    vessel = scene_mod.add_surface(coll, "portal_vein", v * [0.3, 0.3, 2.0] + [23.0, 0, 0], f,
                                   {"anatomesh_value": 2, "anatomesh_name": "portal_vein"}, color=(0.2, 0.3, 0.8))
    far = scene_mod.add_surface(coll, "spleen", v + [200.0, 0, 0], f,
                                {"anatomesh_value": 3, "anatomesh_name": "spleen"}, color=(0.5, 0.13, 0.3))
    bpy.context.view_layer.objects.active = tumour
    return coll, tumour, vessel, far


def _srgb(obj):
    from anatomesh.core.model.labels import linear_to_srgb

    attr = obj.data.color_attributes["anatomesh_color"]
    c = np.empty(len(obj.data.vertices) * 4, np.float32)
    attr.data.foreach_get("color", c)
    return linear_to_srgb(c.reshape(-1, 4)[:, :3])


def test_distance_to_active_colours_the_neighbours(organs):
    coll, tumour, vessel, far = organs
    assert bpy.ops.anatomesh.paint_margins(target=tumour.name, margins="2,5,10") == {"FINISHED"}
    assert "anatomesh_color" not in tumour.data.color_attributes
    near = _srgb(vessel)
    x = np.array([v.co.x for v in vessel.data.vertices])
    assert np.allclose(near[x.argmin()], RED, atol=2e-3)  # its tip runs inside the tumour: 0 mm
    assert np.allclose(_srgb(far), (0.5, 0.13, 0.3), atol=2e-3)  # far away: its own colour
    with pytest.raises(RuntimeError, match="margins"):
        bpy.ops.anatomesh.paint_margins(target=tumour.name, margins="5,2")


def test_export_web_writes_the_page_with_colours(organs, tmp_path):
    coll, tumour, vessel, far = organs
    bpy.ops.anatomesh.paint_margins(target=tumour.name)
    assert bpy.ops.anatomesh.export_web(directory=str(tmp_path), collection=coll.name) == {"FINISHED"}
    page = tmp_path / "phantom_web"
    assert (page / "index.html").exists() and (page / "viewer.js").exists()
    text = (page / "scene.js").read_text()
    scene = json.loads(text[text.index("{"):text.rindex("}") + 1])
    structures = scene["models"][0]["structures"]
    assert sorted(s["name"] for s in structures) == ["portal_vein", "spleen", "tumour"]
    full = scene["levels"][-1]["geometries"]
    coloured = {s["name"]: "c" in full[s["geometry"][-1]] for s in structures}
    assert coloured == {"tumour": False, "portal_vein": True, "spleen": True}
    assert scene["models"][0]["structures"][0]["volume_mm3"] > 30000  # 4/3 π 20³ ≈ 33510 mm³
    with pytest.raises(RuntimeError, match="already exist"):
        bpy.ops.anatomesh.export_web(directory=str(tmp_path), collection=coll.name)


def test_export_web_lists_saved_views_and_keeps_each_opacity(organs, tmp_path):
    coll, tumour, vessel, far = organs
    vessel["anatomesh_alpha"] = 0.4
    views = tmp_path / "views.toml"
    views.write_text('"vessel alone" = "hide=spleen,tumour&view=left"\n')
    assert bpy.ops.anatomesh.export_web(directory=str(tmp_path), collection=coll.name,
                                        views=str(views)) == {"FINISHED"}
    text = (tmp_path / "phantom_web" / "scene.js").read_text()
    scene = json.loads(text[text.index("{"):text.rindex("}") + 1])
    assert scene["views"] == [{"name": "vessel alone", "fragment": "hide=spleen,tumour&view=left"}]
    s = {x["name"]: x for x in scene["models"][0]["structures"]}
    assert s["portal_vein"]["opacity"] == 0.4 and "opacity" not in s["tumour"]
    bad = tmp_path / "bad.toml"
    bad.write_text('a = "view=front"\n')
    with pytest.raises(RuntimeError, match="bad.toml"):
        bpy.ops.anatomesh.export_web(directory=str(tmp_path / "x"), collection=coll.name, views=str(bad))
    assert not (tmp_path / "x").exists()
