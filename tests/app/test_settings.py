"""One definition per setting: a recipe field defined once (``app.recipe.setting``) gives the
command-line flag and its help, the recipe file's key (read, written, checked) and the
documentation's table row."""
import argparse
import dataclasses
from pathlib import Path

import pytest

from anatomesh.app.cli.settings_args import add_setting_args
from anatomesh.app.flow.recipe import Recipe, dump_recipe, recipe_from_text
from anatomesh.app.flow.settings import sections, setting, settings_table
from anatomesh.core.model.errors import AnatomeshError

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def extended():
    """The Recipe with one new setting, added the way a developer adds one: a single definition."""
    return dataclasses.make_dataclass("Extended", [(
        "sharpness", float, setting(0.5, "smoothing", "sharpness", "float", "how sharp the edges stay",
                                    unit="mm", flag="--sharpness", metavar="MM"))], bases=(Recipe,))


def test_a_new_setting_reaches_the_flags_the_recipe_file_and_the_docs(extended):
    parser = argparse.ArgumentParser(prog="mesh")
    add_setting_args(parser, ["sharpness"], recipe_type=extended)
    text = " ".join(parser.format_help().split())
    assert "--sharpness MM how sharp the edges stay (mm); default 0.5" in text
    assert parser.parse_args(["--sharpness", "0.25"]).sharpness == 0.25
    assert parser.parse_args([]).sharpness is None  # not given: the recipe's value stays
    assert sections(extended)["smoothing"]["sharpness"] == "sharpness"
    toml = dump_recipe(extended(input="/a.nii.gz", sharpness=0.7))
    assert "sharpness = 0.7" in toml.split("[smoothing]")[1]
    assert recipe_from_text(toml, recipe_type=extended).sharpness == 0.7
    with pytest.raises(AnatomeshError, match=r"\[smoothing\] sharpness must be a number"):
        recipe_from_text('[smoothing]\nsharpness = "x"\n', recipe_type=extended)
    row = [r for r in settings_table(extended).splitlines() if "`sharpness`" in r]
    assert row and "`--sharpness`" in row[0] and "`0.5`" in row[0] and "mm" in row[0]


def test_the_docs_settings_table_is_the_definitions():
    assert settings_table(Recipe) in (REPO / "docs" / "SETTINGS.md").read_text(encoding="utf-8")


def test_every_flag_made_from_a_definition_sets_its_field():
    from anatomesh.app.cli import mesh

    parser = argparse.ArgumentParser(prog="anatomesh")
    subs = parser.add_subparsers()
    mesh.add_parser(subs)
    fields = {f.name: f for f in dataclasses.fields(Recipe)}
    flagged = [name for name, f in fields.items() if f.metadata["flag"]]
    assert set(flagged) <= set(mesh.RECIPE_FLAGS)
    for name in flagged:  # the flag's value lands in the field of the same name
        m = fields[name].metadata
        argv = ["mesh", "x.nii.gz", "--out", "o", m["flag"]]
        if m["kind"] != "bool":
            argv.append(m["choices"][-1] if m["choices"] else "3")
        recipe = mesh.recipe_from_args(parser.parse_args(argv))
        assert getattr(recipe, name) != getattr(Recipe(), name) or m["kind"] == "str", name
