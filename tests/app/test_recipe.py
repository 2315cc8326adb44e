"""Recipe files: TOML written by hand and read back with tomllib, paths, and one-line errors."""
import dataclasses
import os
import tomllib

import pytest

from anatomesh.core.model.errors import AnatomeshError
from anatomesh.app.flow.recipe import Recipe
from anatomesh.app.flow.recipe import SECTIONS, dump_recipe, load_recipe, recipe_from_text


def full_recipe(tmp_path) -> Recipe:
    """A recipe with every field away from its default (paths absolute, under tmp_path)."""
    return Recipe(
        input=str(tmp_path / "scans" / "seg \"quoted\" ü.nii.gz"), out_dir=str(tmp_path / "out"),
        series="1.2.840.113619.2.1", volume_index=2, label_table=str(tmp_path / "scans" / "t.json"),
        labels=["liver", 3, "kidney\\left"], levels=[-500.0, 300.5], space="LPS", cap=False,
        keep_largest=True, min_component_mm3=12.5, smooth="hc", iterations=7, lam=0.25, mu=-0.3,
        max_deviation=0.75, damping_distance=2.0, staircase="off", decimate=None, target_faces=None,
        max_error=0.4, check=True, profile="resin", min_wall=0.6, min_gap=0.3,
        formats=["stl", "3mf", "glb", "blend"], render_samples=8, render_size=[320, 200],
        report=str(tmp_path / "out" / "r.json"), overwrite=True)


def test_every_recipe_field_has_one_key():
    fields = [f.name for f in dataclasses.fields(Recipe)]
    mapped = [name for keys in SECTIONS.values() for name in keys.values()]
    assert sorted(mapped) == sorted(fields)  # each field once: UI, CLI and file hold the same settings


def test_round_trip_every_field(tmp_path):
    r = full_recipe(tmp_path)
    path = tmp_path / "recipes" / "r.toml"
    path.parent.mkdir()
    text = dump_recipe(r, base=path.parent)
    tomllib.loads(text)  # valid TOML for any reader
    path.write_text(text)
    back = load_recipe(path)
    assert back == r
    # paths sharing a folder with the recipe are written relative to it
    doc = tomllib.loads(text)
    assert doc["input"]["path"] == "../scans/seg \"quoted\" ü.nii.gz"
    assert doc["output"]["dir"] == "../out"
    assert doc["decimation"] == {"max_error_mm": 0.4} and doc["check"]["enabled"] is True


def test_round_trip_defaults_and_without_base(tmp_path):
    r = Recipe(input="/data/a.nii.gz", out_dir="/data/out")
    assert recipe_from_text(dump_recipe(r)) == r
    r2 = Recipe(input=["/d/1.dcm", "/d/2.dcm"], decimate=0.25, labels="all")
    assert recipe_from_text(dump_recipe(r2)) == r2


def test_relative_paths_resolve_against_the_recipe_folder(tmp_path, monkeypatch):
    (tmp_path / "project").mkdir()
    (tmp_path / "project" / "recipe.toml").write_text(
        '[input]\npath = "scans/seg.nii.gz"\nlabel_table = "../tables/t.json"\n'
        '[output]\ndir = "out"\n')
    monkeypatch.chdir(tmp_path)  # not the folder the paths are relative to
    r = load_recipe("project/recipe.toml")
    assert r.input == os.path.normpath(tmp_path / "project" / "scans" / "seg.nii.gz")
    assert r.label_table == os.path.normpath(tmp_path / "tables" / "t.json")
    assert r.out_dir == os.path.normpath(tmp_path / "project" / "out")
    assert r.smooth == "organ" and r.formats == ["stl"]  # keys not given keep the defaults


def test_only_the_root_in_common_stays_absolute(tmp_path):
    text = dump_recipe(Recipe(input="/definitely/elsewhere/scan.nii.gz"), base=tmp_path)
    assert tomllib.loads(text)["input"]["path"] == "/definitely/elsewhere/scan.nii.gz"


@pytest.mark.parametrize("text, words", [
    ('[input]\npath = "a.nii"\nlable = "liver"\n', ["'lable'", "[input]", "labels", "label_table"]),
    ('[decimate]\nratio = 0.5\n', ["[decimate]", "decimation", "smoothing"]),
    ('[decimation]\nratio = "half"\n', ["ratio", "number", "'half'"]),
    ('[check]\nenabled = 1\n', ["enabled", "true or false"]),
    ('[output]\nformats = "stl"\n', ["formats", "list"]),
    ('[input]\nlabels = [1.5]\n', ["labels", "all"]),
    ('input = "a.nii"\n', ["input", "section"]),
    ('[input\npath = 1\n', ["not valid TOML"]),
])
def test_errors_name_the_key_and_what_is_allowed(tmp_path, text, words):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(AnatomeshError) as err:
        load_recipe(path)
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg
    for w in words:
        assert w in msg


def test_missing_recipe_file(tmp_path):
    with pytest.raises(AnatomeshError, match="no such recipe file"):
        load_recipe(tmp_path / "nope.toml")


def test_integers_accepted_for_numbers(tmp_path):
    r = recipe_from_text('[decimation]\nmax_error_mm = 1\n[input]\nlevels = [300, -500]\n')
    assert r.max_error == 1.0 and isinstance(r.max_error, float)
    assert r.levels == [300.0, -500.0]


def test_example_recipe_loads():
    from conftest import REPO

    r = load_recipe(REPO / "examples" / "recipe_organs.toml")
    assert os.path.exists(r.input) and r.decimate == 0.5 and "liver" in r.labels
    assert r.formats == ["stl", "3mf", "glb"] and r.out_dir == str(REPO / "demo_out" / "organs")
