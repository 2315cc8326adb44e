"""Fuzzy isosurfaces nest and fade toward the ends; precise extraction follows the trilinear
interpolant (closer to an analytic surface it reproduces) and keeps the surface closed; the edge
list Blender's mesh format wants."""
import numpy as np
import pytest

from anatomesh.core import load
from anatomesh.core.export.gltf import read_glb, write_glb
from anatomesh.core.extract import _precise_kernels
from anatomesh.core.extract.edges import unique_edges
from anatomesh.core.extract.fuzzy import fuzzy_isosurfaces, fuzzy_levels
from anatomesh.core.extract.isosurface import isosurface
from anatomesh.core.extract.precise import refine
from anatomesh.core.geometry.measure import sample_points
from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.geometry.topology import edge_face_counts, topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.model.volume import Volume
from conftest import shared
from helpers.fields import grid


@pytest.fixture(scope="module")
def blob():
    """A smooth bright blob (a Gaussian, 1000 at the centre) on anisotropic voxels."""
    (x, y, z), affine = grid((40, 36, 20), (1.0, 1.2, 2.0))
    return Volume((1000.0 * np.exp(-(x**2 + y**2 + (z / 1.3) ** 2) / (2 * 9.0**2))).astype(np.float32), affine)


def test_fuzzy_levels_and_alphas():
    levels, alphas = fuzzy_levels(200, 400, 5)
    np.testing.assert_allclose(levels, [200, 250, 300, 350, 400])
    np.testing.assert_allclose(alphas, [1 / 3, 2 / 3, 1, 2 / 3, 1 / 3])
    _, even = fuzzy_levels(-1, 1, 4)
    np.testing.assert_allclose(even, [0.5, 1, 1, 0.5])
    for bad in ((1, 1, 5), (0, 1, 1), (0, 1, 2.5)):
        with pytest.raises(AnatomeshError):
            fuzzy_levels(*bad)


def test_fuzzy_shells_nest_and_write_their_opacity(blob, tmp_path):
    shells = fuzzy_isosurfaces(blob, 300, 700, 5, cap=True)
    assert [m.value for m in shells] == [300, 400, 500, 600, 700]
    assert [m.color[3] for m in shells] == pytest.approx([0.3333, 0.6667, 1.0, 0.6667, 0.3333], abs=1e-4)
    volumes = [signed_volume(m.vertices, m.faces) for m in shells]
    assert all(a > b > 0 for a, b in zip(volumes[:-1], volumes[1:]))
    for outer, inner in zip(shells[:-1], shells[1:]):  # every inner vertex inside the outer shell
        assert TriangleGrid(outer.vertices, outer.faces).contains(inner.vertices.astype(float)).all()
        t = topology(inner.vertices, inner.faces)
        assert t.closed and t.genus == 0
    path = write_glb(shells, tmp_path / "fuzzy.glb")
    back = read_glb(path)
    assert [round(m.color[3], 3) if len(m.color) == 4 else 1.0 for m in back] == [0.333, 0.667, 1.0, 0.667, 0.333]


def test_precise_is_closer_to_the_analytic_surface():
    """A field the trilinear interpolant reproduces exactly (degree one in each coordinate): its
    level set x*y*z + ... = c is curved, the flat marching-cubes triangles cut across it, the
    refined surface follows it (first-order distance |f - c| / |grad f| of the samples)."""
    (x, y, z), affine = grid((14, 14, 14), (1.0, 1.0, 1.0))
    f = lambda x, y, z: x * y * z / 27 + 0.3 * x * y / 3 + 0.2 * z  # noqa: E731
    vol = Volume(f(x, y, z).astype(np.float64), affine)
    linear = isosurface(vol, 0.1)
    fine, info = refine(linear, vol, tolerance=0.001)  # split wherever a triangle strays

    def error(m):
        p = sample_points(m.vertices, m.faces)
        h = 1e-4
        g = np.stack([(f(*(p + h * e).T) - f(*(p - h * e).T)) / (2 * h) for e in np.eye(3)], 1)
        return np.mean(np.abs(f(*p.T) - 0.1) / np.linalg.norm(g, axis=1))

    assert error(fine) < error(linear) / 1.4, (error(linear), error(fine))  # measured 1.55x
    default, info_default = refine(linear, vol)  # tolerance 0.02 voxel: fewer splits, less gain
    assert error(fine) < error(default) < error(linear)
    assert info_default["split_faces"] < info["split_faces"]
    assert info["split_faces"] > 0 and info["faces_after"] == info["faces_before"] + 2 * info["split_faces"]
    assert 0 < info["mean_moved_mm"] <= info["max_moved_mm"] <= 1.0
    # new vertices lie on the interpolant: f at them equals the level
    new = fine.vertices[linear.n_vertices:].astype(np.float64)
    np.testing.assert_allclose(f(*new.T), 0.1, atol=1e-3)
    # boundary edges stay as they were (the surface is open at the grid's border), no new holes
    _, count, _ = edge_face_counts(fine.faces, fine.n_vertices)
    _, count0, _ = edge_face_counts(linear.faces, linear.n_vertices)
    assert (count == 1).sum() == (count0 == 1).sum() and (count > 2).sum() == 0


def test_precise_keeps_a_real_ct_surface_closed():
    vol = load(str(shared("slicer_ctheadaxial")))
    m = isosurface(vol, 1150.0, cap=True)
    fine, info = refine(m, vol)
    t0, t1 = topology(m.vertices, m.faces), topology(fine.vertices, fine.faces)
    assert t1.closed and t1.manifold and t1.oriented and t1.genus == t0.genus
    assert info["split_faces"] > 1000 and info["max_moved_mm"] <= max(vol.spacing)
    assert fine.normals is not None and len(fine.normals) == fine.n_vertices
    assert abs(signed_volume(fine.vertices, fine.faces) / signed_volume(m.vertices, m.faces) - 1) < 0.05


def test_trilinear_kernel_value_and_gradient():
    data = np.arange(8, dtype=np.float64).reshape(2, 2, 2)  # 4 i + 2 j + k
    g = np.empty(3)
    assert _precise_kernels.trilinear(data, np.array([0.25, 0.5, 0.75]), g) == pytest.approx(2.75)
    np.testing.assert_allclose(g, [4, 2, 1])


def test_unique_edges_of_a_closed_surface(blob):
    m = isosurface(blob, 500.0, cap=True)
    edges, corner_edge = unique_edges(m.faces, m.n_vertices)
    ref, count, _ = edge_face_counts(m.faces, m.n_vertices)
    assert len(edges) == len(ref) and (count == 2).all()
    np.testing.assert_array_equal(np.sort(edges, axis=0)[:, 0], np.sort(ref[:, 0]))
    corners = np.stack([m.faces, np.roll(m.faces, -1, axis=1)], 2).reshape(-1, 2)
    np.testing.assert_array_equal(np.sort(edges[corner_edge], axis=1), np.sort(corners, axis=1))
