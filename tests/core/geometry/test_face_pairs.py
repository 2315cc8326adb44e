"""Candidate face pairs from vertex boxes, and the crossing test over them, against brute force."""
import numpy as np
import pytest

from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry import _face_pair_kernels as K
from anatomesh.core.geometry import kernels as IK
from anatomesh.core.geometry.face_pairs import FaceBoxes, candidate_pairs, crossing_pairs_among
from anatomesh.core.geometry.intersections import self_intersections
from anatomesh.core.model.errors import AnatomeshError


def diagonal_gap(n=14):
    """Two labels separated by a diagonal band of background one voxel wide: staircase sheets
    whose risers span two cells, so their faces can cross while every vertex stays in its cell."""
    i, j, k = np.indices((n, n, 6))
    lab = np.zeros((n, n, 6), np.int32)
    inner = (k > 0) & (k < 5)
    lab[inner & (i + j <= n - 2)] = 1
    lab[inner & (i + j >= n)] = 2
    return lab


def jitter(ss, rng, scale=1.0):
    """Every vertex moved uniformly inside its lattice cell (scale 1: the whole cell)."""
    return (ss.lattice - 0.5 + scale * rng.uniform(-0.5, 0.5, ss.lattice.shape)).astype(np.float32)


def extents(faces, centres, half):
    """(lo, hi) (M, 3): the bounding box of each face's corner boxes centre ± half."""
    corners = np.asarray(centres, np.float64)[faces]
    return corners.min(axis=1) - half, corners.max(axis=1) + half


def brute_candidates(lo, hi, faces):
    m = len(faces)
    out = set()
    for a in range(m):
        ok = np.all((lo[a] < hi) & (lo < hi[a]), axis=1)
        ok[:a + 1] = False
        for b in np.flatnonzero(ok):
            if not set(faces[a]) & set(faces[b]):
                out.add((a, int(b)))
    return out


def test_scalar_triangle_test_gives_the_reference_answer_bit_for_bit():
    """Random, nearly coplanar, touching and degenerate pairs, both orders: same as
    tri_tri_intersect (which the grid search uses)."""
    rng = np.random.default_rng(3)
    cases = []
    for _ in range(4000):
        t = rng.normal(size=(6, 3))
        cases.append(t)
        flat = t.copy()
        flat[:, 2] = rng.normal(scale=1e-7, size=6)  # nearly coplanar
        cases.append(flat)
        grid = np.round(t * 2) / 2  # shared coordinates: touching edges and corners
        cases.append(grid)
        coplanar = grid.copy()
        coplanar[:, 2] = 0.0
        cases.append(coplanar)
    cases.append(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 0], [0, 1, 0], [1, 1, 0.]]))
    hits = 0
    for X in cases:
        X = np.ascontiguousarray(X, np.float64) * 100 + 250.0  # patient-like coordinates
        for a, b in ((0, 3), (3, 0)):
            want = IK.tri_tri_intersect(X[a], X[a + 1], X[a + 2], X[b], X[b + 1], X[b + 2], 1e-9)
            got = K.tri_tri(X, a, a + 1, a + 2, b, b + 1, b + 2, 1e-9)
            assert got == want
            hits += want
    assert 0.1 * 2 * len(cases) < hits < 0.9 * 2 * len(cases)


def test_candidate_pairs_are_exactly_the_overlapping_extents():
    ss = label_surfaces(diagonal_gap(8))
    centres = ss.lattice - 0.5
    lo, hi = extents(ss.faces, centres, 0.5)
    pairs = candidate_pairs(ss.faces, centres, (0.5, 0.5, 0.5))
    got = set(map(tuple, pairs.as_array()))
    assert len(got) == pairs.n_pairs  # each pair once
    assert got == brute_candidates(lo, hi, ss.faces)
    # float boxes (a marching-cubes-like surface: boxes around any start), anisotropic half
    rng = np.random.default_rng(5)
    centres = centres + rng.uniform(-0.3, 0.3, centres.shape)
    lo, hi = extents(ss.faces, centres, np.array([0.4, 0.5, 0.7]))
    got = set(map(tuple, candidate_pairs(ss.faces, centres, (0.4, 0.5, 0.7)).as_array()))
    assert got == brute_candidates(lo, hi, ss.faces)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_candidate_pairs_find_every_crossing_of_vertices_jittered_in_their_cells(seed):
    """Sheets one voxel apart (staircases along a diagonal gap) and the 41-label
    TotalSegmentator map, every vertex moved at random inside its cell: the crossings among the
    candidate pairs are exactly the crossings of a search over all faces, for the float32
    positions (tested as they are) and for their float64 copy."""
    from anatomesh.core import load
    from conftest import shared

    rng = np.random.default_rng(seed)
    found = 0
    for ss in (label_surfaces(diagonal_gap()),
               label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))):
        pairs = candidate_pairs(ss.faces, ss.lattice - 0.5, (0.5, 0.5, 0.5))
        v = jitter(ss, rng, 0.998) * np.float32(1.5) + np.float32(7.0)  # 1.5 mm voxels
        want = self_intersections(v, ss.faces)
        want = want[np.lexsort((want[:, 1], want[:, 0]))]
        assert v.dtype == np.float32
        np.testing.assert_array_equal(crossing_pairs_among(v, pairs), want)
        np.testing.assert_array_equal(crossing_pairs_among(v.astype(np.float64), pairs), want)
        np.testing.assert_array_equal(FaceBoxes(ss.faces, ss.lattice - 0.5, 0.5).crossings(v), want)
        lean = FaceBoxes(ss.faces, ss.lattice - 0.5, 0.5, listing=False)  # one-shot: no extents
        np.testing.assert_array_equal(lean.crossings(v), want)
        got = want
        found += len(got)
        active = np.zeros(len(ss.faces), bool)
        active[rng.integers(0, len(ss.faces), len(ss.faces) // 50)] = True
        active[want[::3, 1]] = True
        got = crossing_pairs_among(v, pairs, active)
        keep = want[active[want[:, 0]] | active[want[:, 1]]]
        assert sorted(map(tuple, got)) == sorted(map(tuple, keep))
    assert found > 100  # jittered sheets do cross: the test can fail


def test_faces_a_hair_apart_do_not_cross_although_their_16_bit_boxes_overlap():
    """The stored face boxes are 16-bit steps of the positions' span (~0.005 mm over 300 mm):
    two parallel triangles 1e-9 mm apart share a step, and Möller's tolerance calls them
    touching, but their exact boxes are apart: no crossing, as for the search over all faces.
    The same triangles in one plane do cross (touching counts)."""
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    far = tri + 300.0  # a third face: the positions span 300 mm
    faces = np.arange(9, dtype=np.int32).reshape(3, 3)
    for gap, crossing in ((1e-9, False), (0.0, True)):
        v = np.vstack([tri, tri + [0.2, 0.2, gap], far]).astype(np.float32)
        want = self_intersections(v, faces)
        assert len(want) == int(crossing)
        for listing in (True, False):
            boxes = FaceBoxes(faces, v, 0.5, listing)
            np.testing.assert_array_equal(boxes.crossings(v), want)
            np.testing.assert_array_equal(boxes.crossings(v, np.ones(3, bool)), want)
            if listing:
                np.testing.assert_array_equal(boxes.materialize().crossings(v), want)


def test_bad_inputs():
    ss = label_surfaces(diagonal_gap(6))
    pairs = candidate_pairs(ss.faces, ss.lattice - 0.5, 0.5)
    with pytest.raises(AnatomeshError, match="do not match"):
        crossing_pairs_among(ss.vertices[:10], pairs)
    with pytest.raises(AnatomeshError, match="positive"):
        candidate_pairs(ss.faces, ss.lattice - 0.5, 0.0)
    with pytest.raises(AnatomeshError, match="one flag per face"):
        crossing_pairs_among(ss.vertices, pairs, np.ones(3, bool))
    with pytest.raises(AnatomeshError, match="listing=True"):
        FaceBoxes(ss.faces, ss.lattice - 0.5, 0.5, listing=False).materialize()
    with pytest.raises(AnatomeshError, match="span up to"):
        FaceBoxes(ss.faces, ss.lattice * 1e5, 0.5)
