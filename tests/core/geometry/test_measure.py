"""Measurement: exact distances against brute force, curvature on analytic shapes, volumes, angles."""
import numpy as np
import pytest

from anatomesh.core.geometry import measure as M
from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.model.errors import AnatomeshError
from helpers.meshes import icosphere, torus

RNG = np.random.default_rng(3)


def brute_point_triangle(p, a, b, c):
    """Nearest-point distance by minimising over a fine barycentric grid plus the three edges
    solved exactly (reference independent of the Voronoi-region code)."""
    best = np.inf
    # interior: project onto the plane, accept if inside
    n = np.cross(b - a, c - a)
    nn = n @ n
    if nn > 0:
        q = p - ((p - a) @ n) / nn * n
        v0, v1, v2 = b - a, c - a, q - a
        d00, d01, d11, d20, d21 = v0 @ v0, v0 @ v1, v1 @ v1, v2 @ v0, v2 @ v1
        den = d00 * d11 - d01 * d01
        s = (d11 * d20 - d01 * d21) / den
        t = (d00 * d21 - d01 * d20) / den
        if s >= 0 and t >= 0 and s + t <= 1:
            best = np.linalg.norm(p - q)
    for u, w in ((a, b), (b, c), (c, a)):
        e = w - u
        t = np.clip((p - u) @ e / (e @ e), 0, 1) if e @ e > 0 else 0.0
        best = min(best, np.linalg.norm(p - (u + t * e)))
    return best


def test_point_to_surface_matches_brute_force():
    v, f = icosphere(1, radius=5.0)
    v = v + RNG.normal(scale=0.3, size=v.shape)
    pts = RNG.uniform(-8, 8, (120, 3))
    pts = np.concatenate([pts, v[:20] + 1e-3, v[f[:20]].mean(1)])  # near and on the surface
    got = M.point_to_surface(pts, v, f)
    ref = np.array([min(brute_point_triangle(p, *v[t]) for t in f) for p in pts])
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_distance_grid_is_exact_for_far_points_and_degenerate_triangles():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3]])  # the first is degenerate (a segment)
    g = TriangleGrid(v, f, cell_size=0.25)
    d = g.distance(np.array([[2.0, 0, 30.0], [3.0, 0, 0], [0.2, 0.2, -1.0]]))
    np.testing.assert_allclose(d, [30.0, 1.0, 1.0], atol=1e-12)


def test_surface_distance_of_offset_planes_is_the_offset():
    x, y = np.meshgrid(np.arange(11.0), np.arange(11.0), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(121)], 1)
    i = np.arange(10)[:, None] * 11 + np.arange(10)[None]
    q = np.stack([i, i + 11, i + 12, i + 1], -1).reshape(-1, 4)
    f = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    d = M.surface_distance(v, f, v + [0, 0, 0.3], f)
    assert d["hausdorff_mm"] == pytest.approx(0.3) and d["mean_mm"] == pytest.approx(0.3)
    w = v.copy()
    w[60, 2] = 2.0  # one spike in the middle
    d = M.surface_distance(w, f, v, f)
    assert d["hausdorff_mm"] == pytest.approx(2.0)
    assert d["b_to_a_max_mm"] < 2.0 and 0 < d["mean_mm"] < 0.1


def test_curvature_of_a_sphere():
    R = 7.0
    v, f = icosphere(4, radius=R)
    H, K, A = M.vertex_curvatures(v, f)
    assert A.sum() == pytest.approx(4 * np.pi * R ** 2, rel=5e-3)
    np.testing.assert_allclose(H, 1 / R, rtol=0.02)
    np.testing.assert_allclose(K, 1 / R ** 2, rtol=0.05)
    # Gauss-Bonnet holds exactly for the angle deficit: Σ K A = 2π χ
    assert (K * A).sum() == pytest.approx(4 * np.pi, abs=1e-9)
    # inward-facing faces flip the sign of the mean curvature only
    H2, K2, _ = M.vertex_curvatures(v, f[:, ::-1])
    np.testing.assert_allclose(H2, -H, atol=1e-12)
    np.testing.assert_allclose(K2, K, atol=1e-12)


def test_curvature_of_a_torus():
    R, r = 3.0, 1.0
    v, f = torus(R, r, nu=120, nv=60)
    H, K, A = M.vertex_curvatures(v, f)
    assert (K * A).sum() == pytest.approx(0.0, abs=1e-9)  # genus 1: χ = 0
    rho = np.hypot(v[:, 0], v[:, 1])
    cosw = (rho - R) / r
    k_true = cosw / (r * (R + r * cosw))
    h_true = (R + 2 * r * cosw) / (2 * r * (R + r * cosw))
    sign = np.sign(np.median(H / h_true))  # the helper's orientation
    np.testing.assert_allclose(sign * H, h_true, atol=0.01)
    np.testing.assert_allclose(K, k_true, atol=0.01)


def test_triangle_angles_and_quality():
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3]])
    ang = M.triangle_angles(v, f)
    np.testing.assert_allclose(ang[0], 60.0)
    np.testing.assert_allclose(ang[1], [90.0, 45.0, 45.0])
    q = M.triangle_quality(v, f)
    assert q["min_angle_deg"] == pytest.approx(45.0) and q["fraction_below_10deg"] == 0


def test_volume_change_and_flips():
    v, f = icosphere(3, radius=4.0)
    assert M.volume_change(v, 1.1 * v, f) == pytest.approx(100 * (1.1 ** 3 - 1))
    w = v.copy()
    w[0] *= -1  # push a vertex through the centre: its fan flips
    assert M.flipped_faces(v, w, f) >= 5
    assert M.flipped_faces(v, 2 * v, f) == 0


def test_compare_reports_one_shell():
    v, f = icosphere(3, radius=10.0)
    noisy = v + RNG.normal(scale=0.1, size=v.shape)
    r = M.compare(noisy, v, f)
    assert r["max_displacement_mm"] == pytest.approx(np.linalg.norm(noisy - v, axis=1).max())
    assert 0 < r["mean_distance_mm"] < r["hausdorff_mm"] <= r["max_displacement_mm"] + 1e-9
    assert r["curvature_after"]["mean_abs_H"] < r["curvature_before"]["mean_abs_H"]
    assert r["topology_before"]["genus"] == 0 and r["topology_changed"] == []
    assert r["volume_after_mm3"] == pytest.approx(r["volume_before_mm3"] * (1 + r["volume_change_pct"] / 100))
    with pytest.raises(AnatomeshError, match="same vertices"):
        M.compare(v, v[:-1], f[:10])
    with pytest.raises(AnatomeshError, match="faces"):
        M.compare(v, v, f[:, :2])
