"""The linear-time topology (core/geometry/topology.py) against a sorted half-edge reference,
on real shells and on damaged copies of them."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import shared

from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.topology import area_and_volume, face_components, topology, topology_and_size
from anatomesh.core.io import load
from anatomesh.core.model.mesh import signed_volume, surface_area


def _reference(vertices, faces):
    """Edges, boundary/non-manifold/unoriented edges and V from np.unique on half-edges."""
    f = np.asarray(faces, np.int64)
    a, b = f.ravel(), np.roll(f, -1, axis=1).ravel()
    key = np.minimum(a, b) * len(vertices) + np.maximum(a, b)
    uk, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    balance = np.bincount(inv.ravel(), weights=np.where(a < b, 1, -1), minlength=uk.size)
    return {"edges": uk.size, "boundary_edges": int(np.sum(count == 1)),
            "nonmanifold_edges": int(np.sum(count > 2)),
            "oriented": bool(np.all(balance[count == 2] == 0)), "vertices": np.unique(f).size}


@pytest.fixture(scope="module")
def shells():
    vol = load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz"))
    return label_surfaces(vol).shells()


def test_real_shells_and_damaged_copies_match_the_sorted_reference(shells):
    rng = np.random.default_rng(7)
    checked = 0
    for m in shells[::4]:
        f = m.faces[rng.random(m.n_faces) > 0.02]  # holes
        f[:4] = f[:4, ::-1]                         # flipped faces
        f = np.vstack([f, f[5:8]])                  # a third face on some edges
        for faces in (m.faces, f):
            t = topology(m.vertices, faces)
            ref = _reference(m.vertices, faces)
            assert {k: getattr(t, k) for k in ref} == ref
            n, lab = face_components(faces, m.n_vertices)
            assert t.components == n == np.unique(lab).size
            checked += 1
        assert topology(m.vertices, m.faces).closed and topology(m.vertices, m.faces).genus is not None
    assert checked == 2 * len(shells[::4])


def test_components_numbered_by_smallest_vertex_and_shared_vertices_join():
    tri = np.array([[5, 6, 7], [0, 1, 2], [2, 3, 4], [8, 9, 10]])
    n, lab = face_components(tri, 11)
    assert n == 3 and lab.tolist() == [1, 0, 0, 2]  # faces 1 and 2 share vertex 2


def test_area_and_volume_equal_the_numpy_measures(shells):
    for m in shells[:10]:
        area, volume = area_and_volume(m.vertices, m.faces)
        assert area == pytest.approx(surface_area(m.vertices, m.faces), rel=1e-9)
        assert volume == pytest.approx(signed_volume(m.vertices, m.faces), rel=1e-9)
        assert volume > 0


def test_topology_and_size_in_one_pass_equal_the_two_functions(shells):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    repeated = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2], [1, 1, 2]])  # sorted path
    for vertices, faces in [(m.vertices, m.faces) for m in shells[:6]] + [(v, repeated)]:
        t, area, volume = topology_and_size(vertices, faces)
        assert t == topology(vertices, faces)
        assert (area, volume) == area_and_volume(vertices, faces)
    assert topology_and_size(v, np.zeros((0, 3), int))[1:] == (0.0, 0.0)


def test_faces_repeating_a_vertex_take_the_sorted_path():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2], [1, 1, 2]])
    t = topology(v, f)
    assert t.degenerate_faces == 1 and t.nonmanifold_edges == 1 and not t.closed
