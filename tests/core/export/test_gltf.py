"""GLB: real organs and an analytic sphere round trip exactly; the file follows the glTF 2.0 spec."""
import json
import struct

import numpy as np
import pytest
from conftest import SAMPLE

from anatomesh.core import AnatomeshError, Mesh, label_surfaces, load
from anatomesh.core.model.labels import srgb_to_linear
from anatomesh.core.export import SCENE_FORMATS
from anatomesh.core.export.gltf import AXES, ROTATION, UNITS, read_glb, write_glb
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.model.mesh import vertex_normals
from helpers.meshes import icosphere, tiled_spheres

ORGANS = ("kidney_left", "gallbladder", "pancreas")


@pytest.fixture(scope="module")
def organs():
    shells = label_surfaces(load(SAMPLE / "example_seg.nii.gz")).shells()
    return [m for m in shells if m.name in ORGANS]


def _doc(path):
    raw = path.read_bytes()
    magic, version, total = struct.unpack_from("<4sII", raw)
    n, kind = struct.unpack_from("<I4s", raw, 12)
    assert (magic, version, total, kind) == (b"glTF", 2, len(raw), b"JSON")
    assert n % 4 == 0 and (20 + n) % 4 == 0
    nb, kind_b = struct.unpack_from("<I4s", raw, 20 + n)
    assert kind_b == b"BIN\0" and 28 + n + nb == len(raw)
    return json.loads(raw[20:20 + n]), raw[28 + n:]


def test_organs_round_trip_exactly(organs, tmp_path):
    assert SCENE_FORMATS["glb"] is write_glb
    p = write_glb(organs, tmp_path / "organs.glb", title="three organs")
    back = read_glb(p)
    assert [m.name for m in back] == [m.name for m in organs] and len(back) == 3
    for a, b in zip(organs, back):
        np.testing.assert_array_equal(b.vertices, a.vertices)
        np.testing.assert_array_equal(b.faces, a.faces)
        np.testing.assert_allclose(b.color, a.color, atol=1e-6)
        assert b.value == a.value and b.space == a.space == "RAS"
        # no normals on the shells: area-weighted vertex normals were written
        np.testing.assert_allclose(b.normals, vertex_normals(a.vertices, a.faces), atol=1e-6)
    assert not list(tmp_path.glob("*.part"))


def test_document_structure(organs, tmp_path):
    p = write_glb(organs, tmp_path / "o.glb", title="T")
    doc, binary = _doc(p)
    assert doc["asset"]["version"] == "2.0"
    assert doc["asset"]["extras"] == {"space": "RAS", "units": UNITS, "title": "T"}
    root = doc["nodes"][doc["scenes"][0]["nodes"][0]]
    assert root["scale"] == [0.001] * 3 and root["rotation"] == ROTATION["RAS"]
    assert [doc["nodes"][c]["name"] for c in root["children"]] == list(ORGANS)
    assert doc["buffers"] == [{"byteLength": len(binary)}]
    for k, m in enumerate(organs):
        prim = doc["meshes"][k]["primitives"][0]
        pos = doc["accessors"][prim["attributes"]["POSITION"]]
        assert pos["min"] == m.vertices.min(0).tolist() and pos["max"] == m.vertices.max(0).tolist()
        assert doc["accessors"][prim["indices"]]["componentType"] == 5123  # uint16: < 65536 vertices
        mat = doc["materials"][prim["material"]]
        np.testing.assert_allclose(mat["pbrMetallicRoughness"]["baseColorFactor"],
                                   list(srgb_to_linear(m.color)) + [1.0])
        assert "alphaMode" not in mat
    for view in doc["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["byteOffset"] + view["byteLength"] <= len(binary)


@pytest.mark.parametrize("space", ["RAS", "LPS"])
def test_root_rotation_turns_patient_space_upright(space):
    """The quaternion is the documented axis table: superior → +Y, anterior → +Z."""
    x, y, z, w = ROTATION[space]
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    np.testing.assert_allclose(R, AXES[space], atol=1e-12)
    anterior = {"RAS": [0, 1, 0], "LPS": [0, -1, 0]}[space]
    left = {"RAS": [-1, 0, 0], "LPS": [1, 0, 0]}[space]
    np.testing.assert_allclose(R @ [0, 0, 1], [0, 1, 0], atol=1e-12)  # superior is up
    np.testing.assert_allclose(R @ anterior, [0, 0, 1], atol=1e-12)  # faces +Z (glTF front)
    np.testing.assert_allclose(R @ left, [1, 0, 0], atol=1e-12)


def test_sphere_volume_normals_uint32_and_alpha(tmp_path):
    v, f = icosphere(7, 40.0)  # 163 842 vertices: uint32 indices
    m = Mesh(v - [30.0, 80.0, -500.0], f, normals=v * 3.0, name="ball", value=2.5,
             color=(0.2, 0.4, 0.6, 0.5), space="LPS")
    p = write_glb([m], tmp_path / "ball.glb")
    doc, _ = _doc(p)
    assert doc["accessors"][doc["meshes"][0]["primitives"][0]["indices"]]["componentType"] == 5125
    assert doc["materials"][0]["alphaMode"] == "BLEND"
    (b,) = read_glb(p)
    vol = signed_volume(b.vertices, b.faces)
    assert vol == signed_volume(m.vertices, m.faces)
    assert abs(vol / (4 / 3 * np.pi * 40.0 ** 3) - 1) < 1e-3
    np.testing.assert_allclose(b.normals, v / 40.0, atol=1e-6)  # given normals, made unit length
    np.testing.assert_allclose(b.color, m.color, atol=1e-6)
    assert b.space == "LPS" and b.value == 2.5


def test_million_triangle_file(tmp_path):
    """A million triangles in one GLB, read back whole (the write time is in benchmarks/bench_export.py)."""
    vv, ff = tiled_spheres()
    m = Mesh(vv, ff, name="big")
    p = write_glb([m], tmp_path / "big.glb")
    assert p.stat().st_size > m.n_faces * 12 + m.n_vertices * 24
    assert read_glb(p)[0].n_faces == m.n_faces == 1_064_960


@pytest.mark.parametrize("bad, what", [([], "no surfaces"), ("nan", "NaN"), ("space", "space"),
                                       ("index", "outside")])
def test_bad_inputs(bad, what, tmp_path):
    v, f = icosphere(1, 5.0)
    if bad == "nan":
        v = v.copy()
        v[0, 2] = np.inf
        bad = [Mesh(v, f, name="broken")]
    elif bad == "space":  # one file, one space
        bad = [Mesh(v, f, name="a", space="RAS"), Mesh(v, f, name="b", space="LPS")]
    elif bad == "index":
        f = f.copy()
        f[5, 2] = len(v)
        bad = [Mesh(v, f, name="broken")]
    with pytest.raises(AnatomeshError, match=what):
        write_glb(bad, tmp_path / "bad.glb")
    assert not list(tmp_path.iterdir())


def test_not_a_glb(tmp_path):
    p = tmp_path / "x.glb"
    p.write_bytes(b"glTF\x01\x00\x00\x00" + b"\0" * 16)
    with pytest.raises(AnatomeshError, match="GLB 2.0"):
        read_glb(p)


def test_vertex_colors_round_trip_linear_in_the_file(tmp_path):
    v, f = icosphere(2, 5.0)
    rgb = np.stack([np.linspace(0, 1, len(v)), np.full(len(v), 0.5), np.zeros(len(v))], 1)
    p = write_glb([Mesh(v, f, name="painted", color=(0.2, 0.3, 0.4), vertex_colors=rgb)], tmp_path / "c.glb")
    doc = json.loads(p.read_bytes()[20:20 + struct.unpack_from("<I", p.read_bytes(), 12)[0]])
    prim = doc["meshes"][0]["primitives"][0]
    assert "COLOR_0" in prim["attributes"]
    # the vertex colours carry the colour: the material's base colour is white, not the label's
    assert doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"][:3] == [1.0, 1.0, 1.0]
    back = read_glb(p)[0]
    np.testing.assert_allclose(back.vertex_colors, rgb, atol=1e-5)
    assert read_glb(write_glb([Mesh(v, f)], tmp_path / "plain.glb"))[0].vertex_colors is None
