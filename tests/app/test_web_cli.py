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
from conftest import SAMPLE

SEG = SAMPLE / "example_seg.nii.gz"
FEW = "liver,kidney_right,gallbladder,spleen"


def cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _scene(folder):
    text = (folder / "scene.js").read_text()
    return json.loads(text[text.index("{"):text.rindex("}") + 1])


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
    scene = _scene(out / "web")
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
    scene = _scene(tmp_path / "page")
    assert [m["name"] for m in scene["models"]] == ["a", "b"] and scene["title"] == "two runs"
    summary = json.loads((tmp_path / "page.json").read_text())
    assert summary["structures"] == 6 and summary["levels"][0]["triangles"] < summary["levels"][1]["triangles"]
    stl = sorted(b.glob("*.stl"))
    code, out, err = cli(capsys, "web", *stl, "--out", tmp_path / "files", "--distance-to", "liver",
                         "--web-levels", "3")
    assert code == 0, err
    scene = _scene(tmp_path / "files")
    assert len(scene["levels"]) == 3 and scene["models"][0]["distance"]["target"] == "liver"
    code, _, err = cli(capsys, "web", a / "recipe.toml", "--out", tmp_path / "bad")
    assert code == 2 and "cannot put a .toml file on a page" in err
    code, _, err = cli(capsys, "web", a / "report.json", "--out", tmp_path / "page")
    assert code == 2 and "already exist" in err
