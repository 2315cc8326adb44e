"""app.run.run: extract → smooth → decimate → write → check → report, on the real sample.

Expected values come from the data (the SurfaceSet's own interface faces, the undecimated run's
face counts, the files read back), not from the code under test.
"""
import json
import sys

import numpy as np
import pytest

from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.io.mesh_files import read_stl
from anatomesh.core.export.threemf import read_3mf
from anatomesh.core.export.gltf import read_glb
from anatomesh.app.flow.run import run
from anatomesh.app.flow.recipe import Recipe
from anatomesh.app.flow.recipe import load_recipe
from helpers.readback import pinch_volume_bound
from conftest import SAMPLE

SEG = str(SAMPLE / "example_seg.nii.gz")
CT = str(SAMPLE / "example_ct_sm.nii.gz")
LIVER, GALLBLADDER, SPLEEN = 5, 4, 1
TRIO = ["liver", "gallbladder", "spleen"]  # liver and gallbladder share an interface


@pytest.fixture(scope="module")
def smoothed(tmp_path_factory):
    """The trio smoothed, not decimated (the reference for faces_before)."""
    out = tmp_path_factory.mktemp("smoothed")
    return run(Recipe(input=SEG, out_dir=str(out), labels=TRIO))


@pytest.fixture(scope="module")
def decimated(tmp_path_factory):
    out = tmp_path_factory.mktemp("decimated")
    return run(Recipe(input=SEG, out_dir=str(out), labels=TRIO, decimate=0.4,
                      formats=["stl", "3mf", "glb"]))


def _tri_keys(tri: np.ndarray) -> set:
    """Unordered triangles (3 vertex positions each) as hashable keys."""
    t = np.sort(np.round(tri.reshape(-1, 3, 3), 5).view([("", "f4")] * 3).reshape(-1, 3), axis=1)
    return {row.tobytes() for row in t}


def test_decimation_report_per_surface(smoothed, decimated):
    before = {s["name"]: s for s in smoothed.report["surfaces"]}
    rep = decimated.report
    assert rep["decimation"]["target"] == {"ratio": 0.4, "max_error_mm": 3.0,  # one 3 mm voxel
                                           "max_error_mm_source": "default cap: one voxel"}
    assert rep["decimation"]["target_met"] is True
    for s in rep["surfaces"]:
        assert s["faces_before"] == before[s["name"]]["faces"]        # counted on the smoothed shell
        assert s["faces"] < 0.7 * s["faces_before"]  # the ratio is for the whole set, not each label
        assert s["closed"] and s["manifold"] and s["oriented"]
        assert s["genus"] == before[s["name"]]["genus"] and s["components"] == before[s["name"]]["components"]
        assert 0 < s["decimation_mean_error_mm"] < s["decimation_max_error_mm"] < 1.5  # half a 3 mm voxel
        assert abs(s["decimation_volume_change_pct"]) < 1.0
        vol0 = before[s["name"]]["volume_mm3"]
        assert s["volume_mm3"] == pytest.approx(vol0 * (1 + s["decimation_volume_change_pct"] / 100), rel=1e-3)
    dec = rep["decimation"]
    assert dec["faces_after"] <= 0.4 * dec["faces_before"] + 1 < sum(s["faces"] for s in smoothed.report["surfaces"])
    assert dec["hausdorff_mm"] == pytest.approx(
        max(s["decimation_max_error_mm"] for s in rep["surfaces"]), abs=1e-3)
    assert "decimate_s" in rep["timings"]
    assert smoothed.report["decimation"] is None and "faces_before" not in smoothed.report["surfaces"][0]


def test_result_carries_the_surface_set_and_seams_stay_shared(decimated):
    sset = decimated.surface_set
    assert sset is not None and sorted(sset.values()) == [SPLEEN, GALLBLADDER, LIVER]
    # the liver/gallbladder interface: faces of the set with both labels on their sides
    pair = np.sort(sset.face_labels, axis=1)
    interface = sset.vertices[sset.faces[(pair[:, 0] == GALLBLADDER) & (pair[:, 1] == LIVER)]]
    assert len(interface) > 50
    out = decimated.report_path.parent
    names = {s["value"]: s["files"]["stl"] for s in decimated.report["surfaces"]}
    liver = _tri_keys(read_stl(out / names[LIVER])["triangles"])
    gall = _tri_keys(read_stl(out / names[GALLBLADDER])["triangles"])
    # the written files share exactly the interface triangles: bit-identical seams, no cracks
    assert liver & gall == _tri_keys(interface)


def test_scene_files_3mf_combined_and_glb(decimated):
    out = decimated.report_path.parent
    rep = decimated.report
    assert rep["files"]["3mf"] == "example_seg.3mf" and rep["files"]["glb"] == "example_seg.glb"
    assert rep["files"]["recipe"] == "recipe.toml" and rep["files"]["report"] == "report.json"
    by_name = {m.name: m for m in decimated.surfaces}
    for path in (out / "example_seg.3mf", out / "example_seg.glb"):
        parts = read_3mf(path) if path.suffix == ".3mf" else read_glb(path)
        assert sorted(p.name for p in parts) == sorted(by_name)
        for p in parts:
            m = by_name[p.name]
            assert p.n_faces == m.n_faces
            np.testing.assert_allclose(p.vertices.min(0), m.vertices.min(0), atol=1e-3)
            np.testing.assert_allclose(p.color, m.color, atol=1 / 255)
    for s in rep["surfaces"]:  # one 3MF per part too
        (single,) = read_3mf(out / s["files"]["3mf"])
        assert single.name == s["name"] and single.n_faces == s["faces"]
        assert topology(single.vertices, single.faces).closed


def test_recipe_beside_the_report_reruns_the_same(decimated, tmp_path):
    saved = load_recipe(decimated.report_path.parent / "recipe.toml")
    assert saved.decimate == 0.4 and saved.labels == TRIO and saved.overwrite is False
    assert saved.out_dir == str(decimated.report_path.parent)
    saved.out_dir, saved.formats = str(tmp_path), ["stl"]
    again = run(saved)
    assert [(s["name"], s["faces"]) for s in again.report["surfaces"]] == \
        [(s["name"], s["faces"]) for s in decimated.report["surfaces"]]


def test_max_error_target_is_honoured(tmp_path):
    res = run(Recipe(input=SEG, out_dir=str(tmp_path), labels=["gallbladder", "spleen"], max_error=0.3))
    dec = res.report["decimation"]
    assert dec["target"] == {"max_error_mm": 0.3} and dec["error_bound_met"] is True
    for s in res.report["surfaces"]:
        assert 0 < s["decimation_max_error_mm"] <= 0.3 + 1e-6
        assert s["faces"] < s["faces_before"]


def test_isosurfaces_decimated_each_with_a_shared_face_budget(tmp_path):
    res = run(Recipe(input=CT, out_dir=str(tmp_path), levels=[-500, 300], keep_largest=True,
                     target_faces=20000))
    assert res.surface_set.lattice is None and len(res.surfaces) == 2  # one set, a label per level
    rep = res.report
    # 20000 faces under the default cap of one voxel (3 mm): the cost estimate alone lets the
    # skin's thin tips slide 4.3 mm; the stricter runs pin them, and the target is met within it
    dec = rep["decimation"]
    assert dec["target"]["max_error_mm"] == 3.0 and dec["target_met"] and dec["error_bound_met"]
    assert dec["faces_after"] <= 20000 and 0 < dec["hausdorff_mm"] <= 3.0
    assert not any("short of its target" in w for w in rep["warnings"])
    for s in rep["surfaces"]:
        assert s["closed"] and s["manifold"] and s["faces_before"] > s["faces"]
        assert s["decimation_max_error_mm"] > 0


def test_print_check_section(tmp_path):
    res = run(Recipe(input=SEG, out_dir=str(tmp_path), labels=["spleen"], check=True, profile="resin"))
    pc = res.report["print_check"]
    assert pc["profile"]["min_wall"] == 0.4 and pc["profile"]["min_gap"] == 0.2
    assert [p["name"] for p in pc["parts"]] == ["spleen"] and pc["passed"] is True
    assert json.loads(res.report_path.read_text())["print_check"]["passed"] is True
    assert "check_s" in res.report["timings"]


def test_overwrite_refusal_covers_every_output(decimated):
    out = decimated.report_path.parent
    stamp = {p: p.stat().st_mtime_ns for p in out.iterdir()}
    for formats in (["glb"], ["3mf"], ["ply"]):  # only the combined/scene files, report and recipe exist
        with pytest.raises(AnatomeshError, match="--overwrite"):
            run(Recipe(input=SEG, out_dir=str(out), labels=["spleen"], formats=formats))
    assert {p: p.stat().st_mtime_ns for p in out.iterdir()} == stamp  # nothing touched


@pytest.mark.parametrize("changes, words", [
    (dict(decimate=0.5, target_faces=100), ["--decimate", "--target-faces", "not both"]),
    (dict(decimate=1.5), ["--decimate", "(0, 1]"]),
    (dict(target_faces=0), ["--target-faces"]),
    (dict(max_error=-1.0), ["--max-error", "> 0"]),
    (dict(min_wall=0.0), ["--min-wall"]),
    (dict(formats=["stl", "fbx"]), ["fbx", "3mf", "glb", "blend"]),
    (dict(profile="sls"), ["profile", "fdm", "resin"]),
    (dict(smooth="organn"), ["smoothing method", "'organn'", "organ"]),
    (dict(iterations=-5), ["iterations", ">= 0", "-5"]),
    (dict(lam=1.5), ["lam", "1.5"]),
    (dict(smooth="taubin", lam=0.5, mu=-0.2), ["mu", "-lam"]),
])
def test_bad_settings_fail_before_reading(tmp_path, monkeypatch, changes, words):
    def never(*args, **kwargs):
        raise AssertionError("the input was read")

    monkeypatch.setattr("anatomesh.core.io.load", never)
    out = tmp_path / "never"
    with pytest.raises(AnatomeshError) as err:
        run(Recipe(input=SEG, out_dir=str(out), **changes))
    for w in words:
        assert w in str(err.value)
    assert not out.exists()


def test_existing_results_are_refused_before_reading(decimated, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("the input was read")

    monkeypatch.setattr("anatomesh.core.io.load", never)
    with pytest.raises(AnatomeshError, match="--overwrite"):
        run(Recipe(input=SEG, out_dir=str(decimated.report_path.parent), labels=["spleen"]))


def test_the_callers_recipe_is_not_changed(tmp_path):
    import copy

    asked = Recipe(input=SEG, out_dir=str(tmp_path / "o"), labels=["spleen"], formats=[" STL", ".ply"],
                   margins=[2, 5])
    before = copy.deepcopy(asked)
    res = run(asked)
    assert asked == before
    assert res.recipe.formats == ["stl", "ply"] and res.recipe.margins == [2.0, 5.0] and (tmp_path / "o" / "spleen.ply").exists()
    assert load_recipe(tmp_path / "o" / "recipe.toml").formats == ["stl", "ply"]


def test_blend_without_blender_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "anatomesh.addon", None)  # as if bpy were not installed
    with pytest.raises(AnatomeshError, match="bpy"):
        run(Recipe(input=SEG, out_dir=str(tmp_path / "o"), formats=["stl", "blend"]))
    assert not (tmp_path / "o").exists()


def test_levels_of_detail_written_as_glb_files(tmp_path):
    """--lod 3: three GLBs from one progressive run, lod0 = the written surfaces, each level about
    half the faces of the one before, every shell closed, the error in mm reported per level."""
    from anatomesh.core.export.gltf import read_glb
    from anatomesh.core.geometry.topology import topology

    res = run(Recipe(input=SEG, out_dir=str(tmp_path), labels=["liver", "gallbladder", "spleen"],
                     formats=["stl"], lod=3))
    lods = res.report["lod"]
    assert [d["file"] for d in lods] == [f"example_seg_lod{i}.glb" for i in range(3)]
    faces = [d["faces"] for d in lods]
    assert faces[0] == sum(s["faces"] for s in res.report["surfaces"])
    assert faces[0] > faces[1] > faces[2] and faces[1] <= 0.55 * faces[0]
    assert lods[0]["hausdorff_mm"] == 0.0 < lods[1]["hausdorff_mm"] <= lods[2]["hausdorff_mm"]
    for d in lods:
        meshes = read_glb(tmp_path / d["file"])
        assert sorted(m.name for m in meshes) == ["gallbladder", "liver", "spleen"]
        assert sum(m.n_faces for m in meshes) == d["faces"]
        for m in meshes:
            t = topology(m.vertices, m.faces)
            assert t.closed and t.manifold and t.oriented


def test_print_fixes_fuse_thicken_and_clearance(tmp_path):
    """--fuse makes one closed solid of the chosen organs (raw: exactly their voxel volume);
    --clearance pulls touching organs apart so they share no vertex and the checks see the gap;
    --thicken grows thin parts in the label map; each fix is reported."""
    from anatomesh.core import load
    from anatomesh.core.printing.checks import check_parts

    vol = load(SEG)
    voxel = float(abs(np.linalg.det(vol.affine[:3, :3])))
    liver, gall = (v for v, info in vol.labels.items() if info.name in ("liver", "gallbladder"))
    n_vox = int(np.isin(vol.data, [liver, gall]).sum())

    res = run(Recipe(input=SEG, out_dir=str(tmp_path / "fused"), labels=["liver", "gallbladder", "spleen"],
                     smooth="none", fuse=[["liver", "gallbladder"]]))
    by_name = {s["name"]: s for s in res.report["surfaces"]}
    assert sorted(by_name) == ["liver+gallbladder", "spleen"]
    fused = by_name["liver+gallbladder"]
    assert fused["closed"] and fused["manifold"]
    assert abs(fused["volume_mm3"] - n_vox * voxel) <= pinch_volume_bound(fused["pinch_points"], n_vox * voxel, voxel)
    assert res.report["fixes"][0]["fix"] == "fuse" and res.report["fixes"][0]["voxels"] == n_vox

    res = run(Recipe(input=SEG, out_dir=str(tmp_path / "apart"), labels=["liver", "gallbladder"],
                     clearance=0.4))
    (fix,) = res.report["fixes"]
    assert fix["fix"] == "clearance" and fix["pairs"] == [sorted([liver, gall])]
    a, b = res.surfaces
    assert not set(map(tuple, a.vertices)) & set(map(tuple, b.vertices))
    rep = check_parts(res.surfaces, "resin")
    (gap,) = [g for g in rep["gaps"] if {g["a"], g["b"]} == {"liver", "gallbladder"}]
    # the full clearance across the interface; at its rim, where both organs' outer surfaces
    # run on almost tangentially after smoothing, the gap narrows (measured 0.128 mm here)
    assert not gap["touching"] and gap["min_gap_mm"] >= 0.25 * 0.4
    assert all(p["part_intersections"] == 0 and p["closed"] for p in rep["parts"])

    res = run(Recipe(input=SEG, out_dir=str(tmp_path / "thick"), smooth="none", thicken=True,
                     min_wall=7.0, labels=["rib_left_9", "liver"]))  # 3 mm voxels: a wall of 2+ voxels
    (fix,) = res.report["fixes"]
    assert fix["fix"] == "thicken" and fix["min_wall_mm"] == 7.0 and fix["labels"]
    grown = {int(k) for k in fix["labels"]}
    for s in res.report["surfaces"]:
        n0 = int((vol.data == s["value"]).sum())
        assert (s["volume_mm3"] > n0 * voxel + 1e-6) == (s["value"] in grown)


def test_print_fixes_need_a_label_map(tmp_path):
    with pytest.raises(AnatomeshError, match="label maps"):
        run(Recipe(input=CT, out_dir=str(tmp_path), levels=[300], thicken=True))


def test_one_shot_runs_let_go_of_the_voxels_before_smoothing(tmp_path):
    """``keep_voxels=False`` (the command line): the chest CT's 74 MB of voxels are gone while
    the bone is smoothed (tracemalloc's peak drops by about that much), and the files and the
    report are those of a run that keeps them; with a preprocessing step they stay."""
    import tracemalloc
    from conftest import shared

    runs = {}
    for keep in (True, False):
        out = tmp_path / f"keep_{keep}"
        tracemalloc.start()
        res = run(Recipe(input=str(shared("itkelastix_chest_ct")), out_dir=str(out), levels=[300.0]),
                  keep_voxels=keep)
        runs[keep] = (res, tracemalloc.get_traced_memory()[1], out)
        tracemalloc.stop()
    (kept, peak_kept, out_kept), (released, peak_released, out_released) = runs[True], runs[False]
    voxels = 512 * 512 * 141 * 2
    assert kept.volume.data.nbytes == voxels and released.volume.data.strides == (0, 0, 0)
    assert released.volume.shape == kept.volume.shape  # the geometry still answers
    assert peak_kept - peak_released > 0.8 * voxels, (peak_kept, peak_released)
    for name in [p.name for p in out_kept.glob("*.stl")]:
        assert (out_kept / name).read_bytes() == (out_released / name).read_bytes()
    drop = ("timings", "recipe")
    same = [{k: v for k, v in r.report.items() if k not in drop} for r in (kept, released)]
    for rep in same:
        rep["smoothing"].pop("seconds")
    assert same[0] == same[1]
    res = run(Recipe(input=SEG, out_dir=str(tmp_path / "pre"), labels=TRIO, fill_cavities=True),
              keep_voxels=False)
    assert res.volume.data.strides != (0, 0, 0)  # the preprocessing's measures read them later


def test_specks_are_dropped_where_they_are_made_and_counted():
    """A ball (radius 6 voxels) and one voxel barely above the level: the voxel's blob (far under
    0.1 voxel) is dropped right after extraction, the ball kept whole; a label map's shells come
    back as they are."""
    from anatomesh.app.flow import stages
    from anatomesh.core.model.volume import Volume

    z, y, x = np.mgrid[:24, :24, :24]
    data = np.where((x - 12) ** 2 + (y - 12) ** 2 + (z - 12) ** 2 <= 36, 1.0, 0.0).astype(np.float32)
    data[2, 2, 2] = 0.51
    raw = stages.extract(Volume(data, np.diag([2.0, 2.0, 2.0, 1.0])), Recipe(input="x", levels=[0.5]))
    clean = stages.drop_specks(raw)
    assert raw.n_faces - clean.n_faces == 8  # the blob: 8 triangles around one corner
    (ball,) = clean.shells()
    assert topology(ball.vertices, ball.faces).components == 1
    assert any("1 speck(s)" in w for w in clean.warnings)
    from anatomesh.core.model.labels import LabelInfo

    label_map = Volume((data == 1).astype(np.uint8), np.eye(4), labels={1: LabelInfo(1, "ball", (1, 0, 0))})
    labels = stages.extract(label_map, Recipe(input="x"))
    assert stages.drop_specks(labels) is labels
