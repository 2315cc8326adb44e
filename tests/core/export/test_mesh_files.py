"""Exporters write what they say: space and units in headers, exact geometry round trip."""
import numpy as np

from anatomesh.core.export.mesh_files import write_mesh
from anatomesh.core.io.mesh_files import read_mesh, read_stl
from anatomesh.core.model.mesh import Mesh
from helpers.meshes import icosphere


def _mesh(space="LPS"):
    v, f = icosphere(2, 25.0)
    return Mesh(v + [100.0, -50.0, 20.0], f, normals=v / 25.0, name="liver", value=5, space=space)


def test_stl_round_trip_and_header(tmp_path):
    m = _mesh()
    p = write_mesh(m, tmp_path / "liver.stl")
    data = read_stl(p)
    assert b"SPACE=LPS" in data["header"] and b"UNITS=mm" in data["header"]
    np.testing.assert_array_equal(data["triangles"], m.vertices[m.faces])
    assert not list(tmp_path.glob("*.part"))


def test_ply_binary_round_trip(tmp_path):
    m = _mesh("RAS")
    m.color = (0.6, 0.3, 0.2)
    p = write_mesh(m, tmp_path / "liver.ply")
    raw = p.read_bytes()
    head, body = raw.split(b"end_header\n", 1)
    assert b"comment SPACE=RAS" in head and b"element face %d" % m.n_faces in head
    vertex = np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("c", "u1", 3)])  # the colour on every vertex
    vert = np.frombuffer(body[: m.n_vertices * vertex.itemsize], vertex)
    np.testing.assert_array_equal(vert["p"], m.vertices)
    assert (vert["c"] == [153, 76, 51]).all()
    faces = np.frombuffer(body[m.n_vertices * vertex.itemsize:], dtype=[("n", "u1"), ("i", "<i4", 3)])
    assert (faces["n"] == 3).all()
    np.testing.assert_array_equal(faces["i"], m.faces)


def test_obj_text(tmp_path):
    m = _mesh()
    p = write_mesh(m, tmp_path / "x.obj")
    lines = p.read_text().splitlines()
    assert lines[0] == "# anatomesh SPACE=LPS UNITS=mm"
    assert sum(1 for ln in lines if ln.startswith("v ")) == m.n_vertices
    assert sum(1 for ln in lines if ln.startswith("f ")) == m.n_faces


def test_ply_vertex_colors_as_bytes(tmp_path):
    v, f = icosphere(1, 5.0)
    rgb = np.tile([[1.0, 0.5, 0.0]], (len(v), 1))
    p = write_mesh(Mesh(v, f, vertex_colors=rgb), tmp_path / "c.ply")
    data = p.read_bytes()
    head = data[:data.index(b"end_header")].decode()
    assert "property uchar red" in head and "property uchar blue" in head
    body = data[data.index(b"end_header") + 11:]
    rec = np.frombuffer(body[:len(v) * 15], dtype=[("p", "<f4", 3), ("c", "u1", 3)])
    np.testing.assert_allclose(rec["p"], v, atol=1e-5)
    assert np.all(rec["c"] == [255, 128, 0])
    assert read_mesh(p).n_faces == len(f)  # our reader skips the colour properties
