"""The Blender door shows the command line's colours: the style table's, with touching structures
moved apart by the same extraction stage, and the style's opacity on see-through structures."""
from __future__ import annotations

import importlib

import bpy
import pytest
from conftest import shared


def test_extracted_objects_have_the_command_lines_colours(addon, empty_scene):
    stages = importlib.import_module(addon.__name__ + ".app.flow.stages")
    Recipe = importlib.import_module(addon.__name__ + ".app.flow.recipe").Recipe
    load = importlib.import_module(addon.__name__ + ".core.io.load").load
    labels = importlib.import_module(addon.__name__ + ".core.model.labels")
    seg = str(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz"))
    table = str(shared("totalsegmentator", "label_names_total_and_total_mr.json"))
    vol = load(seg, labels=table)
    cli = {i.name: i for i in stages.extract(vol, Recipe(input=seg, label_table=table)).labels.values()}
    moved = [n for n, i in cli.items() if i.color != vol.labels[i.value].color]
    assert "aorta" in moved  # the aorta and the iliac arteries touch: one was moved
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    objs = {o["anatomesh_name"]: o for o in coll.objects}
    assert sorted(objs) == sorted(cli)
    for name, info in cli.items():
        linear = tuple(labels.srgb_to_linear(info.color))
        assert tuple(objs[name].color)[:3] == pytest.approx(linear, abs=1e-5), name
        alpha = objs[name].get("anatomesh_alpha", 1.0)
        assert alpha == pytest.approx(info.opacity, abs=1e-6), name
    assert objs["lung_lower_lobe_left"]["anatomesh_alpha"] < 0.5
