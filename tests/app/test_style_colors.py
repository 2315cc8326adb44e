"""Colours every door gets from the extraction stage: the style table, touching structures told
apart (CIE76 ΔE >= 12, two bones excepted) on real TotalSegmentator maps, and the user's
``--style`` file end to end into the written GLB, PLY and 3MF."""
import json
import struct
import zipfile

import numpy as np
import pytest
import trimesh

from anatomesh.app.cli import main as cli_main
from anatomesh.app.flow import stages
from anatomesh.app.flow.recipe import Recipe, load_recipe
from anatomesh.core.io.load import load
from anatomesh.core.model.contrast import delta_e, srgb_to_lab, touching_pairs
from anatomesh.core.model.labels import srgb_to_linear
from anatomesh.core.model.style import load_style
from conftest import SAMPLE, shared

MAPS = {41: ("totalsegmentator", "example_seg.nii.gz"),
        61: ("totalsegmentator", "example_seg_fast_force_split.nii.gz"),
        23: ("totalsegmentator", "example_seg_mr.nii.gz")}


@pytest.mark.parametrize("n", sorted(MAPS))
def test_touching_structures_differ_by_delta_e_12(n):
    vol = load(shared(*MAPS[n]))
    surfaces = stages.extract(vol, Recipe(input="x"))
    table, style = surfaces.labels, load_style()
    assert len(table) == n
    pairs = touching_pairs(surfaces)
    checked = 0
    for a, b in pairs:
        bones = table[a].material == "bone" and table[b].material == "bone"
        d = delta_e(table[a].color, table[b].color)
        assert d >= (2.5 if bones else 12), (table[a].name, table[b].name, round(d, 2))
        checked += not bones
    assert checked >= 13  # the 23-label map has the fewest non-bone contacts
    for info in table.values():  # each colour stays near its style colour: recognisable
        assert delta_e(info.color, style.style_of(info.name).color) <= 32, info.name
    L, a, b = srgb_to_lab(next(i.color for i in table.values() if i.name == "liver"))
    assert 20 < L < 55 and a > 10 and b > 10  # liver: a dark reddish brown


def _glb_json(path):
    raw = path.read_bytes()
    n = struct.unpack("<I", raw[12:16])[0]
    return json.loads(raw[20:20 + n])


def test_a_style_file_changes_the_written_colours(tmp_path):
    mine = tmp_path / "mine.toml"
    mine.write_text('[structures]\nliver = { color = "#00ff00" }\n'
                    'lung_lower_lobe_left = { opacity = 0.6 }\n')
    out = tmp_path / "out"
    code = cli_main(["mesh", str(SAMPLE / "example_seg.nii.gz"), "--out", str(out),
                     "--format", "glb,ply,3mf", "--style", str(mine)])
    assert code == 0
    materials = {m["name"]: m for m in _glb_json(out / "example_seg.glb")["materials"]}
    assert materials["liver"]["pbrMetallicRoughness"]["baseColorFactor"] == \
        pytest.approx([*srgb_to_linear([0.0, 1.0, 0.0]), 1.0])  # the user's colour, not moved
    lower = materials["lung_lower_lobe_left"]
    assert lower["alphaMode"] == "BLEND" and lower["pbrMetallicRoughness"]["baseColorFactor"][3] == 0.6
    upper = materials["lung_upper_lobe_left"]
    assert upper["alphaMode"] == "BLEND" and upper["pbrMetallicRoughness"]["baseColorFactor"][3] < 0.4
    assert "alphaMode" not in materials["spleen"]
    ply = trimesh.load(out / "liver.ply", process=False)
    assert np.all(ply.visual.vertex_colors[:, :3] == [0, 255, 0])
    lung = trimesh.load(out / "lung_lower_lobe_left.ply", process=False)
    assert np.all(lung.visual.vertex_colors[:, 3] == round(0.6 * 255))
    with zipfile.ZipFile(out / "liver.3mf") as z:
        model = z.read("3D/3dmodel.model").decode()
    assert "#00FF00" in model.upper()
    assert load_recipe(out / "recipe.toml").style == str(mine)


def test_a_recipe_names_its_style_file_relative_to_itself(tmp_path):
    (tmp_path / "recipe.toml").write_text('[input]\npath = "x.nii.gz"\n[output]\nstyle = "looks.toml"\n')
    assert load_recipe(tmp_path / "recipe.toml").style == str(tmp_path / "looks.toml")


def test_a_bad_style_file_stops_the_run_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[structures]\nliver = { color = "brown" }\n')
    code = cli_main(["mesh", str(SAMPLE / "example_seg.nii.gz"), "--out", str(tmp_path / "o"),
                     "--style", str(bad)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and str(bad) in err[0] and "#rrggbb" in err[0]


def test_colours_of_a_users_colour_table_are_kept(tmp_path):
    vol = load(SAMPLE / "example_seg.nii.gz")
    rows = [f"{v} {info.name} 200 150 120 255" for v, info in vol.labels.items()
            if info.name in ("small_bowel", "colon")]  # one colour for two touching organs
    (tmp_path / "mine.ctbl").write_text("\n".join(rows) + "\n")
    names = {info.name: v for v, info in vol.labels.items()}
    vol = load(SAMPLE / "example_seg.nii.gz", labels=str(tmp_path / "mine.ctbl"))
    table = stages.extract(vol, Recipe(input="x")).labels
    for n in ("small_bowel", "colon"):
        assert table[names[n]].color == pytest.approx((200 / 255, 150 / 255, 120 / 255))
        assert table[names[n]].color_given and table[names[n]].material == "hollow"
