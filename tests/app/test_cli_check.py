"""`anatomesh check`: mesh files and `anatomesh mesh` folders → print report, exit codes, fixes;
the mesh-file readers it uses (STL binary/ASCII, PLY, OBJ) and their un-welding of voxel shells."""
import json

import numpy as np
import pytest
from helpers.meshes import box

from anatomesh.app.cli import main as cli_main
from anatomesh.core.export.threemf import write_3mf
from anatomesh.core.export.mesh_files import write_obj, write_ply, write_stl
from anatomesh.core.io.mesh_files import read_mesh, split_nonmanifold
from anatomesh.core.model.mesh import Mesh
from anatomesh.core.geometry.topology import topology

REQUIRED_PART_KEYS = {"name", "closed", "manifold", "self_intersections", "min_wall_mm",
                      "thin_area_mm2", "passed"}


def run(capsys, *argv):
    code = cli_main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def write_box(path, lo, hi, n=6, name=None):
    v, f = box(lo, hi, n)
    write_stl(Mesh(v, f, name=name or path.stem), path)
    return path


def test_two_blocks_at_a_known_gap_fuse_for_fdm_not_below_the_override(capsys, tmp_path):
    a = write_box(tmp_path / "a.stl", (0, 0, 0), (6, 6, 6))
    b = write_box(tmp_path / "b.stl", (6.3, 0, 0), (12, 6, 6))
    c = write_box(tmp_path / "far.stl", (30, 0, 0), (36, 6, 6))  # 18 mm away: not listed
    rep_path = tmp_path / "r" / "check.json"
    code, out, _ = run(capsys, "check", a, b, c, "--report", rep_path)
    assert code == 1
    rep = json.loads(rep_path.read_text())
    assert rep["profile"]["min_gap"] == 0.5 and rep["profile"]["min_wall"] == 0.8
    assert [p["name"] for p in rep["parts"]] == ["a", "b", "far"]
    for p in rep["parts"]:
        assert REQUIRED_PART_KEYS <= set(p)
        assert p["closed"] and p["manifold"] and p["self_intersections"] == 0 and p["passed"]
        assert p["min_wall_mm"] == pytest.approx(6.0, abs=0.15) or p["min_wall_mm"] >= 5.0
    assert len(rep["gaps"]) == 1
    g = rep["gaps"][0]
    assert {g["a"], g["b"]} == {"a", "b"}
    assert g["min_gap_mm"] == pytest.approx(0.3, abs=0.01) and g["fuses"]
    assert 6.0 <= g["location"][0] <= 6.3
    assert rep["passed"] is False
    assert "fuses" in out and "FAILED" in out
    code, out, _ = run(capsys, "check", a, b, c, "--min-gap", "0.2")
    assert code == 0 and "PASSED" in out


def test_thin_plate_fails_fdm_passes_resin(capsys, tmp_path):
    p = write_box(tmp_path / "plate.stl", (0, 0, 0), (12, 10, 0.5), n=8)
    rep_path = tmp_path / "fdm.json"
    code, out, _ = run(capsys, "check", p, "--profile", "fdm", "--report", rep_path)
    assert code == 1
    part = json.loads(rep_path.read_text())["parts"][0]
    assert part["min_wall_mm"] == pytest.approx(0.5, abs=0.15)
    assert part["thin_area_mm2"] > 100  # both 12 x 10 faces at least
    assert "thin" in out
    code, out, _ = run(capsys, "check", p, "--profile", "resin")
    assert code == 0
    code, _, _ = run(capsys, "check", p, "--profile", "resin", "--min-wall", "0.6")
    assert code == 1


def test_folder_from_anatomesh_mesh_uses_its_names_and_reads_back_closed(capsys, tmp_path):
    from conftest import SAMPLE

    out_dir = tmp_path / "m"
    # default (smoothed) output: where a label touches itself along an edge its two sheets may
    # cross slightly after smoothing, which the STL round trip must still undo
    code, _, _ = run(capsys, "mesh", SAMPLE / "example_seg.nii.gz", "--labels", "2,3,5,30,31",
                     "--out", out_dir)
    assert code == 0
    mesh_rep = json.loads((out_dir / "report.json").read_text())
    rep_path = tmp_path / "check.json"
    code, out, _ = run(capsys, "check", out_dir, "--report", rep_path)
    assert code in (0, 1)
    rep = json.loads(rep_path.read_text())
    assert [p["name"] for p in rep["parts"]] == [s["name"] for s in mesh_rep["surfaces"]]
    for p, s in zip(rep["parts"], mesh_rep["surfaces"]):
        # the STL round trip (corners welded by position, voxel pinches split again) keeps the
        # topology the pipeline reported
        assert (p["closed"], p["manifold"], p["genus"]) == (s["closed"], s["manifold"], s["genus"])
        assert p["closed"] and p["manifold"]
    names = {s["name"] for s in mesh_rep["surfaces"]}
    for g in rep["gaps"]:
        assert {g["a"], g["b"]} <= names and g["min_gap_mm"] < 5.0
    assert ("PASSED" if code == 0 else "FAILED") in out


@pytest.mark.parametrize("argv, words", [
    (["check", "{tmp}/missing.stl"], "no such file"),
    (["check", "{tmp}/notes.txt"], "not a mesh file"),
    (["check", "{tmp}/broken.stl"], "not an STL file"),
    (["check", "{tmp}/empty_dir"], "no report.json"),
    (["check", "{tmp}/ok.stl", "--min-wall", "-1"], "min_wall"),
    (["check", "{tmp}/ok.stl", "--close-holes", "10"], "--out"),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, argv, words):
    (tmp_path / "notes.txt").write_text("hello")
    (tmp_path / "broken.stl").write_bytes(b"\x00" * 200)
    (tmp_path / "empty_dir").mkdir()
    write_box(tmp_path / "ok.stl", (0, 0, 0), (5, 5, 5))
    code, out, err = run(capsys, *[a.format(tmp=tmp_path) for a in argv])
    assert code == 2
    assert err.count("\n") == 1 and words in err and "Traceback" not in err


def test_fixes_remove_tiny_shells_and_close_holes_then_pass(capsys, tmp_path):
    v, f = box((0, 0, 0), (8, 8, 8), 4)
    # a hole: drop the two triangles of one quad on the top face (the first top face and the one
    # sharing an edge with it; two faces sharing only a corner would leave a bowtie, two pieces of
    # surface touching at a point, which the check rightly reports as a pinch)
    top = np.flatnonzero(np.all(v[f][:, :, 2] == 8, axis=1))
    mate = next(t for t in top[1:] if len(set(f[t]) & set(f[top[0]])) == 2)
    f = np.delete(f, [top[0], mate], axis=0)
    tv, tf = box((20, 0, 0), (20.5, 0.5, 0.5), 1)  # 0.125 mm³ crumb
    mesh = Mesh(np.concatenate([v, tv]), np.concatenate([f, tf + len(v)]), name="cube")
    src = tmp_path / "cube.stl"
    write_stl(mesh, src)
    code, _, _ = run(capsys, "check", src)
    assert code == 1
    rep_path = tmp_path / "fixed.json"
    code, out, _ = run(capsys, "check", src, "--remove-tiny", "1", "--close-holes", "8",
                       "--out", tmp_path / "fixed", "--report", rep_path)
    assert code == 0, out
    assert "removed 1 tiny shell(s)" in out and "closed 1 hole(s)" in out
    fixed = read_mesh(tmp_path / "fixed" / "cube.stl")
    t = topology(fixed.vertices, fixed.faces)
    assert t.closed and t.manifold and t.oriented and t.components == 1
    rep = json.loads(rep_path.read_text())
    assert rep["fixes"][0]["name"] == "cube" and rep["passed"]
    from anatomesh.core.export.threemf import read_3mf  # the print-ready file holds the fixed part
    (part,) = read_3mf(tmp_path / "fixed" / "parts.3mf")
    assert part.name == "cube" and len(part.faces) == len(fixed.faces)
    code, _, err = run(capsys, "check", src, "--remove-tiny", "1", "--out", tmp_path / "fixed")
    assert code == 2 and "--overwrite" in err


# ---------------------------------------------------------------------------------------------
# readers
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("fmt", ["stl", "ply", "obj"])
def test_readers_round_trip_a_closed_box(tmp_path, fmt):
    v, f = box((-3, 1, 100), (4, 2.5, 103), 3)
    m = Mesh(v, f, name="b", space="LPS")
    path = tmp_path / f"b.{fmt}"
    {"stl": write_stl, "ply": write_ply, "obj": write_obj}[fmt](m, path)
    r = read_mesh(path)
    assert r.space == "LPS" and r.name == "b" and r.n_faces == m.n_faces and r.n_vertices == m.n_vertices
    # same triangles (as sets of corner positions)
    key = lambda vv, ff: sorted(map(tuple, np.round(np.sort(vv[ff].reshape(len(ff), -1), axis=1), 4)))
    assert key(r.vertices, r.faces) == key(m.vertices, m.faces)
    t = topology(r.vertices, r.faces)
    assert t.closed and t.manifold and t.oriented and t.genus == 0


def test_ascii_stl_and_ascii_ply_quads(tmp_path):
    stl = tmp_path / "t.stl"
    tri = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    stl.write_text("solid t\nfacet normal 0 0 1\nouter loop\n" +
                   "".join(f"vertex {x} {y} {z}\n" for x, y, z in tri) + "endloop\nendfacet\nendsolid t\n")
    r = read_mesh(stl)
    assert r.n_faces == 1 and np.allclose(r.vertices[r.faces[0]], tri)
    ply = tmp_path / "q.ply"
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                   "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                   "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    r = read_mesh(ply)
    assert r.faces.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_split_nonmanifold_separates_cubes_touching_along_an_edge_and_at_a_corner():
    v1, f1 = box((0, 0, 0), (1, 1, 1), 1)
    v2, f2 = box((1, 1, 0), (2, 2, 1), 1)  # shares the edge x=y=1
    v3, f3 = box((2, 2, 1), (3, 3, 2), 1)  # touches cube 2 at the corner (2, 2, 1)
    pts = np.concatenate([v1[f1], v2[f2], v3[f3]]).reshape(-1, 3)
    u, inv = np.unique(pts, axis=0, return_inverse=True)
    welded = inv.ravel().reshape(-1, 3)
    t0 = topology(u, welded)
    assert not t0.manifold
    v, f = split_nonmanifold(u, welded)
    t = topology(v, f)
    assert t.closed and t.manifold and t.oriented and t.components == 3 and t.genus == 0
    assert len(v) == 24  # 8 corners per cube, none shared
    assert np.allclose(v[f], u[welded])  # same triangles, same winding


def test_3mf_parts_are_checked_together(capsys, tmp_path):
    a, b = box((0, 0, 0), (6, 6, 6), 4), box((0, 0, 6.2), (6, 6, 12), 4)
    path = tmp_path / "pair.3mf"
    write_3mf([Mesh(*a, name="lower"), Mesh(*b, name="upper")], path)
    rep_path = tmp_path / "r.json"
    code, _, _ = run(capsys, "check", path, "--report", rep_path)
    rep = json.loads(rep_path.read_text())
    assert code == 1 and [p["name"] for p in rep["parts"]] == ["lower", "upper"]
    assert all(p["closed"] and p["passed"] for p in rep["parts"])
    assert rep["gaps"][0]["min_gap_mm"] == pytest.approx(0.2, abs=0.01) and rep["gaps"][0]["fuses"]


def test_separate_fix_opens_the_seams_of_touching_labels(capsys, tmp_path):
    from anatomesh.core.extract.multilabel import label_surfaces

    lab = np.zeros((14, 8, 8), np.uint8)
    lab[2:7, 2:6, 2:6] = 1
    lab[7:12, 2:6, 2:6] = 2  # touches label 1 over a 4 x 4 voxel face
    a = np.diag([0.9, 0.9, 0.9, 1.0])
    for m in label_surfaces(lab, affine=a).shells():
        write_stl(m, tmp_path / f"{m.name}.stl")
    rep_path = tmp_path / "r.json"
    code, _, _ = run(capsys, "check", tmp_path / "label_1.stl", tmp_path / "label_2.stl", "--report", rep_path)
    g = json.loads(rep_path.read_text())["gaps"][0]
    assert g["touching"] and g["seam_area_mm2"] == pytest.approx(16 * 0.81, rel=1e-4)
    code, out, _ = run(capsys, "check", tmp_path / "label_1.stl", tmp_path / "label_2.stl",
                       "--separate", "0.6", "--out", tmp_path / "apart", "--report", rep_path)
    assert code == 0, out
    assert "pulled 0.6 mm away from label_2" in out
    rep = json.loads(rep_path.read_text())
    g = rep["gaps"][0]
    assert not g["touching"] and g["min_gap_mm"] == pytest.approx(0.6, abs=0.01) and not g["fuses"]
    assert all(p["closed"] and p["manifold"] and p["passed"] for p in rep["parts"])


def test_split_nonmanifold_keeps_sheets_apart_where_they_cross_near_the_edge():
    v1, f1 = box((0, 0, 0), (1, 1, 1), 2)
    v2, f2 = box((1, 1, 0), (2, 2, 1), 2)  # shares the edge x=y=1 (subdivided at z=0.5)
    # push box 1's face-centre vertex next to the edge into box 2: its faces at the edge now
    # cross box 2's, so the faces no longer alternate around the edge
    k = np.flatnonzero(np.all(np.isclose(v1, [1.0, 0.5, 0.5]), axis=1))[0]
    v1 = v1.copy()
    v1[k] = [1.4, 1.2, 0.5]
    pts = np.concatenate([v1[f1], v2[f2]]).reshape(-1, 3)
    u, inv = np.unique(pts, axis=0, return_inverse=True)
    v, f = split_nonmanifold(u, inv.ravel().reshape(-1, 3))
    t = topology(v, f)
    assert t.closed and t.manifold and t.components == 2
    assert len(v) == len(v1) + len(v2)  # each box keeps its own copy of the edge's vertices
    assert np.allclose(v[f[:len(f1)]], v1[f1])
