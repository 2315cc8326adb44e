"""Pinch points resolved in geometry: voxel phantoms whose labels touch themselves along an edge
or at a corner, meshed, separated and judged by position (vertices joined where they coincide,
as STL readers do) with trimesh, a reader nobody here wrote."""
import numpy as np
import pytest
import trimesh

from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.intersections import crossing_pairs
from anatomesh.core.geometry.pinches import (PINCH_GAP_MM, copy_numbers, pinch_gap_mm,
                                             pinch_moves, separate_shells, shell_label)
from anatomesh.core.model.mesh import signed_volume


def _separated(vol, spacing=1.0):
    affine = np.diag([spacing, spacing, spacing, 1.0])
    s = label_surfaces(vol, affine=affine)
    meshes = s.shells()
    info = separate_shells(s, meshes, pinch_gap_mm(s.affine))
    return s, meshes, info


def _by_position(mesh):
    """trimesh's reading of a mesh given as positions only (a triangle soup, like STL)."""
    soup = mesh.vertices[mesh.faces].reshape(-1, 3)
    t = trimesh.Trimesh(soup, np.arange(len(soup)).reshape(-1, 3), process=True)
    _, counts = np.unique(t.edges_sorted, axis=0, return_counts=True)
    parts = trimesh.graph.connected_components(t.face_adjacency, nodes=np.arange(len(t.faces)))
    return t, bool(np.all(counts == 2)), len(parts)


def _cubes_on_edge():
    vol = np.zeros((6, 6, 5), np.uint8)
    vol[1:3, 1:3, 1:4] = 1
    vol[3:5, 3:5, 1:4] = 1  # touches the first block along a 3-voxel edge
    return vol


def _cubes_on_corner():
    vol = np.zeros((6, 6, 6), np.uint8)
    vol[1:3, 1:3, 1:3] = 1
    vol[3:5, 3:5, 3:5] = 1  # touches the first block at one corner
    return vol


@pytest.mark.parametrize("make, points", [(_cubes_on_edge, 4), (_cubes_on_corner, 1)])
def test_touching_blocks_become_two_closed_manifold_pieces(make, points):
    s, meshes, info = _separated(make())
    (mesh,) = meshes
    t, two_per_edge, parts = _by_position(mesh)
    assert info["points"] == points  # the edge's 4 lattice vertices, or the one corner
    assert two_per_edge and t.is_watertight and t.is_winding_consistent
    assert parts == 2 and t.body_count == 2
    assert abs(signed_volume(mesh.vertices, mesh.faces) - 16.0 * (1.5 if points == 4 else 1)) \
        <= points * 2 * PINCH_GAP_MM + 1e-9  # a moved fan changes the volume by ≤ 2·gap·s²
    assert crossing_pairs([(mesh.vertices, mesh.faces)]).pairs.shape[0] == 0


def test_unpinched_shapes_do_not_move():
    vol = np.zeros((6, 6, 6), np.uint8)
    vol[1:5, 1:5, 1:5] = 1
    vol[2:4, 2:4, 2:4] = 2  # a label inside another: a cavity, no pinch
    s, meshes, info = _separated(vol)
    assert info["points"] == 0
    for m in meshes:
        assert np.array_equal(m.vertices, s.vertices[m.meta["vertex_ids"]])


def test_moves_are_the_stated_gap_and_stay_in_own_cone():
    s, (mesh,), info = _separated(_cubes_on_edge(), spacing=2.0)
    moved = np.linalg.norm(mesh.vertices - s.vertices[mesh.meta["vertex_ids"]], axis=1)
    gap = pinch_gap_mm(s.affine)
    assert gap == pytest.approx(PINCH_GAP_MM)
    assert np.all(moved[moved > 0] == pytest.approx(gap, rel=1e-5))
    # one fan stays, the other moves: exactly the edge's 4 vertices moved once
    assert np.count_nonzero(moved) == info["points"] == 4


def test_fine_grids_get_a_gap_of_a_tenth_of_a_voxel():
    assert pinch_gap_mm(np.diag([0.2, 0.3, 0.25, 1.0])) == pytest.approx(0.02)
    assert pinch_gap_mm(np.diag([3.0, 3.0, 3.0, 1.0])) == pytest.approx(PINCH_GAP_MM)


def test_checkerboard_of_two_labels_opens_no_overlap():
    """Two labels alternating around an edge: their seams cross at the edge, so each copy moves
    into its own material; the shells stay 2-manifold by position and never overlap."""
    vol = np.zeros((4, 4, 3), np.uint8)
    vol[1, 1, 1] = vol[2, 2, 1] = 1
    vol[1, 2, 1] = vol[2, 1, 1] = 2
    s, meshes, info = _separated(vol)
    assert info["checkerboards"] >= 1
    for m in meshes:
        _, two_per_edge, parts = _by_position(m)
        assert two_per_edge and parts == 2
    both = crossing_pairs([(m.vertices, m.faces) for m in meshes])
    assert both.pairs.shape[0] == 0


def test_invariant_to_label_numbering():
    vol = _cubes_on_edge().astype(np.uint8)
    vol[vol == 0] = 0
    other = vol.copy()
    vol[4:6, 0:2, 1:4] = 2  # a second label elsewhere
    other[4:6, 0:2, 1:4] = 7
    a = _separated(vol)[1]
    b = _separated(other)[1]
    va = sorted(np.round(m.vertices, 6).tobytes() for m in a)
    vb = sorted(np.round(m.vertices, 6).tobytes() for m in b)
    assert va == vb


def test_copy_numbers_and_shell_label():
    s, (mesh,), _ = _separated(_cubes_on_edge())
    ids = mesh.meta["vertex_ids"]
    copies = copy_numbers(ids)
    assert copies.max() == 1 and np.count_nonzero(copies) == 4
    assert shell_label(s, mesh) == 1


def test_moves_summary_states_the_rule():
    s = label_surfaces(_cubes_on_corner(), affine=np.eye(4))
    summary = pinch_moves(s, PINCH_GAP_MM).summary()
    assert summary["points"] == 1 and summary["gap_mm"] == PINCH_GAP_MM
    assert "moved apart" in summary["rule"]
