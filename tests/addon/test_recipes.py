"""Recipe buttons: the scene's settings → a TOML recipe the command line runs, and back."""
from __future__ import annotations

import importlib
import os

import bpy
import pytest
from conftest import shared  # tests/conftest.py


@pytest.fixture(scope="module")
def recipes(addon):
    return importlib.import_module(addon.__name__ + ".app.flow.recipe")


@pytest.fixture
def seg_path():
    return str(shared("totalsegmentator", "example_seg.nii.gz"))


def test_save_writes_the_ticked_labels_smoothing_and_export(empty_scene, recipes, seg_path, tmp_path):
    assert bpy.ops.anatomesh.import_scan(filepath=seg_path, extract=False) == {"FINISHED"}
    s = empty_scene.anatomesh
    for item in s.labels:
        item.include = item.name in ("liver", "spleen", "aorta")
    s.smooth_method, s.smooth_iterations, s.smooth_strength = "ORGAN", 15, 0.4
    s.smooth_max_deviation, s.smooth_staircase = 0.8, "OFF"
    s.space, s.export_dir, s.export_format = "LPS", str(tmp_path / "exports"), "GLB"
    path = tmp_path / "recipes" / "mine.toml"
    assert bpy.ops.anatomesh.recipe_save(filepath=str(path)) == {"FINISHED"}
    r = recipes.load_recipe(path)
    assert os.path.samefile(r.input, seg_path)
    values = {item.name: item.value for item in s.labels}
    assert sorted(r.labels) == sorted([values["liver"], values["spleen"], values["aorta"]])
    assert (r.smooth, r.iterations, r.lam, r.max_deviation) == ("organ", 15, pytest.approx(0.4), pytest.approx(0.8))
    assert r.mu is None and r.damping_distance is None and r.staircase == "off"
    assert r.space == "LPS" and r.formats == ["glb"] and r.out_dir == str(tmp_path / "exports")
    assert 'dir = "../exports"' in path.read_text()  # relative to the recipe's folder


def test_load_sets_the_panels_and_extracts(empty_scene, seg_path, tmp_path):
    path = tmp_path / "organs.toml"
    path.write_text(f'[input]\npath = "{seg_path}"\nlabels = ["liver", "spleen"]\nspace = "LPS"\n'
                    '[smoothing]\nmethod = "none"\n[output]\ndir = "out"\nformats = ["ply"]\n')
    assert bpy.ops.anatomesh.recipe_load(filepath=str(path), extract=True) == {"FINISHED"}
    s = empty_scene.anatomesh
    assert os.path.samefile(s.filepath, seg_path) and s.space == "LPS"
    assert sorted(item.name for item in s.labels if item.include) == ["liver", "spleen"]
    assert len(s.labels) == 41  # every label is listed, only the recipe's are ticked
    assert s.smooth_method == "NONE" and s.export_format == "PLY"
    assert s.export_dir == str(tmp_path / "out")
    coll = bpy.data.collections[s.last_collection]
    assert sorted(o.name for o in coll.objects) == ["liver", "spleen"]
    assert all(o["anatomesh_space"] == "LPS" for o in coll.objects)


def test_load_then_save_round_trips(empty_scene, recipes, seg_path, tmp_path):
    first = tmp_path / "a.toml"
    first.write_text(f'[input]\npath = "{seg_path}"\nlabels = [1, 5]\n'
                     '[smoothing]\nmethod = "taubin"\niterations = 12\n"lambda" = 0.3\n')
    assert bpy.ops.anatomesh.recipe_load(filepath=str(first)) == {"FINISHED"}
    assert bpy.ops.anatomesh.recipe_save(filepath=str(tmp_path / "b.toml")) == {"FINISHED"}
    a, b = recipes.load_recipe(first), recipes.load_recipe(tmp_path / "b.toml")
    assert sorted(b.labels) == [1, 5]
    assert (b.smooth, b.iterations, b.lam) == (a.smooth, a.iterations, pytest.approx(a.lam))


def test_bad_recipe_is_a_blender_error(empty_scene, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[input]\npath = "x.nii.gz"\nlabes = "all"\n')
    with pytest.raises(RuntimeError, match="unknown key 'labes'"):
        bpy.ops.anatomesh.recipe_load(filepath=str(path))
    with pytest.raises(RuntimeError, match="no scan"):
        bpy.ops.anatomesh.recipe_save(filepath=str(tmp_path / "x.toml"))


def test_decimation_target_goes_both_ways(empty_scene, recipes, seg_path, tmp_path):
    path = tmp_path / "d.toml"
    path.write_text(f'[input]\npath = "{seg_path}"\nlabels = ["spleen", "kidney_left"]\n'
                    '[decimation]\ntarget_faces = 1200\n')
    assert bpy.ops.anatomesh.recipe_load(filepath=str(path), extract=True) == {"FINISHED"}
    d = empty_scene.anatomesh_decimate
    assert (d.target, d.faces) == ("FACES", 1200)
    out = tmp_path / "saved.toml"
    assert bpy.ops.anatomesh.recipe_save(filepath=str(out)) == {"FINISHED"}
    assert recipes.load_recipe(out).target_faces is None  # not decimated yet: the recipe does not
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    coll["anatomesh_decimation_max_error_mm"] = 0.4  # what the Decimate panel's Apply records
    assert bpy.ops.anatomesh.recipe_save(filepath=str(out)) == {"FINISHED"}
    assert recipes.load_recipe(out).target_faces == 1200


def test_print_settings_go_both_ways(empty_scene, recipes, seg_path, tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(f'[input]\npath = "{seg_path}"\nlabels = ["spleen"]\n'
                    '[check]\nenabled = true\nprofile = "resin"\nmin_gap_mm = 0.35\n')
    assert bpy.ops.anatomesh.recipe_load(filepath=str(path)) == {"FINISHED"}
    p = empty_scene.anatomesh_print
    assert p.profile == "RESIN" and p.min_wall == pytest.approx(0.4) and p.min_gap == pytest.approx(0.35)
    out = tmp_path / "saved.toml"
    p.checked = True  # what running the Print panel's check records
    assert bpy.ops.anatomesh.recipe_save(filepath=str(out)) == {"FINISHED"}
    r = recipes.load_recipe(out)
    assert (r.check, r.profile, r.min_wall, r.min_gap) == (True, "resin", None, pytest.approx(0.35))


def test_panel_fields_describe_themselves_with_the_settings_own_help(empty_scene, recipes):
    """The panels' fields show the help of the setting they fill (one definition, app.recipe)."""
    help_of = recipes.setting_help
    rna = lambda group, prop: getattr(empty_scene, group).bl_rna.properties[prop].description
    assert rna("anatomesh", "smooth_iterations") == help_of("iterations", "0: the method's own")
    assert rna("anatomesh", "smooth_max_deviation").startswith("No vertex moves further than this")
    assert rna("anatomesh_decimate", "ratio") == help_of("decimate")
    assert rna("anatomesh_decimate", "max_error") == help_of("max_error")
    assert rna("anatomesh_print", "min_wall") == help_of("min_wall")
    assert rna("anatomesh_print_tools", "drain_diameter") == help_of("drain_diameter", "0: the printer profile's")


def _mod(addon, name):
    return importlib.import_module(f"{addon.__name__}.{name}")


class _Layout:
    """Records what a panel draws: ``(box label, property name)`` rows."""

    def __init__(self, rows=None, box=""):
        self.rows, self.box_label = (rows if rows is not None else []), box

    def box(self):
        return _Layout(self.rows)

    def label(self, text="", **_):
        self.box_label = text

    def column(self, **_):
        return _Layout(self.rows, self.box_label)

    def prop(self, data, name, **_):
        self.rows.append((self.box_label, name))


def test_a_new_setting_reaches_the_flags_the_recipe_file_and_the_blender_panel(addon, empty_scene):
    """A setting added by one definition (a fixture's field) is a command-line flag, a recipe-file
    key and a Blender property drawn in the Settings panel, with one help text, default and unit;
    the property's value goes into the recipe the add-on runs and back."""
    import argparse
    import dataclasses

    settings, recipe = _mod(addon, "app.flow.settings"), _mod(addon, "app.flow.recipe")
    props, panels = _mod(addon, "addon.operators.setting_props"), _mod(addon, "addon.ui.panels")
    ops_recipe = _mod(addon, "addon.operators.recipe")
    extended = dataclasses.make_dataclass("Extended", [(
        "sharpness", float, settings.setting(0.5, "smoothing", "sharpness", "float", "how sharp the edges stay",
                                             unit="mm", flag="--sharpness", metavar="MM", low=0, high=2))],
        bases=(recipe.Recipe,))
    parser = argparse.ArgumentParser()
    _mod(addon, "app.cli.settings_args").add_setting_args(parser, ["sharpness"], recipe_type=extended)
    assert "--sharpness MM how sharp the edges stay (mm); default 0.5" in " ".join(parser.format_help().split())
    assert "sharpness = 0.5" in settings.to_toml(extended(input="/a.nii.gz")).split("[smoothing]")[1]

    group = props.settings_group(extended, ops_recipe.PANEL_FIELDS + ops_recipe.NOT_IN_BLENDER,
                                 name="ANATOMESH_PG_test_extended")
    bpy.utils.register_class(group)
    try:
        bpy.types.Scene.anatomesh_test = bpy.props.PointerProperty(type=group)
        rna = group.bl_rna.properties["sharpness"]
        assert rna.description == "How sharp the edges stay, mm" and rna.default == 0.5
        assert (rna.hard_min, rna.hard_max, rna.unit) == (0.0, 2.0, "LENGTH")
        layout = _Layout()
        panels.draw_settings(layout, empty_scene.anatomesh_test, extended)
        assert ("Smoothing", "sharpness") in layout.rows
        empty_scene.anatomesh_test.sharpness = 0.25
        r = extended()
        props.group_to_recipe(empty_scene.anatomesh_test, r)
        assert r.sharpness == 0.25
        r.sharpness = 1.5
        props.recipe_to_group(r, empty_scene.anatomesh_test)
        assert empty_scene.anatomesh_test.sharpness == 1.5
    finally:
        del bpy.types.Scene.anatomesh_test
        bpy.utils.unregister_class(group)


def test_every_setting_is_in_a_panel_or_says_why_not(addon, empty_scene, recipes):
    """Each Recipe field is held by exactly one of: a hand-made panel, the generated Settings
    panel, or the list of the command line's file-only settings."""
    import dataclasses

    ops_recipe = _mod(addon, "addon.operators.recipe")
    generated = set(empty_scene.anatomesh_recipe.fields)
    hand, cli_only = set(ops_recipe.PANEL_FIELDS), set(ops_recipe.NOT_IN_BLENDER)
    names = {f.name for f in dataclasses.fields(recipes.Recipe)}
    assert not (hand & generated or hand & cli_only or generated & cli_only)
    assert hand | generated | cli_only == names
    layout = _Layout()
    _mod(addon, "addon.ui.panels").draw_settings(layout, empty_scene.anatomesh_recipe)
    assert {name for _, name in layout.rows} == generated


def test_generated_settings_go_into_the_recipe_and_back(empty_scene, recipes, seg_path, tmp_path):
    assert bpy.ops.anatomesh.import_scan(filepath=seg_path, extract=False) == {"FINISHED"}
    g = empty_scene.anatomesh_recipe
    g.cap, g.lod, g.web_levels, g.margins, g.distance_to = False, 3, 1, "[1.0, 4.0]", "liver"
    path = tmp_path / "generated.toml"
    assert bpy.ops.anatomesh.recipe_save(filepath=str(path)) == {"FINISHED"}
    r = recipes.load_recipe(path)
    assert (r.cap, r.lod, r.web_levels, r.margins, r.distance_to) == (False, 3, 1, [1.0, 4.0], "liver")
    assert r.volume_index is None and r.render_size == [960, 540]  # unset / default stay so
    g.cap, g.lod, g.margins = True, 0, ""
    assert bpy.ops.anatomesh.recipe_load(filepath=str(path)) == {"FINISHED"}
    assert (g.cap, g.lod, g.margins) == (False, 3, "[1.0, 4.0]")
    g.margins = "[1.0, oops]"
    with pytest.raises(RuntimeError, match=r"--margins must be a list of distances"):
        bpy.ops.anatomesh.recipe_save(filepath=str(tmp_path / "bad.toml"))
    assert not (tmp_path / "bad.toml").exists()


def test_level_names_go_into_the_recipe_and_back(empty_scene, recipes, tmp_path):
    ct = str(shared("totalsegmentator", "example_ct_sm.nii.gz"))
    assert bpy.ops.anatomesh.import_scan(filepath=ct, extract=False) == {"FINISHED"}
    s = empty_scene.anatomesh
    s.levels.clear()
    for name, value in (("skin", -500.0), ("bone", 300.0)):
        item = s.levels.add()
        item.name, item.value, item.include = name, value, True
    path = tmp_path / "ct.toml"
    assert bpy.ops.anatomesh.recipe_save(filepath=str(path)) == {"FINISHED"}
    r = recipes.load_recipe(path)
    assert (r.levels, r.level_names) == ([-500.0, 300.0], ["skin", "bone"])
    s.levels.clear()
    assert bpy.ops.anatomesh.recipe_load(filepath=str(path)) == {"FINISHED"}
    assert [(i.name, i.value) for i in s.levels] == [("skin", -500.0), ("bone", 300.0)]
