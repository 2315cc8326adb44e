"""MeshStructure: the 1-ring built on first use, and the vertices on open or non-manifold edges
without any ring."""
import numpy as np

from anatomesh.core import label_surfaces, load
from anatomesh.core.geometry.neighbors import MeshStructure
from helpers.meshes import torus


def test_open_vertices_are_the_feature_rings_kinds_without_groups():
    """A closed torus has none; with four faces cut out, exactly the hole's rim; a fin glued
    to one edge (three faces on it) marks that edge's ends and the fin's open rim; on a real
    label map's set (junctions are 3-face edges) the same vertices as feature_ring(None)."""
    v, f = torus(nu=12, nv=8)
    assert not MeshStructure(f, len(v)).open_vertices().any()
    holed = MeshStructure(f[4:], len(v))
    np.testing.assert_array_equal(np.flatnonzero(holed.open_vertices()),
                                  np.flatnonzero(holed.feature_ring(None)[2] != 0))
    assert 0 < holed.open_vertices().sum() <= 12
    a, b = f[0, 0], f[0, 1]
    fin = np.vstack([f, [[a, b, len(v)]]])
    s = MeshStructure(fin, len(v) + 1)
    np.testing.assert_array_equal(np.flatnonzero(s.open_vertices()), sorted([a, b, len(v)]))
    sset = label_surfaces(load("data/sample/example_seg.nii.gz"))
    s = MeshStructure(sset.faces, sset.n_vertices)
    got = s.open_vertices()
    np.testing.assert_array_equal(got, s.feature_ring(None)[2] != 0)
    assert got.sum() > 100


def test_the_one_ring_is_built_on_first_use_and_again_after_release():
    v, f = torus(nu=12, nv=8)
    s = MeshStructure(f, len(v))
    assert s._ring is None
    offsets, ring = s.ring_offsets.copy(), s.ring.copy()
    assert (np.diff(offsets) == 6).all()  # a regular torus: valence 6 everywhere
    s.release_ring()
    assert s._ring is None
    np.testing.assert_array_equal(s.ring, ring)
    np.testing.assert_array_equal(s.ring_offsets, offsets)
