"""The component guard: default smoothing keeps the volume of every connected component of every
label's shell (single-voxel specks, specks on or inside another label, 1-2 voxel cavities) within
its bound, with seams shared, shells closed and every vertex in its cell."""
import numpy as np
import pytest

from anatomesh.core import load
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.neighbors import MeshStructure
from anatomesh.core.geometry.topology import face_components, topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.model.surfaceset import SurfaceSet
from anatomesh.core.smooth.components import ComponentGuard, shell_component_sides
from anatomesh.core.smooth.constraints import Constraint
from anatomesh.core.smooth.driver import SmoothingSession, smooth_surfaces
from conftest import shared

BOUND = 0.10  # the default component_bound_pct, as a fraction
SPACING = (1.0, 1.2, 1.5)
SPECKS = [(2, 2, 2), (2, 13, 23), (23, 3, 12), (13, 2, 3)]  # label 1, in the background
EDGE_PAIR = [(2, 20, 2), (3, 21, 2)]  # label 1, two voxels touching along an edge
CAVITIES = [[(10, 13, 13)], [(16, 13, 13), (16, 14, 13)]]  # background inside label 1


@pytest.fixture(scope="module")
def phantom():
    """A ball of label 1 with single-voxel specks around it, two specks touching along an edge,
    a label-2 speck on its surface and one inside it, and a 1- and a 2-voxel cavity."""
    idx = np.indices((26, 26, 26))
    lab = (((idx - 13) ** 2).sum(0) <= 49).astype(np.int32)
    for p in SPECKS + EDGE_PAIR:
        lab[p] = 1
    lab[13, 13, 21] = 2  # on the ball's surface: touches label 1 and the background
    lab[13, 13, 13] = 2  # inside: a cavity of label 1 filled by label 2
    for cavity in CAVITIES:
        for p in cavity:
            lab[p] = 0
    assert lab[13, 13, 20] == 1 and lab[13, 13, 22] == 0
    return label_surfaces(lab, affine=np.diag([*SPACING, 1.0]))


def component_volumes(surfaces: SurfaceSet, vertices=None):
    """Per label value: the signed volume (mm³) of each component of its shell, as
    ``SurfaceSet.shell`` + ``face_components`` define them, at ``vertices`` (default: the set's)."""
    moved = surfaces if vertices is None else surfaces.copy_with_vertices(vertices)
    out = {}
    for value, shell in zip(surfaces.values(), moved.shells()):
        n, lab = face_components(shell.faces, shell.n_vertices)
        v = shell.vertices.astype(np.float64)
        out[value] = np.array([signed_volume(v, shell.faces[lab == c]) for c in range(n)])
    return out


def voxel_volume(surfaces):
    return abs(np.linalg.det(surfaces.affine[:3, :3]))


def assert_within_bound(raw, smoothed, bound=BOUND):
    before, after = component_volumes(raw), component_volumes(smoothed)
    vox = voxel_volume(raw)
    for value in before:
        assert before[value].size == after[value].size
        change = np.abs(after[value] - before[value])
        assert np.all(change <= bound * np.abs(before[value]) + 1e-6 * vox), value
        assert np.all(np.abs(after[value]) >= 0.1 * vox), value  # no sliver, no closed cavity


def test_the_phantom_has_the_components_it_was_built_with(phantom):
    vols = component_volumes(phantom)
    vox = voxel_volume(phantom)
    ones = np.sort(np.round(vols[1] / vox).astype(int))
    # 3 cavities (the label-2 speck, 1 and 2 voxels), 4 specks, 2 edge-touching specks, the ball
    assert ones[:3].tolist() == [-2, -1, -1] and ones[3:9].tolist() == [1] * 6
    assert ones.size == 10 and ones[-1] > 1000
    assert np.sort(np.round(vols[2] / vox)).tolist() == [1, 1]


def test_without_the_guard_specks_become_slivers_and_cavities_close(phantom):
    """The failure the guard exists for: the volume step alone restores each label's total."""
    sm, rep = smooth_surfaces(phantom, distances=False, component_bound_pct=None)
    before, after, vox = component_volumes(phantom), component_volumes(sm), voxel_volume(phantom)
    assert "blended_components" not in rep.params
    outside = sum(int(np.sum(np.abs(after[k] - before[k]) > BOUND * np.abs(before[k])))
                  for k in before)
    assert outside >= 8  # specks, the edge pair, cavities
    assert sum(int(np.sum(np.abs(v) < 0.1 * vox)) for v in after.values()) >= 3


def test_default_smoothing_keeps_every_component_within_the_bound(phantom):
    sm, rep = smooth_surfaces(phantom, distances=False)
    assert_within_bound(phantom, sm)
    p = rep.params
    assert p["component_bound_pct"] == 100 * BOUND
    assert p["restored_components"] + p["blended_components"] >= 4
    # every shell closed and manifold, seams shared: a vertex of both labels' shells is one
    # position of the set, in both
    for shell in sm.shells():
        t = topology(shell.vertices, shell.faces)
        assert t.closed and t.manifold and t.oriented and t.degenerate_faces == 0
    one, two = sm.shell(1), sm.shell(2)
    common, i1, i2 = np.intersect1d(one.meta["vertex_ids"], two.meta["vertex_ids"],
                                    return_indices=True)
    assert common.size >= 8  # the speck on the surface and the one inside share corners
    np.testing.assert_array_equal(one.vertices[i1], two.vertices[i2])
    np.testing.assert_array_equal(one.vertices[i1], sm.vertices[common])


def test_every_vertex_stays_in_its_voxel_cell(phantom):
    sm, _ = smooth_surfaces(phantom, distances=False)
    A = phantom.affine
    centre = (phantom.lattice - 0.5) @ A[:3, :3].T + A[:3, 3]
    u = np.linalg.solve(A[:3, :3], (sm.vertices.astype(np.float64) - centre).T).T
    assert np.abs(u).max() <= 0.5 + 1e-4


def test_the_components_found_on_the_set_are_those_of_the_shell_views(phantom):
    """shell_component_sides (on the shared faces, split copies as vertices of their own) gives
    each label's shell the components face_components finds on SurfaceSet.shell."""
    raw61 = label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))
    for surfaces in (phantom, raw61):
        s = MeshStructure(surfaces.faces, surfaces.n_vertices)
        guard = ComponentGuard(surfaces, surfaces.vertices.astype(np.float64), s)
        sides, n = shell_component_sides(surfaces, s)
        assert n == guard.n and sum(v.size for v in component_volumes(surfaces).values()) == n
        label_of = np.empty(n, np.int64)
        label_of[sides[sides >= 0]] = surfaces.face_labels[sides >= 0]
        for value, vols in component_volumes(surfaces).items():
            np.testing.assert_allclose(np.sort(guard.targets[label_of == value]), np.sort(vols),
                                       rtol=1e-9, atol=1e-6)
    assert len(raw61.splits) > 0  # the real map has pinch copies


def test_components_the_restore_cannot_move_are_blended_back(phantom):
    """With a zero gain the volume step cannot move a vertex: a collapsed speck then goes back
    toward its unsmoothed positions until it is within half the bound."""
    rest = phantom.vertices.astype(np.float64)
    s = MeshStructure(phantom.faces, phantom.n_vertices)
    guard = ComponentGuard(phantom, rest, s)
    vox = voxel_volume(phantom)
    corners = np.flatnonzero(np.all((phantom.lattice >= 2) & (phantom.lattice <= 3), axis=1))
    assert corners.size == 8  # the speck in voxel (2, 2, 2)
    speck = int(guard.sides[np.isin(phantom.faces, corners).all(axis=1)][0, 0])
    assert abs(guard.targets[speck] - vox) < 1e-6 * vox
    pos = rest.copy()
    pos[corners] = 0.9 * rest[corners].mean(axis=0) + 0.1 * rest[corners]  # 0.1 % of a voxel
    assert speck in guard.failing(pos, BOUND)
    cons = Constraint().arrays(rest)
    outside, blended = guard.guard(pos, cons, np.zeros(len(rest)), BOUND)
    assert blended == {speck} and outside == {speck}
    v = guard.volumes(pos)
    assert guard.failing(pos, BOUND).size == 0
    assert abs(v[speck] - vox) <= 0.5 * BOUND * vox + 1e-9
    assert np.array_equal(pos[np.setdiff1d(np.arange(len(pos)), corners)],
                          rest[np.setdiff1d(np.arange(len(pos)), corners)])


def test_independent_surfaces_keep_each_closed_component_within_the_bound(phantom):
    """A set of independent surfaces (no lattice): the guard holds their closed components."""
    meshes = phantom.shells()
    iso = SurfaceSet.from_meshes(meshes, phantom.affine, phantom.space)
    sm, rep = smooth_surfaces(iso, distances=False)
    assert rep.params["component_bound_pct"] == 100 * BOUND
    assert_within_bound(iso, sm)


def test_the_bound_is_checked_and_can_be_turned_off(phantom):
    with pytest.raises(AnatomeshError, match="component_bound_pct"):
        smooth_surfaces(phantom, component_bound_pct=0)
    with pytest.raises(AnatomeshError, match="component_bound_pct"):
        SmoothingSession(phantom).run(component_bound_pct=150)
    tight, rep = smooth_surfaces(phantom, distances=False, component_bound_pct=2.0)
    assert rep.params["component_bound_pct"] == 2.0
    assert_within_bound(phantom, tight, bound=0.02)
    _, plain = smooth_surfaces(phantom, "light", distances=False)  # no volume step: no guard
    assert "component_bound_pct" not in plain.params


def test_real_map_keeps_every_component_above_a_tenth_of_a_voxel():
    """The 61-label TotalSegmentator map (3 mm voxels): specks of single voxels and one-voxel
    cavities keep their volume within the bound."""
    raw = label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))
    sm, rep = smooth_surfaces(raw, measure=False)
    assert_within_bound(raw, sm)
    assert rep.params["restored_components"] > 0


def test_components_untangling_moved_out_of_the_bound_are_blended_back(phantom):
    """After untangling (which pulls vertices toward their unsmoothed positions) the session
    checks the components again: one outside the bound is blended back, crossing nothing."""
    from anatomesh.core.geometry.intersections import self_intersections

    session = SmoothingSession(phantom)
    out = session.run()[0]
    corners = np.flatnonzero(np.all((phantom.lattice >= 2) & (phantom.lattice <= 3), axis=1))
    rest = phantom.vertices.astype(np.float64)
    out[corners] = 0.9 * rest[corners].mean(axis=0) + 0.1 * rest[corners]
    blended = set()
    out, _ = session._components_after_untangling(out, None, BOUND, blended)
    guard = session.components()
    assert len(blended) == 1 and guard.failing(out, BOUND).size == 0
    assert_within_bound(phantom, phantom.copy_with_vertices(out))
    assert len(self_intersections(out, phantom.faces)) == 0
