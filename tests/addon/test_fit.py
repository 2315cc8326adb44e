"""Cut to Fit in Blender: the Print panel's button cuts a block too long for the build
volume into closed pieces in its collection (named <part>_1, <part>_2, with its material and
properties) and hides the block; a part that fits is left alone."""
from __future__ import annotations

import sys

import bpy
import numpy as np
import pytest

from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import signed_volume

from helpers.meshes import box


@pytest.fixture
def blocks(empty_scene, addon):
    scene_mod = sys.modules[addon.__name__ + ".addon.scene.objects"]
    coll = scene_mod.new_collection("blocks")
    objs = {}
    for name, lo, hi in (("long", (0, 0, 0), (100, 40, 30)), ("small", (200, 0, 0), (230, 30, 30))):
        v, f = box(lo, hi, 6)
        objs[name] = scene_mod.add_surface(coll, name, v, f, {"anatomesh_value": len(objs) + 1,
                                                              "anatomesh_name": name}, color=(0.9, 0.2, 0.2))
    bpy.context.view_layer.update()
    return coll, objs


def test_cut_to_fit_button_splits_the_long_block_only(blocks, addon):
    coll, objs = blocks
    bridge = sys.modules[addon.__name__ + ".addon.scene.bridge"]
    fit = bpy.context.scene.anatomesh_fit
    assert tuple(fit.size) == pytest.approx((180, 180, 180)) and not fit.connectors
    assert bpy.ops.anatomesh.print_fit(size=(60, 60, 60)) == {"FINISHED"}
    pieces = sorted((o for o in coll.objects if o.get("anatomesh_fit_of") == "long"), key=lambda o: o.name)
    assert [o.name for o in pieces] == ["long_1", "long_2"]
    assert objs["long"].hide_get() and not objs["small"].hide_get()
    total = 0.0
    for o in pieces:
        v, f = bridge.world_arrays(o)
        t = topology(v, f)
        assert t.closed and t.manifold and t.oriented
        assert np.all(np.sort(np.ptp(v, axis=0)) <= 60.0)
        assert o["anatomesh_value"] == 1 and o.active_material == objs["long"].active_material
        total += signed_volume(v, f)
    assert total == pytest.approx(100 * 40 * 30, rel=1e-4)
    assert not [o for o in coll.objects if o.get("anatomesh_fit_of") == "small"]
