"""The web page and distance colouring from the command line and recipes: `anatomesh mesh
--format web --distance-to`, `anatomesh web REPORT_OR_FILES`, the recipe's [distance] and [web]
sections, one-line errors."""
import json

import numpy as np
import pytest

from anatomesh.app.cli import main
from anatomesh.app.flow.recipe import Recipe, check_recipe, dump_recipe, recipe_from_text
from anatomesh.core.export.gltf import read_glb
from anatomesh.core.geometry.margins import MARGIN_COLORS
from anatomesh.core.model.errors import AnatomeshError
from helpers.browser import scene_of
from conftest import SAMPLE

SEG = SAMPLE / "example_seg.nii.gz"
FEW = "liver,kidney_right,gallbladder,spleen"


def cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_recipe_round_trip_of_distance_and_web_settings():
    r = Recipe(input="a.nii.gz", distance_to="liver", margins=[1.5, 4.0], web_levels=3, formats=["web"])
    back = recipe_from_text(dump_recipe(r))
    assert (back.distance_to, back.margins, back.web_levels, back.formats) == ("liver", [1.5, 4.0], 3, ["web"])
    text = dump_recipe(r)
    assert "[distance]\nto = \"liver\"\nmargins_mm = [1.5, 4.0]" in text and "[web]\nlevels = 3" in text
    assert recipe_from_text("[distance]\nto = 5\nmargins_mm = [2, 5]\n").margins == [2.0, 5.0]
    with pytest.raises(AnatomeshError, match=r"\[distance\] margins_mm must be a list of distances"):
        recipe_from_text("[distance]\nmargins_mm = 2\n")
    with pytest.raises(AnatomeshError, match="--margins must be 1 to 3 increasing"):
        check_recipe(Recipe(input="a", margins=[5, 2]))
    with pytest.raises(AnatomeshError, match=r"--web-levels must be a whole number in 1\.\.4"):
        check_recipe(Recipe(input="a", web_levels=0))


def test_mesh_format_web_with_distance_colours_in_every_output(tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = cli(capsys, "mesh", SEG, "--labels", FEW, "--format", "web,glb", "--distance-to",
                       "liver", "--margins", "3,8", "--out", out)
    assert code == 0, err
    rep = json.loads((out / "report.json").read_text())
    assert rep["distance"]["target"] == "liver" and rep["distance"]["margins_mm"] == [3.0, 8.0]
    assert rep["distance"]["shells"]["kidney_right"]["min_distance_mm"] == 0.0
    assert rep["web"]["page"] == "web/index.html" and (out / "web" / "index.html").exists()
    assert rep["web"]["levels"][-1]["triangles"] == sum(s["faces"] for s in rep["surfaces"])
    assert "[distance]" in (out / "recipe.toml").read_text()
    meshes = {m.name: m for m in read_glb(out / "example_seg.glb")}
    assert meshes["liver"].vertex_colors is None  # the target keeps its colour
    kid = meshes["kidney_right"].vertex_colors
    assert np.any(np.all(np.abs(kid - MARGIN_COLORS[0]) < 2e-3, axis=1))  # red, from the GLB's COLOR_0
    scene = scene_of(out / "web")
    model = scene["models"][0]
    assert model["distance"] == {"target": "liver", "colors": [list(c) for c in MARGIN_COLORS[:2]],
                                 "margins": [3.0, 8.0]}
    kidney = next(s for s in model["structures"] if s["name"] == "kidney_right")
    assert kidney["min_distance_mm"] == 0.0 and kidney["system"] == "organs"
    for level in scene["levels"]:  # colours on every level of detail, none on the liver
        recs = [level["geometries"][s["geometry"][scene["levels"].index(level)]] for s in model["structures"]]
        assert [("c" in r) for r in recs] == [s["name"] != "liver" for s in model["structures"]]
    code, _, err = cli(capsys, "mesh", SEG, "--labels", FEW, "--format", "web", "--out", out)
    assert code == 2 and "already exist" in err  # nothing replaced without --overwrite


def test_mesh_distance_to_an_unknown_structure_is_one_line(tmp_path, capsys):
    code, _, err = cli(capsys, "mesh", SEG, "--labels", "liver,spleen", "--format", "web",
                       "--distance-to", "tumour", "--out", tmp_path)
    assert code == 2 and "--distance-to 'tumour': no such structure; choose one of spleen, liver" in err
    code, _, err = cli(capsys, "mesh", SEG, "--labels", "liver", "--margins", "2,x", "--out", tmp_path)
    assert code == 2 and "--margins takes numbers" in err


def test_web_command_from_reports_and_mesh_files(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli(capsys, "mesh", SEG, "--labels", FEW, "--format", "glb", "--out", a)[0] == 0
    assert cli(capsys, "mesh", SEG, "--labels", "liver,spleen", "--format", "stl", "--out", b)[0] == 0
    code, out, err = cli(capsys, "web", a / "report.json", b / "report.json", "--out", tmp_path / "page",
                         "--title", "two runs", "--report", tmp_path / "page.json")
    assert code == 0, err
    assert "6 structures in 2 model(s)" in out and "MB in all" in out
    scene = scene_of(tmp_path / "page")
    assert [m["name"] for m in scene["models"]] == ["a", "b"] and scene["title"] == "two runs"
    summary = json.loads((tmp_path / "page.json").read_text())
    assert summary["structures"] == 6 and summary["levels"][0]["triangles"] < summary["levels"][1]["triangles"]
    stl = sorted(b.glob("*.stl"))
    code, out, err = cli(capsys, "web", *stl, "--out", tmp_path / "files", "--distance-to", "liver",
                         "--web-levels", "3")
    assert code == 0, err
    scene = scene_of(tmp_path / "files")
    assert len(scene["levels"]) == 3 and scene["models"][0]["distance"]["target"] == "liver"
    code, _, err = cli(capsys, "web", a / "recipe.toml", "--out", tmp_path / "bad")
    assert code == 2 and "cannot put a .toml file on a page" in err
    code, _, err = cli(capsys, "web", a / "report.json", "--out", tmp_path / "page")
    assert code == 2 and "already exist" in err


VIEWS_TOML = '''"liver cut" = "hide=skin&clip=coronal:0.45&view=anterior"

[lungs]
opacity = { "lung upper, left" = 0.3, liver = 0.5 }
hide = ["spleen"]
clip = "axial:0.6:flip"
view = "left"
measure = [[1, 2, 3], [4, 5, 6.5]]
'''


def test_views_file_goes_into_the_page_from_mesh_and_web(tmp_path, capsys):
    views = tmp_path / "views.toml"
    views.write_text(VIEWS_TOML)
    out = tmp_path / "out"
    code, _, err = cli(capsys, "mesh", SEG, "--labels", "liver,spleen", "--format", "web,glb", "--out", out,
                       "--web-views", views)
    assert code == 0, err
    want = [{"name": "liver cut", "fragment": "hide=skin&clip=coronal:0.45&view=anterior"},
            {"name": "lungs", "fragment": "hide=spleen&opacity=lung%20upper%2C%20left:0.3,liver:0.5"
                                          "&clip=axial:0.6:flip&view=left&measure=1,2,3;4,5,6.5"}]
    assert scene_of(out / "web")["views"] == want
    assert "views = " in (out / "recipe.toml").read_text()  # kept in the recipe
    js = tmp_path / "views.json"
    js.write_text(json.dumps({"front": "view=anterior", "cut": {"clip": "sagittal:0.5"}}))
    code, _, err = cli(capsys, "web", out / "report.json", "--out", tmp_path / "page", "--web-views", js)
    assert code == 0, err
    assert scene_of(tmp_path / "page")["views"] == [{"name": "front", "fragment": "view=anterior"},
                                                 {"name": "cut", "fragment": "clip=sagittal:0.5"}]


@pytest.mark.parametrize("text, words", [
    ('a = "clip=axial:1.5"', "view 'a': clip is axial|coronal|sagittal:F"),
    ('a = "zoom=2"', "view 'a': unknown key 'zoom'"),
    ('[a]\nview = "front"', "view 'a': view is one of anterior"),
    ('a = "opacity=liver:2"', "view 'a': opacity is NAME:A with A in 0..1"),
    ('a = ', "not valid TOML"),
])
def test_a_bad_views_file_is_one_line_naming_it_before_any_reading(tmp_path, capsys, text, words):
    views = tmp_path / "bad.toml"
    views.write_text(text)
    code, _, err = cli(capsys, "mesh", tmp_path / "missing.nii.gz", "--format", "web", "--out", tmp_path / "o",
                       "--web-views", views)
    assert code == 2 and words in err and str(views) in err and len(err.strip().splitlines()) == 1, err
    code, _, err = cli(capsys, "web", tmp_path / "missing.json", "--out", tmp_path / "p", "--web-views", views)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err
    code, _, err = cli(capsys, "web", tmp_path / "missing.json", "--out", tmp_path / "p", "--web-views",
                       tmp_path / "nope.toml")
    assert code == 2 and "cannot read the views file" in err and "nope.toml" in err


def test_default_opacity_of_a_structure_is_its_colours_alpha(tmp_path):
    from anatomesh.app.web.page import WebModel, write_page
    from anatomesh.core.model.mesh import Mesh
    from helpers.meshes import icosphere

    v, f = icosphere(2, 10.0)
    glass = Mesh(v, f, name="lung", color=(0.8, 0.6, 0.6, 0.35), space="RAS")
    solid = Mesh(v + [30, 0, 0], f, name="liver", color=(0.5, 0.2, 0.1), space="RAS")
    write_page([WebModel("m", [[glass, solid]])], tmp_path)
    s = {x["name"]: x for x in scene_of(tmp_path)["models"][0]["structures"]}
    assert s["lung"]["opacity"] == 0.35 and "opacity" not in s["liver"]
