"""Distance colouring: exact distances on analytic shapes and brute force on the real liver,
margin colours, target lookup, bad margins."""
import numpy as np
import pytest

from anatomesh.core.geometry.margins import (MARGIN_COLORS, check_margins, color_by_distance,
                                             find_target, margin_colors, surface_distances)
from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.io import load
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh
from helpers.meshes import box, icosphere
from conftest import SAMPLE

RED, YELLOW, GREEN = (np.asarray(c, np.float32) for c in MARGIN_COLORS)


def _slab():
    """A closed slab whose top face is the plane z = 0 over [-50, 50]²."""
    v, f = box((-50, -50, -4), (50, 50, 0), n=4)
    return Mesh(v, f, name="tumour", value=9, color=(0.1, 0.9, 0.2))


def test_heights_above_a_plane_get_their_band():
    probe = icosphere(1, 0.5)
    heights = [1.0, 3.5, 7.0, 20.0]  # within 2, 5, 10 mm, then beyond
    meshes = [_slab()] + [Mesh(probe[0] + [0, 0, h + 0.5], probe[1], name=f"p{h}", value=i,
                               color=(0.2, 0.3, 0.8)) for i, h in enumerate(heights)]
    _, summary = color_by_distance(meshes, "tumour", (2, 5, 10))
    assert meshes[0].vertex_colors is None  # the target keeps its own colour
    lowest = [m.vertices[:, 2].argmin() for m in meshes[1:]]  # the vertex nearest the plane
    got = [m.vertex_colors[k] for m, k in zip(meshes[1:], lowest)]
    assert np.allclose(got[0], RED) and np.allclose(got[1], YELLOW) and np.allclose(got[2], GREEN)
    assert np.allclose(got[3], (0.2, 0.3, 0.8))  # beyond 10 mm: the structure's own colour
    for h in heights[:3]:  # the bottom vertex sits exactly h above the plane: exact distance
        assert summary["shells"][f"p{h}"]["min_distance_mm"] == pytest.approx(h, abs=1e-5)
    assert summary["shells"]["p20.0"]["min_distance_mm"] is None
    assert summary["shells"]["p1.0"]["within_mm"]["2"] > 0 and summary["target"] == "tumour"


def test_inside_the_target_is_zero_distance():
    v, f = icosphere(3, 20.0)
    grid = TriangleGrid(v, f)
    pts = np.array([[0.0, 0, 0], [15.0, 0, 0], [0, 0, 19.0], [23.0, 0, 0], [45.0, 0, 0]])
    d = surface_distances(pts, grid, 10.0)
    assert d[:3].tolist() == [0.0, 0.0, 0.0]  # deep inside (20 mm from the surface) too
    assert d[3] == pytest.approx(3.0, abs=0.05) and d[4] == np.inf


def test_margin_colors_picks_the_first_margin_that_holds():
    d = np.array([0.0, 2.0, 2.01, 5.0, 9.99, 10.01, np.inf])
    c = margin_colors(d, (2, 5, 10), (0.5, 0.5, 0.5, 0.4))
    assert c.dtype == np.float32 and c.shape == (7, 3)
    want = [RED, RED, YELLOW, YELLOW, GREEN, (0.5,) * 3, (0.5,) * 3]
    assert np.allclose(c, want)
    one = margin_colors(d, (3.0,), (0, 0, 1))  # a single margin: red within, own colour beyond
    assert np.allclose(one[:3], RED) and np.allclose(one[3:], (0, 0, 1))


def _brute_distance(p, v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    best = np.full(len(p), np.inf)
    for u, w in ((a, b), (b, c), (c, a)):  # edges (closest point on each segment)
        e = w - u
        t = np.clip(np.einsum("pij,ij->pi", p[:, None] - u[None], e) / np.einsum("ij,ij->i", e, e), 0, 1)
        q = u[None] + t[..., None] * e[None]
        best = np.minimum(best, np.linalg.norm(p[:, None] - q, axis=2).min(1))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    h = np.einsum("pij,ij->pi", p[:, None] - a[None], n)  # interiors: projection inside
    q = p[:, None] - h[..., None] * n[None]
    inside = np.ones(h.shape, bool)
    for u, w in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("pij,ij->pi", np.cross(w - u, q - u[None]), n) >= -1e-12
    return np.minimum(best, np.where(inside, np.abs(h), np.inf).min(1))


def test_real_organs_distance_to_the_liver_is_exact():
    from anatomesh.core.extract.multilabel import label_surfaces

    vol = load(SAMPLE / "example_seg.nii.gz", labels=SAMPLE / "label_names_total_and_total_mr.json")
    meshes = label_surfaces(vol, values=[2, 5, 1]).shells()  # right kidney, liver, spleen
    names = [m.name for m in meshes]
    assert names == ["spleen", "kidney_right", "liver"]
    liver = meshes[2]
    _, summary = color_by_distance(meshes, "LIVER", (2, 5, 10))  # names match case-insensitively
    kid = summary["shells"]["kidney_right"]
    assert kid["min_distance_mm"] == 0.0  # the kidney touches the liver: shared seam vertices
    assert 0 < kid["within_mm"]["2"] < kid["within_mm"]["5"] < kid["within_mm"]["10"] < 1
    assert summary["shells"]["spleen"]["min_distance_mm"] is None  # across the abdomen
    k = meshes[1]
    rng = np.random.default_rng(0)
    pick = rng.choice(k.n_vertices, 150, replace=False)
    ref = _brute_distance(k.vertices[pick].astype(np.float64), liver.vertices.astype(np.float64), liver.faces)
    col = k.vertex_colors[pick]
    for d, c in zip(ref, col):
        want = RED if d <= 2 else YELLOW if d <= 5 else GREEN if d <= 10 else None
        if want is None:
            assert not any(np.allclose(c, x) for x in (RED, YELLOW, GREEN))
        elif min(abs(d - 2), abs(d - 5), abs(d - 10)) > 1e-4:  # not on a band's edge
            assert np.allclose(c, want), (d, c)


def test_find_target_by_name_or_value_and_errors():
    meshes = [_slab(), Mesh(*icosphere(1), name="vessel", value=3.0)]
    assert find_target(meshes, "Tumour") == 0 and find_target(meshes, 9) == 0
    assert find_target(meshes, "3") == 1
    with pytest.raises(AnatomeshError, match="no such structure; choose one of tumour, vessel"):
        find_target(meshes, "tumor")


@pytest.mark.parametrize("bad", [[], [5, 2], [0, 1], [1, 2, 3, 4], ["a"], [1, float("nan")]])
def test_bad_margins_are_one_line_errors(bad):
    with pytest.raises(AnatomeshError, match="--margins"):
        check_margins(bad)
    assert check_margins([2, 5.5]) == (2.0, 5.5)
