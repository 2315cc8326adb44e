"""The Blender Import door reads segmentations as users have them: a TotalSegmentator mask folder
(overlapping structures → one child collection per layer), a DICOM SEG and an RTSTRUCT folder."""
from __future__ import annotations

import bpy
import numpy as np
import pytest

from conftest import shared


@pytest.fixture
def imported(addon, empty_scene):
    def do(path, **kw):
        assert bpy.ops.anatomesh.import_scan(filepath=str(path), extract=True, **kw) == {"FINISHED"}
        return bpy.data.collections[empty_scene.anatomesh.last_collection]
    return do


def _objects(coll):
    return {o["anatomesh_name"]: o for o in coll.all_objects if "anatomesh_value" in o}


def test_mask_folder_layers_as_child_collections(imported):
    coll = imported(shared("totalsegmentator", "aorta"))
    objs = _objects(coll)
    assert len(objs) == 9 and "aorta_true_lumen" in objs
    layers = {c.name: sorted(o["anatomesh_name"] for o in c.objects) for c in coll.children}
    assert len(layers) == 3 and all(" layer " in n for n in layers)
    assert objs["aorta"]["anatomesh_layer"] != objs["aorta_true_lumen"]["anatomesh_layer"]
    lumen = objs["aorta_true_lumen"]
    v = np.array([lumen.matrix_world @ p.co for p in lumen.data.vertices])
    aorta = np.array([objs["aorta"].matrix_world @ p.co for p in objs["aorta"].data.vertices])
    assert np.all(v.min(0) >= aorta.min(0) - 3.0) and np.all(v.max(0) <= aorta.max(0) + 3.0)
    assert tuple(objs["aorta"].color)[0] > 0.5  # arteries red


def test_dicom_seg_and_rtstruct(imported, empty_scene):
    coll = imported(shared("dicom_seg", "dcmqi_ct3slice", "partial_overlaps.dcm"), space="LPS")
    objs = _objects(coll)
    assert sorted(objs) == ["DARK_BLUE", "GREEN", "LIGHT_BLUE", "ORANGE", "PURPLE"]
    assert len(coll.children) == 3
    coll = imported(shared("rtstruct", "sts_001"))
    assert list(_objects(coll)) == ["GTV_Mass_CT"]
    assert empty_scene.anatomesh.labels[0].name == "GTV_Mass_CT"
