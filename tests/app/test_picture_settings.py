"""The pictures' settings (views, labels, turntable): from flags and recipe files to the checked
recipe, without Blender."""
from __future__ import annotations

import pytest

from anatomesh.app.cli import main
from anatomesh.app.cli.mesh import add_parser, recipe_from_args
from anatomesh.app.flow.outputs import needs_blender
from anatomesh.app.flow.recipe import VIEWS, Recipe, check_recipe, dump_recipe, recipe_from_text
from anatomesh.core.model.errors import AnatomeshError


def parse(*flags):
    import argparse

    parser = argparse.ArgumentParser(prog="anatomesh")
    add_parser(parser.add_subparsers())
    recipe = recipe_from_args(parser.parse_args(["mesh", "seg.nii.gz", "--out", "o", *flags]))
    check_recipe(recipe)
    return recipe


def test_flags_become_lists():
    r = parse("--view", "Anterior,lateral_left", "--labels-on", "liver,spleen", "--turntable", "36")
    assert r.views == ["anterior", "lateral_left"] and r.labels_on == ["liver", "spleen"]
    assert r.turntable == 36 and needs_blender(r)  # frames need Blender even without png
    assert parse().views == ["anterior"] and not needs_blender(parse())


def test_a_recipe_file_carries_them():
    r = Recipe(input="seg.nii.gz", views=["oblique", "superior"], labels_on=["liver"], turntable=12)
    back = recipe_from_text(dump_recipe(r))
    assert (back.views, back.labels_on, back.turntable) == (["oblique", "superior"], ["liver"], 12)
    assert "views = [\"oblique\", \"superior\"]" in dump_recipe(r)


def test_unknown_view_is_one_line_naming_them(capsys):
    with pytest.raises(AnatomeshError, match="unknown --view sideways; use a comma list of anterior, posterior"):
        parse("--view", "anterior,sideways")
    assert main(["mesh", "seg.nii.gz", "--out", "o", "--view", "back"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(v in err[0] for v in VIEWS)
    with pytest.raises(AnatomeshError, match="--turntable"):
        parse("--turntable", "-1")
