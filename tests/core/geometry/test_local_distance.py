"""Local distances between two positions of one mesh, against exact nearest-triangle distances."""
import numpy as np
import pytest

from anatomesh.core.geometry.local_distance import (distances_by_group, edge_neighbours,
                                                    local_distances)
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
    with pytest.raises(AnatomeshError, match="positions"):
        local_distances(out[:5], v, s)


def _by_group_from_samples(after, rest, s, groups, n_groups):
    """The per-group reduction of :func:`local_distances`' samples, in numpy."""
    worst, total, count = np.zeros(n_groups), np.zeros(n_groups), np.zeros(n_groups, np.int64)
    row = np.repeat(np.arange(s.n_vertices), np.diff(s.vf_offsets))
    for a, b in ((after, rest), (rest, after)):
        at_vertices, at_centroids = local_distances(a, b, s, edge_neighbours(s))
        for k in range(n_groups):
            mine = (groups[s.vf] == k).any(axis=1)
            per_vertex = np.full(s.n_vertices, np.inf)
            np.minimum.at(per_vertex, row[mine], at_vertices[mine])
            samples = np.r_[per_vertex[np.isfinite(per_vertex)],
                            at_centroids[(groups == k).any(axis=1)]]
            worst[k] = max(worst[k], samples.max(initial=0.0))
            total[k] += samples.sum()
            count[k] += samples.size
    return worst, total, count


def test_distances_by_group_equal_the_samples_reduced_per_group():
    """A randomly moved torus in three groups (a different one or −1 on each side of a face, as
    labels in a surface set): the one-pass reduction gives the worst, sum and count of the
    stored samples of each group."""
    rng = np.random.default_rng(3)
    v, f = torus()
    s = MeshStructure(f, len(v))
    after = v + rng.normal(scale=0.05, size=v.shape)
    groups = np.c_[np.where(v[f[:, 0], 2] > 0, 0, 1), rng.integers(-1, 3, len(f))].astype(np.int32)
    groups[groups[:, 0] == groups[:, 1], 1] = -1
    got = distances_by_group(after, v, s, groups, 3)
    want = _by_group_from_samples(after, v, s, groups, 3)
    np.testing.assert_allclose(got[0], want[0], rtol=1e-12)
    np.testing.assert_allclose(got[1], want[1], rtol=1e-9)
    np.testing.assert_array_equal(got[2], want[2])
    assert got[2].min() > len(f) // 3  # every group has samples
    with pytest.raises(AnatomeshError, match="groups"):
        distances_by_group(after, v, s, groups, 2)
