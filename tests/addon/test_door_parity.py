"""Every door, every stage: the Blender operators give what ``run()`` / ``anatomesh mesh`` gives.

On the 41- and 61-label TotalSegmentator maps (3 mm voxels), the same settings through
``bpy.ops.anatomesh`` and through :func:`anatomesh.app.flow.run.run` (the add-on's own copy of
``app``) give the same parts (names), the same face counts and vertices within 1e-3 mm, for:

* preprocessing: the Preprocess panel's *Extract with Preprocessing* (fill cavities, close
  handles) vs ``fill_cavities`` / ``close_handles``; on the CT of the 41-label map (resample,
  Gaussian volume smoothing, an isosurface) vs ``resample`` / ``smooth_volume`` / ``levels``;
* the Print panel's tools: Fuse, Thicken, Clearance, Hollow, Connectors vs ``fuse``,
  ``thicken``, ``clearance``, ``hollow``, ``connectors``;
* Cut to Fit vs ``fit``: the same pieces (``<part>_1``, ...), the cut parts hidden;
* the print check: the Print panel's problem list, per-part verdict and thinnest wall equal the
  rows of the CLI report's ``print_check``;
* Export: the STL files and the 3MF of the Export operator read back by position (trimesh) like
  the command line's files;
* a recipe saved in Blender after changing the smoothing and decimating: the command line run
  on it (``python -m anatomesh.app.cli mesh --recipe``) writes STL files byte for byte equal to
  Blender's Export of the same objects (same float32 vertices, same triangle order and winding,
  same header), so the vertex arrays are equal too.

Blender's float properties are float32: settings are chosen exact in float32 (0.25 mm, not
0.3) where a tool takes them from an operator; the Print panel's minimum wall (0.8 mm, FDM)
is 0.800000011920929 in Blender, which moves connector pins by about 2e-6 mm.
Each test prints its worst vertex difference (``pytest -s``).
"""
from __future__ import annotations

import importlib
import json
import subprocess
import sys

import bpy
import numpy as np
import pytest
from conftest import shared
from scipy.spatial import cKDTree

from helpers.readback import read_back
from helpers.selection import select_only

TABLE = ("totalsegmentator", "label_names_total_and_total_mr.json")
MAPS = {41: ("totalsegmentator", "example_seg.nii.gz"),
        61: ("totalsegmentator", "example_seg_fast_force_split.nii.gz")}
TOL_MM = 1e-3


# ---------------------------------------------------------------------------------------------
# the two doors
# ---------------------------------------------------------------------------------------------
def _paths(n):
    return str(shared(*MAPS[n])), str(shared(*TABLE))


def _mod(addon, name):
    """A module of the add-on's own copy (``app.flow.run``, ``addon.scene.bridge``, ...)."""
    return importlib.import_module(f"{addon.__name__}.{name}")


def _cli(addon, n, out, **settings):
    """``run()`` on the ``n``-label map with these recipe settings (the command line's flow)."""
    seg, table = _paths(n)
    Recipe = _mod(addon, "app.flow.recipe").Recipe
    recipe = Recipe(input=seg, label_table=table, out_dir=str(out), **{"formats": ["stl"], **settings})
    return _mod(addon, "app.flow.run").run(recipe)


def _scan(scene, n, extract=True):
    """Import (and extract, smoothed with the default) the ``n``-label map; the scan collection."""
    seg, table = _paths(n)
    assert bpy.ops.anatomesh.import_scan(filepath=seg, label_table=table, extract=extract) == {"FINISHED"}
    return bpy.data.collections.get(scene.anatomesh.last_collection)


def _shown(addon, coll):
    """``{object name: (vertices, faces)}`` of the scan's visible surfaces, world mm."""
    bridge = _mod(addon, "addon.scene.bridge")
    objs = _mod(addon, "addon.scene.objects").surface_objects(coll)
    return {o.name: bridge.world_arrays(o) for o in objs if not o.hide_get()}


def _worst(ui, surfaces, what):
    """Same part names, face and vertex counts; the largest vertex difference (mm), printed."""
    cli = {m.name: m for m in surfaces}
    assert sorted(ui) == sorted(cli)
    counts = {n: (len(ui[n][1]), cli[n].n_faces, len(ui[n][0]), cli[n].n_vertices) for n in ui}
    assert all(a == b and c == d for a, b, c, d in counts.values()), \
        [f"{n}: Blender {a:,} faces, {c:,} vertices; run() {b:,} faces, {d:,} vertices"
         for n, (a, b, c, d) in counts.items() if a != b or c != d]
    worst = max(float(np.abs(ui[n][0] - cli[n].vertices).max()) for n in ui)
    print(f"\n{what}: {len(ui)} parts, {sum(c[0] for c in counts.values()):,} faces, worst {worst:.2e} mm")
    return worst


# ---------------------------------------------------------------------------------------------
# 1. preprocessing
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("labels", [41, 61])
def test_preprocess_extract_equals_run(addon, empty_scene, tmp_path, labels):
    _scan(empty_scene, labels, extract=False)
    p = empty_scene.anatomesh_preprocess
    p.fill_cavities, p.close_handles = True, 9.0
    assert bpy.ops.anatomesh.preprocess_extract() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    steps = json.loads(coll["anatomesh_preprocess"])["steps"]
    assert [s["step"] for s in steps] == ["fill_cavities", "close_handles"]
    assert max(s["effect"]["max_mm"] for s in steps) > 0  # the steps change the surfaces
    res = _cli(addon, labels, tmp_path, fill_cavities=True, close_handles=9.0)
    assert _worst(_shown(addon, coll), res.surfaces, f"preprocess {labels}") <= TOL_MM


# ---------------------------------------------------------------------------------------------
# 2. the Print panel's tools
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("labels", [41, 61])
def test_fuse_equals_run(addon, empty_scene, tmp_path, labels):
    coll = _scan(empty_scene, labels)
    assert bpy.ops.anatomesh.print_fuse(labels="liver,gallbladder") == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    assert "liver+gallbladder" in coll.objects
    res = _cli(addon, labels, tmp_path, fuse=[["liver", "gallbladder"]])
    assert _worst(_shown(addon, coll), res.surfaces, f"fuse {labels}") <= TOL_MM


def test_thicken_equals_run(addon, empty_scene, tmp_path):
    _scan(empty_scene, 41)
    empty_scene.anatomesh_print.min_wall = 7.0  # over two 3 mm voxels: ribs and small parts grow
    assert bpy.ops.anatomesh.print_thicken() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    res = _cli(addon, 41, tmp_path, thicken=True, min_wall=7.0)
    (fix,) = [f for f in res.fixes if f["fix"] == "thicken"]
    assert sum(fix["labels"].values()) > 0
    assert _worst(_shown(addon, coll), res.surfaces, "thicken 41") <= TOL_MM


def test_clearance_equals_run(addon, empty_scene, tmp_path):
    """Every surface of the scan (41 labels; the 61-label map takes half a minute per door).
    0.25 mm: Blender's float properties are float32, 0.3 would be 0.30000001 in Blender."""
    coll = _scan(empty_scene, 41)
    assert bpy.ops.anatomesh.print_clearance(clearance=0.25) == {"FINISHED"}
    res = _cli(addon, 41, tmp_path, clearance=0.25)
    assert _worst(_shown(addon, coll), res.surfaces, "clearance 41") <= TOL_MM


def test_hollow_equals_run(addon, empty_scene, tmp_path):
    """Kidneys and adrenal glands of the 41-label map: parts the FDM profile's 4 mm drain holes
    fit on (they do not on thin parts such as the aorta, in either door)."""
    parts = ["kidney_right", "kidney_left", "adrenal_gland_right", "adrenal_gland_left"]
    _scan(empty_scene, 41, extract=False)
    assert bpy.ops.anatomesh.extract(labels=",".join(parts)) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    select_only(*coll.objects)
    assert bpy.ops.anatomesh.print_hollow(wall=2.0) == {"FINISHED"}
    res = _cli(addon, 41, tmp_path, labels=parts, hollow=2.0)
    assert _worst(_shown(addon, coll), res.surfaces, "hollow 41") <= TOL_MM


@pytest.mark.parametrize("labels", [41, 61])
def test_connectors_equal_run(addon, empty_scene, tmp_path, labels):
    coll = _scan(empty_scene, labels)
    select_only(coll.objects["vertebrae_L1"], coll.objects["vertebrae_L2"])  # pins on the active: L1
    assert bpy.ops.anatomesh.print_connectors() == {"FINISHED"}
    res = _cli(addon, labels, tmp_path, connectors=[["vertebrae_L1", "vertebrae_L2"]])
    assert _worst(_shown(addon, coll), res.surfaces, f"connectors {labels}") <= TOL_MM


# ---------------------------------------------------------------------------------------------
# 3. cut to fit
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("labels, pins", [(41, True), (61, False)])
def test_cut_to_fit_equals_run(addon, empty_scene, tmp_path, labels, pins):
    coll = _scan(empty_scene, labels)
    assert bpy.ops.anatomesh.print_fit(size=(120.0, 100.0, 120.0), connectors=pins) == {"FINISHED"}
    res = _cli(addon, labels, tmp_path, fit=[120.0, 100.0, 120.0], fit_connectors=pins)
    ui = _shown(addon, coll)
    assert any(n.endswith("_2") for n in ui)  # some parts were cut
    assert _worst(ui, res.surfaces, f"cut to fit {labels}") <= TOL_MM


# ---------------------------------------------------------------------------------------------
# 4. print check
# ---------------------------------------------------------------------------------------------
def _rows(problems):
    return sorted((r["part"], r.get("other", ""), r["kind"], r["value"], tuple(r["location"])) for r in problems)


def test_print_check_equals_the_cli_check(addon, empty_scene, tmp_path):
    coll = _scan(empty_scene, 41)
    assert bpy.ops.anatomesh.print_check() == {"FINISHED"}
    s = empty_scene.anatomesh_print
    rep = _cli(addon, 41, tmp_path, check=True).report["print_check"]
    cli = _rows(_mod(addon, "addon.operators.print_check").problems_of(rep))
    ui = _rows([dict(part=p.part, other=p.other, kind=p.kind, value=p.value, location=p.location)
                for p in s.problems])
    assert [r[:3] for r in ui] == [r[:3] for r in cli] and len(cli) > 0
    worst = max(max(abs(a[3] - b[3]), *np.abs(np.subtract(a[4], b[4]))) for a, b in zip(ui, cli))
    print(f"\nprint check: {len(ui)} problems, worst value/location difference {worst:.2e}")
    assert worst <= TOL_MM
    objs = {o.name: o for o in coll.objects}
    assert sorted(objs) == sorted(p["name"] for p in rep["parts"])
    for p in rep["parts"]:
        o = objs[p["name"]]
        assert bool(o["anatomesh_print_passed"]) == p["passed"]
        assert o["anatomesh_min_wall_mm"] == pytest.approx(-1.0 if p["min_wall_mm"] is None else p["min_wall_mm"],
                                                           abs=TOL_MM)
    assert s.passed == rep["passed"]


# ---------------------------------------------------------------------------------------------
# 5. export
# ---------------------------------------------------------------------------------------------
def _read_worst(a, b):
    """Face counts equal and the largest distance (mm) between the two files' vertex sets, as
    read back by position."""
    assert len(a.faces) == len(b.faces) and len(a.vertices) == len(b.vertices)
    return max(float(cKDTree(a.vertices).query(b.vertices)[0].max()),
               float(cKDTree(b.vertices).query(a.vertices)[0].max()))


@pytest.mark.parametrize("labels", [41, 61])
def test_export_stl_and_3mf_equal_the_cli_files(addon, empty_scene, tmp_path, labels):
    coll = _scan(empty_scene, labels)
    ui_dir, cli_dir = tmp_path / "ui", tmp_path / "cli"
    for fmt in ("STL", "3MF"):
        assert bpy.ops.anatomesh.export(directory=str(ui_dir), format=fmt, collection=coll.name) == {"FINISHED"}
    res = _cli(addon, labels, cli_dir, formats=["stl", "3mf"])
    stls = sorted(p.name for p in ui_dir.glob("*.stl"))
    assert stls == sorted(p.name for p in cli_dir.glob("*.stl")) and len(stls) == labels
    worst = max(_read_worst(read_back(ui_dir / n, "stl")[""], read_back(cli_dir / n, "stl")[""]) for n in stls)
    (ui_3mf,) = ui_dir.glob("*.3mf")
    a, b = read_back(ui_3mf, "3mf"), read_back(res.plan.scene["3mf"], "3mf")
    assert sorted(a) == sorted(b) and len(a) == labels
    worst_3mf = max(_read_worst(a[n], b[n]) for n in a)
    print(f"\nexport {labels}: {len(stls)} STL worst {worst:.2e} mm, 3MF worst {worst_3mf:.2e} mm")
    assert max(worst, worst_3mf) <= TOL_MM


# ---------------------------------------------------------------------------------------------
# 6. a recipe saved in Blender, run by the command line
# ---------------------------------------------------------------------------------------------
def test_saved_recipe_reproduces_blender_byte_for_byte(addon, empty_scene, tmp_path):
    """Byte for byte: the recipe holds the panels' float32 values exactly (λ 0.44999998807907104,
    ratio 0.4000000059604645), both doors smooth and decimate the same float32 set with the same
    functions, and Export writes the objects through the command line's STL writer (header:
    name, space, unit). The smoothing that made the decimated shape is the recipe's, although
    Apply set the scan's own smoothing back to none."""
    coll = _scan(empty_scene, 41)
    coll.anatomesh.smooth_method = "LIGHT"  # the Smooth panel's fields: each re-smooths live
    coll.anatomesh.smooth_iterations = 12
    coll.anatomesh.smooth_strength = 0.45
    d = empty_scene.anatomesh_decimate  # the Decimate panel, then its Apply button
    d.target, d.ratio = "RATIO", 0.4
    assert bpy.ops.anatomesh.decimate_apply(collection=coll.name, target="RATIO", ratio=0.4) == {"FINISHED"}
    empty_scene.anatomesh.export_dir = str(tmp_path / "cli")
    recipe = tmp_path / "recipe.toml"
    assert bpy.ops.anatomesh.recipe_save(filepath=str(recipe)) == {"FINISHED"}
    r = _mod(addon, "app.flow.recipe").load_recipe(recipe)
    assert (r.smooth, r.iterations, r.decimate) == ("light", 12, pytest.approx(0.4))
    assert bpy.ops.anatomesh.export(directory=str(tmp_path / "ui"), format="STL",
                                    collection=coll.name) == {"FINISHED"}
    done = subprocess.run([sys.executable, "-m", "anatomesh.app.cli", "mesh", "--recipe", str(recipe)],
                          capture_output=True, text=True, cwd=str(tmp_path), timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    ui = sorted((tmp_path / "ui").glob("*.stl"))
    assert [p.name for p in ui] == sorted(p.name for p in (tmp_path / "cli").glob("*.stl")) and len(ui) == 41
    differ = [p.name for p in ui if p.read_bytes() != (tmp_path / "cli" / p.name).read_bytes()]
    print(f"\nrecipe: {len(ui)} STL files, {len(differ)} differ from Blender's: {differ[:5]}")
    assert not differ


# ---------------------------------------------------------------------------------------------
# 1b. preprocessing a scalar scan (specks dropped where they are made, in both doors)
# ---------------------------------------------------------------------------------------------
def test_preprocess_scalar_scan_equals_run(addon, empty_scene, tmp_path):
    """The CT of the 41-label map resampled to 2 mm, Gaussian-smoothed (1 mm), the 250 HU
    isosurface (the Import panel's level list holds only it)."""
    ct = str(shared("totalsegmentator", "example_ct_sm.nii.gz"))
    assert bpy.ops.anatomesh.import_scan(filepath=ct, extract=False) == {"FINISHED"}
    empty_scene.anatomesh.levels.clear()
    assert bpy.ops.anatomesh.level_add(value=250.0) == {"FINISHED"}
    p = empty_scene.anatomesh_preprocess
    p.resample, p.smooth_volume, p.smooth_value = 2.0, "GAUSSIAN", 1.0
    assert bpy.ops.anatomesh.preprocess_extract() == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    steps = json.loads(coll["anatomesh_preprocess"])["steps"]
    assert [s["step"] for s in steps] == ["resample", "smooth_volume"]
    assert max(s["effect"]["max_mm"] for s in steps) > 0
    Recipe = _mod(addon, "app.flow.recipe").Recipe
    res = _mod(addon, "app.flow.run").run(Recipe(input=ct, out_dir=str(tmp_path), levels=[250.0],
                                                 level_names=["level 250"],  # the panel's row
                                                 resample=[2.0], smooth_volume="gaussian:1"))
    assert _worst(_shown(addon, coll), res.surfaces, "preprocess CT") <= TOL_MM
