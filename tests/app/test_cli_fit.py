"""Cut to fit through the doors: `anatomesh mesh --fit` writes the liver of the 41-label
sample as pieces that fit, with one `fit` entry in the report's fixes (volumes add up); `anatomesh
check --fit --out` does the same on mesh files; a bad --fit exits 2 with one line; the recipe keys
[check] fit_mm / fit_connectors round-trip."""
import json

import numpy as np
import pytest
from conftest import SAMPLE
from helpers.meshes import box

from anatomesh.app.cli import main
from anatomesh.app.flow.recipe import Recipe, dump_recipe, recipe_from_text
from anatomesh.core.export.mesh_files import write_stl
from anatomesh.core.io.mesh_files import read_stl
from anatomesh.core.model.mesh import Mesh


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_mesh_fit_cuts_the_liver_into_pieces_that_fit(capsys, tmp_path):
    out = tmp_path / "out"
    code, text, _ = run(capsys, "mesh", SAMPLE / "example_seg.nii.gz", "--labels", "liver",
                        "--fit", "120,120,120", "--out", out)
    assert code == 0, text
    rep = json.loads((out / "report.json").read_text())
    (fit,) = [f for f in rep["fixes"] if f["fix"] == "fit"]
    assert fit["part"] == "liver" and fit["build_volume_mm"] == [120.0, 120.0, 120.0] and fit["cuts"]
    names = [p["name"] for p in fit["pieces"]]
    assert names == [f"liver_{k}" for k in range(1, len(names) + 1)] and len(names) >= 2
    assert [s["name"] for s in rep["surfaces"]] == names
    assert all(s["closed"] and s["manifold"] for s in rep["surfaces"])
    assert sum(p["volume_mm3"] for p in fit["pieces"]) == pytest.approx(fit["volume_mm3"], rel=0.001)
    for p in fit["pieces"]:
        assert p["fits"] and np.all(np.sort(p["extents_mm"]) <= 120.0)
        tri = read_stl(out / f"{p['name']}.stl")["triangles"].reshape(-1, 3)
        assert np.all(np.sort(np.ptp(tri, axis=0)) <= 120.0)
    assert 'fit_mm = [120.0, 120.0, 120.0]' in (out / "recipe.toml").read_text()


def test_check_fit_writes_pieces_and_fit_entries(capsys, tmp_path):
    part = tmp_path / "block.stl"
    v, f = box((0, 0, 0), (100, 40, 30), 6)
    write_stl(Mesh(v, f, name="block"), part)
    out = tmp_path / "fixed"
    code, text, _ = run(capsys, "check", part, "--fit", "60,60,60", "--out", out, "--report", tmp_path / "r.json")
    assert code == 0, text
    assert sorted(p.name for p in out.glob("*.stl")) == ["block_1.stl", "block_2.stl"]
    assert "fit block: 1 cut(s) (x " in text
    rep = json.loads((tmp_path / "r.json").read_text())
    (fit,) = [f for f in rep["fixes"] if f.get("fix") == "fit"]
    assert sum(p["volume_mm3"] for p in fit["pieces"]) == pytest.approx(100 * 40 * 30, rel=1e-4)
    assert [p["name"] for p in rep["parts"]] == ["block_1", "block_2"] and rep["passed"]


@pytest.mark.parametrize("value", ["120,abc,1", "0,10,10", "100,100"])
def test_bad_fit_exits_2_with_one_line(capsys, tmp_path, value):
    code, _, err = run(capsys, "mesh", SAMPLE / "example_seg.nii.gz", "--labels", "liver", "--fit", value,
                       "--out", tmp_path / "o")
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("first run")]
    assert code == 2 and len(lines) == 1 and "--fit" in lines[0] and "X,Y,Z" in lines[0], err
    assert not (tmp_path / "o").exists()


def test_recipe_fit_keys_round_trip():
    r = Recipe(input="a.nii.gz", fit=[180.0, 180.0, 200.0], fit_connectors=True)
    back = recipe_from_text(dump_recipe(r))
    assert back.fit == [180.0, 180.0, 200.0] and back.fit_connectors is True
    assert recipe_from_text("[check]\nfit_mm = [120, 120, 100]\n").fit == [120.0, 120.0, 100.0]
    with pytest.raises(Exception, match="fit_mm"):
        recipe_from_text("[check]\nfit_mm = [120, 120]\n")
