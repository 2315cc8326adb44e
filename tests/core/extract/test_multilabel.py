"""label_surfaces(): conforming multi-label shells (cuberille / surface nets topology).

Every test checks the invariants on every shell: closed, 2-manifold (edges and vertices),
consistently oriented with positive volume equal to the voxel volume, and seams shared
bit-for-bit between touching labels.
"""
from __future__ import annotations

import numba
import numpy as np
import pytest

from anatomesh.core import AnatomeshError, LabelInfo, Volume, load
import anatomesh.core.extract.multilabel as labels_module
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.extract.shell_table import FACE_VOXELS, tables
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.surfaceset import SurfaceSet

from conftest import shared


# ---------------------------------------------------------------------------------------------
# checks
# ---------------------------------------------------------------------------------------------
def check_shells(s: SurfaceSet, arr: np.ndarray, affine=np.eye(4), values=None):
    """All invariants for every label of ``arr`` (or ``values``); returns {value: topology}."""
    voxel = abs(np.linalg.det(np.asarray(affine)[:3, :3]))
    expected = values if values is not None else [int(v) for v in np.unique(arr)
                                                  if v != s.background]
    assert s.values() == sorted(expected)
    out = {}
    for m in s.shells():
        t = topology(m.vertices, m.faces)
        assert t.closed and t.manifold and t.oriented, (m.value, t.as_dict())
        assert t.degenerate_faces == 0
        count = int(np.count_nonzero(arr == m.value))
        assert s.voxel_counts[m.value] == count
        assert signed_volume(m.vertices, m.faces) == pytest.approx(count * voxel, rel=1e-5)
        np.testing.assert_array_equal(m.vertices, s.vertices[m.meta["vertex_ids"]])
        out[m.value] = t
    check_seams(s)
    return out


def _position_ids(vertices: np.ndarray) -> np.ndarray:
    """One id per distinct position (exact float32 bit pattern)."""
    bits = np.ascontiguousarray(vertices, np.float32).view(np.uint32).reshape(-1, 3)
    return np.unique(bits, axis=0, return_inverse=True)[1].reshape(-1)


def _triangle_keys(pos: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each triangle as the sorted position ids of its corners, rows sorted: two face sets are
    the same geometric triangles iff their keys are equal."""
    keys = np.sort(pos[faces], axis=1)
    return keys[np.lexsort(keys.T[::-1])]


def _same_triangles(va, fa, vb, fb) -> bool:
    """Do (va, fa) and (vb, fb) hold the same triangles, bit-identical positions?"""
    pos = _position_ids(np.concatenate([va, vb]))
    return len(fa) == len(fb) and np.array_equal(_triangle_keys(pos, fa),
                                                 _triangle_keys(pos, fb + len(va)))


def check_seams(s: SurfaceSet):
    """Touching labels share bit-identical faces; no face is stored twice.

    Shell vertices equal ``s.vertices[vertex_ids]`` bit for bit (checked in check_shells), so
    one position numbering of the set serves all shells."""
    fl = s.face_labels
    pos = _position_ids(s.vertices)
    keys = _triangle_keys(pos, s.faces)
    assert not np.any(np.all(keys[1:] == keys[:-1], axis=1))  # no two faces at one place
    shells = {m.value: m for m in s.shells()}
    rows = {v: fl[(fl == v).any(axis=1)] for v in shells}  # each shell's faces' labels, in order
    for a, b, n in s.interfaces():
        pa = pos[shells[a].meta["vertex_ids"]]
        pb = pos[shells[b].meta["vertex_ids"]]
        fa = shells[a].faces[(rows[a] == b).any(axis=1)]
        fb = shells[b].faces[(rows[b] == a).any(axis=1)]
        assert len(fa) == len(fb) == n
        assert np.array_equal(_triangle_keys(pa, fa), _triangle_keys(pb, fb)), (a, b)


def ball(shape, centre, radius):
    idx = np.indices(shape).astype(float)
    return sum((idx[d] - centre[d]) ** 2 for d in range(3)) <= radius ** 2


# ---------------------------------------------------------------------------------------------
# built maps
# ---------------------------------------------------------------------------------------------
def test_touching_boxes_share_their_interface():
    a = np.zeros((6, 7, 8), np.uint8)
    a[1:5, 1:6, 1:4] = 1
    a[1:5, 1:6, 4:7] = 2
    s = label_surfaces(a)
    topo = check_shells(s, a)
    assert topo[1].genus == 0 and topo[2].genus == 0
    assert s.interfaces() == [(1, 2, 2 * 4 * 5)]
    # each face is stored once: the 4x5 contact appears in neither shell twice
    assert len(s.splits) == 0
    assert s.n_faces == 2 * (2 * (4 * 5 + 4 * 6 + 5 * 6) + 4 * 5)  # outer box + contact


def test_nested_balls_in_a_box():
    shape = (24, 24, 24)
    a = np.zeros(shape, np.uint8)
    a[2:22, 2:22, 2:22] = 3
    a[ball(shape, (12, 12, 12), 7)] = 2
    a[ball(shape, (12, 12, 12), 3.5)] = 1
    topo = check_shells(label_surfaces(a), a)
    assert topo[1].components == 1 and topo[1].genus == 0
    assert topo[2].components == 2  # outer sphere + the cavity around label 1
    assert topo[3].components == 2


@pytest.mark.parametrize("second", [(1, 1, 0), (1, 0, 1), (0, 1, 1), (1, 1, 1)])
def test_voxels_of_one_label_touching_along_an_edge_or_a_vertex(second):
    a = np.zeros((3, 3, 3), np.uint8)
    a[0, 0, 0] = 1
    a[second] = 1
    s = label_surfaces(a)
    topo = check_shells(s, a)
    assert topo[1].components == 2 and topo[1].genus == 0
    assert len(s.splits) > 0  # the touching corner(s) got a vertex copy
    m = s.shell(1)
    assert m.n_vertices == 16  # two cubes of 8 corners: nothing shared in the shell


@pytest.mark.parametrize("second", [(1, 1, 0), (1, 1, 1)])
def test_different_labels_touching_along_an_edge_or_a_vertex(second):
    a = np.zeros((2, 2, 2), np.uint8)
    a[0, 0, 0] = 1
    a[second] = 2
    s = label_surfaces(a)
    check_shells(s, a)
    assert s.interfaces() == []
    shared_ = set(s.shell(1).meta["vertex_ids"]) & set(s.shell(2).meta["vertex_ids"])
    assert len(shared_) == (2 if sum(second) == 2 else 1)  # the same corner vertices


def test_pinched_complement():
    """Label 1 everywhere around two background voxels that touch at one corner."""
    a = np.ones((4, 4, 4), np.uint8)
    a[1, 1, 1] = 0
    a[2, 2, 2] = 0
    topo = check_shells(label_surfaces(a), a)
    assert topo[1].components == 3  # outside + two cavities


def test_ring_has_genus_one():
    shape = (20, 20, 8)
    i, j, _ = np.indices(shape)
    r = np.hypot(i - 9.5, j - 9.5)
    a = ((r >= 4) & (r <= 8)).astype(np.uint8)
    a[:, :, [0, 1, 6, 7]] = 0
    a[(a == 1) & (i < 10)] = 2  # two half rings: each genus 0, the union would be genus 1
    topo = check_shells(label_surfaces(a), a)
    assert topo[1].genus == 0 and topo[2].genus == 0
    b = (a > 0).astype(np.uint8)
    assert check_shells(label_surfaces(b), b)[1].genus == 1


@pytest.mark.parametrize("nlabels", [2, 3])
def test_checkerboards(nlabels):
    i, j, k = np.indices((6, 7, 5))
    a = ((i + j + k) % nlabels + 1).astype(np.uint8)
    s = label_surfaces(a)
    check_shells(s, a)
    assert len(s.splits) > 0


def test_checkerboard_with_background_holes():
    i, j, k = np.indices((7, 6, 6))
    a = ((i + j + k) % 2).astype(np.uint8)  # label 1 cells touch only along edges and corners
    check_shells(label_surfaces(a), a)


@pytest.mark.parametrize("seed", range(12))
def test_random_label_noise(seed):
    rng = np.random.default_rng(seed)
    nlabels = int(rng.integers(3, 7))
    shape = tuple(int(n) for n in rng.integers(4, 11, 3))
    a = rng.integers(0, nlabels, shape).astype(np.uint8)
    if seed % 2:  # sparser noise: more isolated voxels and pinches against the background
        a[rng.random(shape) < 0.4] = 0
    check_shells(label_surfaces(a), a)


def test_joined_edges_are_needed_and_handled():
    """A label looping around a diagonal lattice edge, 6-connected through the blocks at both
    ends: with 6-connectivity alone the edge would carry 4 triangles of the shell. The table
    joins the label across such an edge, which keeps the shell a closed 2-manifold."""
    a = np.zeros((4, 4, 5), np.uint8)
    # layers 1 and 3: an L of three voxels around the edge; layer 2: the diagonal pair only
    for z in (1, 3):
        a[1, 1, z] = a[2, 1, z] = a[2, 2, z] = 1
    a[1, 1, 2] = a[2, 2, 2] = 1
    _, joinable, _ = tables()
    # corner (2, 2, 2): label voxels q = 0, 1, 3 (layer 1) and 4, 7 (layer 2); half-edge +z = 5
    assert (joinable[1 + 2 + 8 + 16 + 128] >> 5) & 1
    s = label_surfaces(a)
    topo = check_shells(s, a)
    assert topo[1].genus == 0  # joined: the label closes around the edge, no handle
    assert len(s.splits) > 0


def test_shell_table_fans():
    cycle, joinable, needs = tables()
    fans = lambda cfg, bits=0: cycle[cfg * 64 + bits]  # noqa: E731
    assert sorted(fans(0b00000001)) == [-1] * 9 + [0] * 3  # one voxel: one fan of 3 faces
    assert fans(0b00000011).max() == 0 and not needs[0b00000011]  # two face-adjacent voxels
    assert fans(0b10000001).max() == 1 and needs[0b10000001]  # vertex-diagonal pair: 2 fans
    assert fans(0b00001001).max() == 1  # edge-diagonal pair: 2 fans
    assert fans(0b10010110).max() == 3  # checkerboard: 4 isolated voxels
    assert fans(0b01111110).max() == 1  # around a pinched complement: 2 fans
    assert joinable[0] == 0 and joinable[255] == 0
    for cfg in range(256):  # every label face is in a fan of >= 3 faces, for any joins allowed
        for bits in range(64):
            if bits & ~int(joinable[cfg]):
                continue
            f = fans(cfg, bits)
            boundary = [(cfg >> int(p)) & 1 != (cfg >> int(q)) & 1 for p, q in FACE_VOXELS]
            assert np.array_equal(f >= 0, boundary)
            if f.max() >= 0:
                assert np.bincount(f[f >= 0]).min() >= 3


# ---------------------------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------------------------
def _affines():
    aniso = np.diag([0.7, 0.8, 2.5, 1.0])
    aniso[:3, 3] = (-100.0, 20.0, 5.0)
    c, s_ = np.cos(0.4), np.sin(0.4)
    oblique = np.eye(4)
    oblique[:3, :3] = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]]) @ np.diag([1.2, 0.9, 3.0])
    oblique[:3, :3] += np.array([[0, 0, 0.3], [0, 0, 0], [0.1, 0, 0]])  # sheared
    oblique[:3, 3] = (12.0, -7.0, 300.0)
    mirrored = np.diag([-0.9, -0.9, 2.0, 1.0])  # LPS-like flip of two axes: det > 0
    negdet = np.diag([-1.5, 1.0, 1.0, 1.0])  # det < 0
    negdet[:3, 3] = (50.0, 0.0, 0.0)
    return {"aniso": aniso, "oblique": oblique, "mirrored": mirrored, "negdet": negdet}


@pytest.mark.parametrize("name", list(_affines()))
def test_affines_keep_volumes_orientation_and_corner_positions(name):
    A = _affines()[name]
    rng = np.random.default_rng(3)
    a = np.zeros((7, 8, 6), np.uint8)
    a[1:6, 1:7, 1:5] = rng.integers(1, 4, (5, 6, 4))
    s = label_surfaces(a, affine=A)
    check_shells(s, a, A)
    # vertices are voxel corners: lattice (a, b, c) at index (a - .5, b - .5, c - .5)
    expect = (s.lattice - 0.5) @ A[:3, :3].T + A[:3, 3]
    np.testing.assert_allclose(s.vertices, expect, atol=1e-4)


def test_memory_order_does_not_change_the_surface():
    rng = np.random.default_rng(5)
    a = rng.integers(0, 4, (6, 9, 7)).astype(np.uint8)
    A = _affines()["oblique"]
    c = label_surfaces(np.ascontiguousarray(a), affine=A)
    f = label_surfaces(np.asfortranarray(a), affine=A)
    odd = label_surfaces(a.transpose(1, 2, 0).copy().transpose(2, 0, 1), affine=A)  # a 3-cycle
    for s in (f, odd):
        check_shells(s, a, A)
        assert _same_triangles(c.vertices, c.faces, s.vertices, s.faces)
        expect = (s.lattice - 0.5) @ A[:3, :3].T + A[:3, 3]  # lattice in the volume's (i, j, k)
        np.testing.assert_allclose(s.vertices, expect, atol=1e-4)


def test_output_does_not_depend_on_thread_count(monkeypatch):
    rng = np.random.default_rng(11)
    a = rng.integers(0, 5, (30, 12, 10)).astype(np.uint8)
    monkeypatch.setattr(labels_module, "PARALLEL_MIN_VOXELS", 0)  # threads even for tiny maps
    n = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = label_surfaces(a)
    finally:
        numba.set_num_threads(n)
    many = label_surfaces(a)
    for field in ("vertices", "faces", "face_labels", "lattice", "splits"):
        np.testing.assert_array_equal(getattr(one, field), getattr(many, field))
    assert numba.get_num_threads() == n


def test_serial_twins_give_the_parallel_kernels_output(monkeypatch):
    a = np.asfortranarray(np.random.default_rng(12).integers(0, 6, (25, 14, 11)).astype(np.uint8))
    monkeypatch.setattr(labels_module, "PARALLEL_MIN_VOXELS", 10**12)  # count_serial, one emit_run
    serial = label_surfaces(a)
    monkeypatch.setattr(labels_module, "PARALLEL_MIN_VOXELS", 0)  # the prange kernels
    parallel = label_surfaces(a)
    check_shells(serial, np.asarray(a))
    for field in ("vertices", "faces", "face_labels", "lattice", "splits"):
        np.testing.assert_array_equal(getattr(serial, field), getattr(parallel, field))


# ---------------------------------------------------------------------------------------------
# values, subsets, background
# ---------------------------------------------------------------------------------------------
def test_subset_crops_and_treats_other_labels_as_background():
    a = np.zeros((12, 12, 12), np.uint8)
    a[1:6, 1:6, 1:6] = 1
    a[6:10, 2:6, 2:6] = 2
    a[3:8, 7:11, 7:11] = 3
    s = label_surfaces(a, values=[2, 3])
    check_shells(s, a, values=[2, 3])
    assert 1 not in s.voxel_counts
    assert set(np.unique(s.face_labels[:, 1])) == {0}  # 2 and 3 do not touch; 1 is background
    lo = s.lattice.min(axis=0)
    hi = s.lattice.max(axis=0)
    assert lo.tolist() == [3, 2, 2] and hi.tolist() == [10, 11, 11]  # the labels' box corners
    one = label_surfaces(a, values=2)
    assert one.values() == [2]


def test_large_label_values_and_other_background():
    a = np.full((6, 6, 7), 7, np.uint16)  # 7 is the background here
    a[1:3, 1:5, 1:6] = 1000
    a[3:5, 1:5, 1:6] = 65535
    a[2:4, 2:4, 0] = 0  # 0 is a real label when the background is 7
    s = label_surfaces(a, background=7)
    check_shells(s, a)
    assert s.values() == [0, 1000, 65535]
    assert s.background == 7
    assert set(np.unique(s.face_labels[:, 1])) <= {0, 1000, 65535, 7}
    assert not np.any(s.face_labels[:, 0] == 7)  # the background is never inside
    assert (1000, 65535, 2 * 4 * 5) in s.interfaces()
    assert s.labels[65535].name  # every label has a name and colour


def test_int32_and_float_maps():
    a = np.zeros((5, 5, 5), np.int32)
    a[1:4, 1:4, 1:3] = 300
    a[1:4, 1:4, 3] = 2
    check_shells(label_surfaces(a), a)
    check_shells(label_surfaces(a.astype(np.float32)), a)


def test_absent_label_warns_and_shell_raises():
    a = np.zeros((4, 4, 4), np.uint8)
    a[1:3, 1:3, 1:3] = 1
    with pytest.warns(UserWarning, match="not in the volume"):
        s = label_surfaces(a, values=[1, 5])
    assert s.values() == [1]
    assert any("5" in w for w in s.warnings)
    with pytest.raises(AnatomeshError, match="label 5 has no surface"):
        s.shell(5)


def test_all_background_gives_an_empty_set():
    s = label_surfaces(np.zeros((5, 4, 3), np.uint8))
    assert s.n_faces == 0 and s.n_vertices == 0
    assert s.values() == [] and s.shells() == [] and s.interfaces() == []
    with pytest.warns(UserWarning):
        s2 = label_surfaces(np.zeros((5, 4, 3), np.uint8), values=[3])
    assert s2.n_faces == 0


@pytest.mark.parametrize("data, match", [
    (np.zeros((4, 4), np.uint8), "3D"),
    (np.full((3, 3, 3), 0.5), "whole numbers"),
    (np.full((3, 3, 3), -1, np.int16), "0..65535"),
    (np.full((3, 3, 3), 70000, np.int32), "0..65535"),
])
def test_bad_inputs_raise_clear_errors(data, match):
    with pytest.raises(AnatomeshError, match=match):
        label_surfaces(data)


def test_bad_arguments_raise_clear_errors():
    a = np.ones((2, 2, 2), np.uint8)
    with pytest.raises(AnatomeshError, match="background"):
        label_surfaces(a, background=-1)
    with pytest.raises(AnatomeshError, match="affine"):
        label_surfaces(a, affine=np.zeros((4, 4)))
    with pytest.raises(AnatomeshError, match="space"):
        label_surfaces(a, space="XYZ")


def test_volume_input_space_labels_and_progress():
    a = np.zeros((5, 5, 5), np.uint8)
    a[1:4, 1:4, 1:4] = 4
    A = np.diag([2.0, 2.0, 2.0, 1.0])
    vol = Volume(a, A, "RAS", labels={4: LabelInfo(4, "liver", (0.5, 0.2, 0.1))})
    calls = []
    s = label_surfaces(vol, space="LPS", progress=lambda f, t: calls.append(f))
    assert s.space == "LPS"
    m = s.shell(4)
    assert (m.name, m.value, m.color, m.space) == ("liver", 4, (0.5, 0.2, 0.1), "LPS")
    assert signed_volume(m.vertices, m.faces) == pytest.approx(27 * 8)
    assert np.all(m.vertices[:, 0] <= -1.0)  # x negated in LPS
    assert calls[-1] == 1.0 and all(0 <= f <= 1 for f in calls)


def test_copy_with_vertices_moves_split_copies_with_their_vertex():
    a = np.zeros((3, 3, 3), np.uint8)
    a[0, 0, 0] = a[1, 1, 1] = 1  # one shared corner, split in the shell
    s = label_surfaces(a)
    moved = s.copy_with_vertices(s.vertices + np.float32(0.25))
    m = moved.shell(1)
    np.testing.assert_array_equal(m.vertices, moved.vertices[m.meta["vertex_ids"]])
    assert m.meta["copies"] == 1
    assert topology(m.vertices, m.faces).manifold
    assert s.vertices[0, 0] + 0.25 == moved.vertices[0, 0]  # the original is untouched
    with pytest.raises(ValueError):
        s.copy_with_vertices(s.vertices[:-1])


# ---------------------------------------------------------------------------------------------
# real label maps
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, nlabels", [("example_seg_fast_force_split.nii.gz", 61),
                                           ("example_seg.nii.gz", 41)])
def test_totalsegmentator_maps(name, nlabels):
    vol = load(shared("totalsegmentator", name))
    arr = np.asarray(vol.data)
    s = label_surfaces(vol)
    assert len(s.values()) == nlabels
    check_shells(s, arr, vol.affine)
    assert len(s.interfaces()) > 50  # many touching organs and bones
    assert s.space == vol.space
