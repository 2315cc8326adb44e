"""Recipe buttons: the scene's settings → a TOML recipe the command line runs, and back."""
from __future__ import annotations

import importlib
import os

import bpy
import pytest
from conftest import shared  # tests/conftest.py


@pytest.fixture(scope="module")
def recipes(addon):
    return importlib.import_module(addon.__name__ + ".app.recipe")


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
