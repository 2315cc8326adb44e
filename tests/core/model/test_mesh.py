"""Mesh invariants on analytic shapes with known area, volume and genus."""
import numpy as np

from anatomesh.core.geometry import topology as T
from anatomesh.core.model import mesh as M
from helpers.meshes import icosphere, torus


def test_icosphere_is_closed_genus0_and_measures_converge():
    v, f = icosphere(4, radius=10.0)
    t = T.topology(v, f)
    assert t.closed and t.manifold and t.oriented
    assert t.euler == 2 and t.genus == 0 and t.components == 1
    assert abs(M.signed_volume(v, f) / (4 / 3 * np.pi * 1000) - 1) < 0.01
    assert abs(M.surface_area(v, f) / (4 * np.pi * 100) - 1) < 0.01


def test_torus_genus1_and_flipped_face_detected():
    v, f = torus()
    t = T.topology(v, f)
    assert t.closed and t.manifold and t.oriented and t.genus == 1 and t.euler == 0
    f2 = f.copy()
    f2[5] = f2[5, ::-1]
    assert not T.topology(v, f2).oriented


def test_open_mesh_and_pinch_vertex_and_nonmanifold_edge():
    v, f = icosphere(1)
    t = T.topology(v, f[1:])
    assert not t.closed and t.boundary_edges == 3 and t.genus is None
    # two tetrahedra sharing one vertex: closed edges, but a pinch vertex
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    pv = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float)
    tet2 = np.array([[0, 5, 4], [0, 4, 6], [4, 5, 6], [0, 6, 5]])
    t = T.topology(pv, np.vstack([tet, tet2]))
    assert t.nonmanifold_vertices == 1 and t.nonmanifold_edges == 0 and not t.manifold
    assert list(T.nonmanifold_vertices(np.vstack([tet, tet2]), 7)) == [0]
    # three triangles on one edge
    t = T.topology(np.eye(3).tolist() + [[1, 1, 1], [0, 0, 0]], [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert t.nonmanifold_edges == 1


def test_components_and_measures_sorted_by_volume():
    v1, f1 = icosphere(2, 2.0)
    v2, f2 = icosphere(2, 1.0)
    v = np.vstack([v1, v2 + 10])
    f = np.vstack([f1, f2 + len(v1)])
    n, lab = T.face_components(f, len(v))
    assert n == 2 and set(lab[: len(f1)]) == {0} and set(lab[len(f1):]) == {1}
    comps = T.component_measures(v, f)
    assert comps[0]["volume_mm3"] > 7 * comps[1]["volume_mm3"] > 0
    assert T.topology(v, f).genus == 0  # two spheres: chi = 4, C = 2


def test_degenerate_and_duplicates():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [1, 1, 3]])
    assert list(M.degenerate_faces(v, f)) == [0, 2]
    assert list(M.duplicate_vertices(v)) == [4]


def cone_fan(k, apex=0, first=1):
    """Faces of a closed cone: apex ``apex`` over a k-gon rim ``first .. first+k-1`` with a
    centre ``first + k`` under it."""
    rim = first + np.arange(k)
    nxt = first + (np.arange(k) + 1) % k
    base = first + k
    return np.r_[np.c_[np.full(k, apex), rim, nxt], np.c_[np.full(k, base), nxt, rim]]


def test_pinch_found_among_many_faces_and_every_fan_counted():
    """Two closed cones touching at the apex, 40 faces each side (past the small-list sort):
    the apex is the one pinch; one cone alone has none; 3 cones give 3 fans."""
    one = cone_fan(40)
    assert T.nonmanifold_vertices(one, 42).size == 0 and T.topology(np.random.rand(42, 3), one).manifold
    two = np.r_[one, cone_fan(40, first=42)]
    assert list(T.nonmanifold_vertices(two, 83)) == [0]
    from anatomesh.core.geometry._neighbors_kernels import fan_counts, vertex_faces

    three = np.r_[two, cone_fan(5, first=83)]
    offsets, vf = vertex_faces(three, np.int64(89))
    fans = fan_counts(three, offsets, vf)
    assert fans[0] == 3 and np.all(fans[1:] == 1)
    # a pinch in the middle of a real surface: glue two vertices of a sphere's far sides
    v, f = icosphere(3)
    far = int(np.argmax(v[:, 0])), int(np.argmin(v[:, 0]))
    glued = np.where(f == far[1], far[0], f)
    assert list(T.nonmanifold_vertices(glued, len(v))) == [far[0]]
