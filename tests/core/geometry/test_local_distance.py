"""Local distances between two positions of one mesh, against exact nearest-triangle distances."""
import numpy as np
import pytest

from anatomesh.core.geometry.local_distance import edge_neighbours, local_distances
from anatomesh.core.geometry.measure import TriangleGrid
from anatomesh.core.geometry.neighbors import MeshStructure
from anatomesh.core.model.errors import AnatomeshError
from helpers.meshes import icosphere, torus


def test_edge_neighbours_are_the_faces_across_each_edge():
    v, f = torus(nu=12, nv=8)
    near = edge_neighbours(MeshStructure(f, len(v)))
    for face, row in enumerate(near):
        for k, g in enumerate(row):
            a, b = f[face, k], f[face, (k + 1) % 3]
            assert g != face and {a, b} <= set(f[g])
    open_f = f[:-4]  # four faces less: edges of the hole have no neighbour
    assert (edge_neighbours(MeshStructure(open_f, len(v))) == -1).sum() > 0


def test_a_scaled_sphere_is_at_its_radial_offset_everywhere():
    """Every vertex of a sphere moved outwards by 1 % of its radius: each sample's local
    distance equals the exact distance to the other sphere (the nearest point lies on the faces
    around it) and is bounded by the displacement."""
    v, f = icosphere(3, radius=10.0)
    s = MeshStructure(f, len(v))
    out = v * 1.01
    at_vertices, at_centroids = local_distances(out, v, s, edge_neighbours(s))
    per_vertex = np.minimum.reduceat(at_vertices, s.vf_offsets[:-1])
    exact = TriangleGrid(v, f).distance(out)
    np.testing.assert_allclose(per_vertex, exact, atol=1e-9)
    assert np.all(per_vertex <= 0.1 + 1e-9) and per_vertex.min() > 0.09
    centroids = out[f].mean(axis=1)
    np.testing.assert_allclose(at_centroids, TriangleGrid(v, f).distance(centroids), atol=1e-9)
    lean = local_distances(out, v, s, edge_neighbours(s), np.float32)  # the same, rounded
    np.testing.assert_array_equal(lean[0], at_vertices.astype(np.float32))
    np.testing.assert_array_equal(lean[1], at_centroids.astype(np.float32))
    with pytest.raises(AnatomeshError, match="positions"):
        local_distances(out[:5], v, s)
