"""untangle: smoothing never leaves crossing faces (inside a shell or between neighbouring shells)."""
import numpy as np
import pytest

from anatomesh.core import label_surfaces, load
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.geometry.intersections import self_intersections
from anatomesh.core.smooth.driver import smooth_surfaces
from anatomesh.core.smooth.untangle import untangle


@pytest.fixture(scope="module")
def smoothed_sample():
    raw = label_surfaces(load("data/sample/example_seg.nii.gz"))
    sm, _ = smooth_surfaces(raw, "organ", untangle=False)
    return raw, sm


def test_smoothing_alone_makes_faces_cross_and_untangle_removes_every_crossing(smoothed_sample):
    raw, sm = smoothed_sample
    assert len(self_intersections(raw.vertices, raw.faces)) == 0  # surface nets: none
    before = self_intersections(sm.vertices, sm.faces)
    assert len(before) > 0  # the case this module exists for (organs one voxel apart)
    v, info = untangle(sm.vertices, raw.vertices, sm.faces)
    assert info["crossing_pairs"] == len(before) and info["crossings_left"] == 0
    assert len(self_intersections(v, sm.faces)) == 0
    # only vertices near the crossings moved, each back along its own smoothing displacement
    moved = np.any(v != sm.vertices, axis=1)
    assert 0 < moved.sum() == info["moved_vertices"] < 0.02 * len(v)
    d_new = np.linalg.norm(v - raw.vertices, axis=1)
    d_old = np.linalg.norm(sm.vertices - raw.vertices, axis=1)
    assert np.all(d_new <= d_old + 1e-5)


def test_active_faces_give_exactly_the_pairs_that_touch_them(smoothed_sample):
    """self_intersections(..., active=): the full answer's pairs with an active face, no more."""
    _, sm = smoothed_sample
    full = self_intersections(sm.vertices, sm.faces)
    active = np.zeros(len(sm.faces), bool)
    active[full[::2, 0]] = True  # half the crossings' first faces
    active[np.random.default_rng(0).integers(0, len(sm.faces), 500)] = True
    got = self_intersections(sm.vertices, sm.faces, active=active)
    want = full[active[full[:, 0]] | active[full[:, 1]]]
    assert 0 < len(got) < len(full)
    assert sorted(map(tuple, got)) == sorted(map(tuple, want))


def test_untangle_is_a_no_op_without_crossings(smoothed_sample):
    raw, _ = smoothed_sample
    v, info = untangle(raw.vertices + 0.0, raw.vertices, raw.faces)
    assert info == {"crossing_pairs": 0, "moved_vertices": 0, "rounds": 0, "crossings_left": 0}
    assert np.array_equal(v, raw.vertices)


def test_untangle_checks_shapes():
    with pytest.raises(AnatomeshError, match="rest positions"):
        untangle(np.zeros((4, 3)), np.zeros((3, 3)), np.array([[0, 1, 2]]))


def test_default_smoothing_of_the_61_label_map_leaves_no_crossing_faces():
    """The organ preset on the 61-label TotalSegmentator map: no face crosses another, inside a
    shell or between shells (42 pairs crossed before untangling), and the report counts the
    vertices pulled back."""
    from conftest import shared

    raw = label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))
    sm, rep = smooth_surfaces(raw, "organ", distances=False)
    assert len(self_intersections(sm.vertices, sm.faces)) == 0
    assert 0 < rep.params["untangled_vertices"] < 0.01 * len(sm.vertices)
    assert not any("still cross" in w for w in rep.warnings)


def diagonal_gap(n=14):
    """Two labels separated by a diagonal band of background one voxel wide: staircase sheets one
    voxel apart whose risers span two cells, so their faces can cross inside their cells."""
    i, j, k = np.indices((n, n, 6))
    lab = np.zeros((n, n, 6), np.int32)
    inner = (k > 0) & (k < 5)
    lab[inner & (i + j <= n - 2)] = 1
    lab[inner & (i + j >= n)] = 2
    return lab


@pytest.mark.parametrize("seed", [0, 1])
def test_untangling_over_cached_pairs_equals_untangling_over_all_faces(smoothed_sample, seed):
    """Vertices moved at random inside their cells (sheets one voxel apart, and a real map):
    untangling that tests only the cached candidate pairs finds the same crossings every round as
    the search over all faces, so it gives the very same positions, and leaves none."""
    from anatomesh.core.geometry.face_pairs import FaceBoxes
    from anatomesh.core.geometry.neighbors import structure

    rng = np.random.default_rng(seed)
    raw, _ = smoothed_sample
    found = 0
    for ss in (label_surfaces(diagonal_gap()), raw):
        pairs = FaceBoxes(ss.faces, ss.lattice - 0.5, (0.5, 0.5, 0.5))
        if seed:  # both ways of testing: sweeping the buckets, and the listed pairs
            pairs.materialize()
        u = ss.lattice - 0.5 + 0.998 * rng.uniform(-0.5, 0.5, ss.lattice.shape)
        moved = (u @ ss.affine[:3, :3].T + ss.affine[:3, 3]).astype(np.float32)
        s = structure(ss.faces, ss.n_vertices)
        fast, info = untangle(moved, ss.vertices, ss.faces, pairs=pairs, structure=s)
        slow, ref = untangle(moved, ss.vertices, ss.faces)
        assert info == ref and info["crossing_pairs"] > 0
        np.testing.assert_array_equal(fast, slow)
        given = moved.copy()  # in place (memory): the same positions, in the array given
        same, _ = untangle(given, ss.vertices, ss.faces, pairs=pairs, structure=s, in_place=True)
        assert same is given and np.array_equal(same, fast) and not np.array_equal(moved, fast)
        assert len(self_intersections(fast, ss.faces)) == 0
        found += info["crossing_pairs"]
    assert found > 20


def test_untangling_leaves_no_folded_faces_on_the_chest_ct_bone():
    """Untangling pulls vertices part of the way back toward the unsmoothed surface, which can
    fold a face (the chest CT's 300 HU surface had 4-5): the driver unfolds those and untangles
    the moved vertices' faces again, so the default leaves neither folds nor crossings."""
    from anatomesh.core.extract.isosurface import isosurface
    from anatomesh.core.geometry.face_pairs import FaceBoxes
    from anatomesh.core.model.surfaceset import SurfaceSet
    from conftest import shared

    vol = load(shared("itkelastix_chest_ct"))
    mesh = isosurface(vol, 300.0)
    raw = SurfaceSet.from_meshes([mesh], vol.affine, mesh.space)
    sm, rep = smooth_surfaces(raw, "organ", topology=False)
    shell = next(iter(rep.shells.values()))
    assert rep.params["untangled_vertices"] > 0  # untangling had work to do here
    assert shell["flipped_faces"] == 0
    assert not any("folded" in w or "cross" in w for w in rep.warnings)
    centres = np.einsum("ij,kj->ik", raw.vertices - vol.affine[:3, 3],
                        np.linalg.inv(vol.affine[:3, :3]))
    boxes = FaceBoxes(raw.faces, centres, (0.5, 0.5, 0.5))
    assert len(boxes.crossings(sm.vertices)) == 0


def test_the_one_ring_of_seeds_needs_no_one_ring(smoothed_sample):
    """one_ring_of takes the corners of the seeds' faces: the same vertices as the 1-ring
    CSR's rows (which a one-shot run has freed), and the structure builds no 1-ring for it."""
    from anatomesh.core.geometry.neighbors import MeshStructure
    from anatomesh.core.smooth.untangle import one_ring_of, rows_of

    raw = smoothed_sample[0]
    s = MeshStructure(raw.faces, raw.n_vertices)
    seeds = np.random.default_rng(5).choice(raw.n_vertices, 300, replace=False)
    got = one_ring_of(s, seeds)
    assert s._ring is None
    want = np.unique(np.concatenate([seeds, rows_of(s.ring_offsets, s.ring, seeds)]))
    np.testing.assert_array_equal(got, want)
    assert len(got) > 5 * len(seeds)
