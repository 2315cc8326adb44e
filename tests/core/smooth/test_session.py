"""SmoothingSession: cached re-smoothing equals fresh smoothing; the default's quality on the 61-label
map; float32 live smoothing; fast report distances against the exact ones; independent surfaces."""
import numpy as np
import pytest

from anatomesh.core import load
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry import measure as M
from anatomesh.core.geometry.intersections import self_intersections
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.surfaceset import SurfaceSet
from anatomesh.core.smooth.driver import SmoothingSession, smooth_mesh, smooth_surfaces
from conftest import shared


@pytest.fixture(scope="module")
def map61():
    return label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))


@pytest.fixture(scope="module")
def map41():
    return label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))


def cell_offsets(ss, vertices):
    """Offset of each vertex from its cell centre in voxel units (|u| <= 0.5: inside)."""
    A = ss.affine
    centre = (ss.lattice - 0.5) @ A[:3, :3].T + A[:3, 3]
    return np.linalg.solve(A[:3, :3], (np.asarray(vertices, np.float64) - centre).T).T


def test_a_session_smooths_again_exactly_as_fresh_calls(map41):
    session = SmoothingSession(map41)
    settings = [dict(), dict(method="organ", iterations=30, lam=0.6, mu=-0.63, max_deviation=1.2),
                dict(method="light", damping_distance=4.0, staircase=False), dict()]
    for kw in settings:
        method = kw.pop("method", "organ")
        again, rep = session.smooth(method, **kw)
        fresh, ref = smooth_surfaces(map41, method, **kw)
        np.testing.assert_array_equal(again.vertices, fresh.vertices)
        assert rep.params == ref.params and rep.shells == ref.shells
        assert rep.warnings == ref.warnings
    assert not np.array_equal(session.run("organ")[0], session.run("light")[0])
    assert np.array_equal(map41.vertices, label_surfaces(load(shared(
        "totalsegmentator", "example_seg.nii.gz"))).vertices)  # the input is never modified


def test_a_one_shot_run_frees_each_steps_caches_and_gives_the_same_surfaces(map41):
    """keep=False (the CLI's driver): the passes' buffers and rings, junction groups, volume
    regions, cell boxes and face buckets are gone after the run (memory: the peak is the
    largest step's), the surfaces and report are those of a session that keeps them."""
    kept, kept_rep = SmoothingSession(map41).smooth("organ")
    session = SmoothingSession(map41)
    once, rep = session.smooth("organ", keep=False)
    np.testing.assert_array_equal(once.vertices, kept.vertices)
    assert rep.shells == kept_rep.shells and rep.params == kept_rep.params
    assert not {"boxes", "regions", "groups", "components"} & set(session._cache)
    assert not [k for k in session._cache if isinstance(k, tuple) and k[0] == "cell"]
    s = session.structure
    assert not s._padded and not s._buffers and not s._feature
    assert s._ring is None  # a label map's one-shot run needs its 1-ring only for the passes
    again, _ = session.smooth("organ")  # rebuilt on demand
    np.testing.assert_array_equal(again.vertices, kept.vertices)


def test_passes_that_keep_no_buffers_give_the_same_positions_and_leave_none(map41):
    """taubin(keep_buffers=False), as a one-shot run calls it: bit for bit the positions of the
    default call, and the structure keeps no padded columns, feature rings, buffers or 1-ring
    (the rings are freed before the passes run, the buffers before the result is made)."""
    from anatomesh.core.geometry.neighbors import MeshStructure
    from anatomesh.core.smooth.filters import taubin
    from anatomesh.core.smooth.session import face_groups_of

    groups = face_groups_of(map41.face_labels)
    kept = MeshStructure(map41.faces, map41.n_vertices)
    want = taubin(map41.vertices, map41.faces, structure=kept, face_groups=groups)
    assert kept._padded and kept._buffers and kept._feature
    s = MeshStructure(map41.faces, map41.n_vertices)
    got = taubin(map41.vertices, map41.faces, structure=s, face_groups=groups,
                 keep_buffers=False)
    np.testing.assert_array_equal(got, want)
    assert not s._padded and not s._buffers and not s._feature and s._ring is None


def test_the_report_sums_faces_a_block_at_a_time_and_the_block_changes_nothing(map61, monkeypatch):
    """The per-shell measures are summed in face order, a block of faces at a time (memory):
    the 61-label map's (381 k faces, six blocks) are the same bit for bit with blocks of 999
    faces."""
    from anatomesh.core.smooth import shell_measures

    assert map61.n_faces > 5 * shell_measures._BLOCK  # six blocks by default
    vertices, _ = SmoothingSession(map61).run("organ", keep=False)
    want, _ = SmoothingSession(map61).measure(vertices)
    monkeypatch.setattr(shell_measures, "_BLOCK", 999)
    got, _ = SmoothingSession(map61).measure(vertices)
    assert got == want and len(want) == 61


def test_default_on_the_61_label_map_keeps_every_guarantee(map61):
    """61/61 shells closed, no face crossing another (inside or between shells), volumes kept
    (median ~0, worst >= -3 %), every vertex in its voxel cell, close to the voxel surface (the
    report's symmetric mean distance to the unsmoothed shells, averaged over shells)."""
    out, rep = smooth_surfaces(map61)
    shells = out.shells()
    assert len(shells) == 61 and all(topology(m.vertices, m.faces).closed for m in shells)
    assert len(self_intersections(out.vertices, out.faces)) == 0
    change = np.array([s["volume_change_pct"] for s in rep.shells.values()])
    assert abs(np.median(change)) < 0.05 and change.min() >= -3.0
    assert np.abs(cell_offsets(map61, out.vertices)).max() <= 0.5
    assert rep.summary()["mean_distance_mm"] <= 0.5
    assert rep.summary()["max_hausdorff_mm"] <= 0.5 * np.sqrt(3) * 3.0  # half the voxel diagonal
    assert rep.params["untangled_vertices"] > 0 and rep.summary()["flipped_faces"] == 0


def test_float32_live_smoothing_stays_near_float64(map41):
    """The sliders' float32 passes: within 1e-3 mm of float64 but where a guard (fold, crossing)
    decided a borderline face the other way — a handful of vertices, still in their cells."""
    session = SmoothingSession(map41)
    for kw in (dict(), dict(lam=0.6, mu=-0.63, iterations=30), dict(max_deviation=1.0)):
        a, info_a = session.run("organ", **kw)
        b, info_b = session.run("organ", precision="float32", **kw)
        d = np.linalg.norm(a.astype(np.float64) - b, axis=1)
        assert np.count_nonzero(d > 1e-3) <= 1e-3 * len(d), kw
        assert np.median(d) < 1e-4 and info_b["params"]["precision"] == "float32"
        assert np.abs(cell_offsets(map41, b)).max() <= 0.5
    filt64, _ = session.run("taubin", constraint="cell", fold_guard=False, untangle=False)
    filt32, _ = session.run("taubin", constraint="cell", fold_guard=False, untangle=False,
                            precision="float32")
    assert np.abs(filt64.astype(np.float64) - filt32).max() < 1e-3  # the filter alone: all


def test_report_distances_agree_with_exact_nearest_triangle_distances(map61):
    """The report's per-shell Hausdorff and mean distance (local samples) against the exact
    symmetric distances over a triangle grid: within 5 % or 0.05 mm on every 5th shell."""
    out, rep = smooth_surfaces(map61)
    before, after = map61.shells(), out.shells()
    for a, b in list(zip(before, after))[::5]:
        exact = M.surface_distance(b.vertices, b.faces, a.vertices, a.faces)
        fast = rep.shells[a.value]
        for key, ref in (("hausdorff_mm", "hausdorff_mm"), ("mean_distance_mm", "mean_mm")):
            assert fast[key] == pytest.approx(exact[ref], rel=0.05, abs=0.05), (a.value, key)
            assert fast[key] >= exact[ref] - 1e-4  # local samples: upper bounds
        slow = M.compare(a.vertices, b.vertices, a.faces, distances=False, curvature=False)
        for key in ("volume_before_mm3", "volume_after_mm3", "area_after_mm2"):
            assert fast[key] == pytest.approx(slow[key], rel=1e-6)
        for key in ("faces", "flipped_faces", "topology_before", "topology_after"):
            assert fast[key] == slow[key]
        assert fast["max_displacement_mm"] == pytest.approx(slow["max_displacement_mm"], abs=1e-6)
        assert fast["quality_after"] == pytest.approx(slow["quality_after"], rel=1e-6)


def test_independent_surfaces_get_voxel_boxes_and_volumes_per_component():
    """Isosurfaces as a set (SurfaceSet.from_meshes): each vertex stays in the voxel box around
    its start, each closed connected piece keeps its volume (a bone isosurface has many), no face
    crosses another that did not before (3 mm voxels: bone and skin come within a voxel), and
    but for untangling between them a surface smoothed in a set equals it smoothed alone."""
    from anatomesh.core.extract import isosurface

    vol = load(shared("totalsegmentator", "example_ct.nii.gz"))
    bone, skin = isosurface(vol, 250.0), isosurface(vol, -300.0)
    surfaces = SurfaceSet.from_meshes([bone, skin], vol.affine)
    session = SmoothingSession(surfaces)
    regions = session.regions()
    assert regions.r > 20  # the bone surface's pieces
    out, rep = session.smooth(distances=False)
    u = np.linalg.solve(vol.affine[:3, :3], (out.vertices - surfaces.vertices).astype(float).T)
    assert np.abs(u).max() <= 0.5 and np.abs(u).max() > 0.3
    pieces = regions.volumes(out.vertices.astype(np.float64))[0]
    big = regions.targets > 1000.0  # mm³
    assert np.abs(pieces[big] / regions.targets[big] - 1).max() < 0.01
    rest = {tuple(p) for p in self_intersections(surfaces.vertices, surfaces.faces)}
    assert {tuple(p) for p in self_intersections(out.vertices, out.faces)} <= rest  # none new
    assert rep.params["untangled_vertices"] > 0
    alone, rep_alone = smooth_mesh(bone, affine=vol.affine, untangle=False, distances=False)
    kept, rep_kept = session.smooth(untangle=False, distances=False)
    np.testing.assert_array_equal(alone.vertices, kept.vertices[:bone.n_vertices])
    assert rep_kept.shells[250] == rep_alone.shells[250]


def test_a_one_shot_run_of_independent_surfaces_builds_its_one_ring_once(monkeypatch):
    """Isosurfaces in a one-shot run: the volume regions (closed components, found from the
    faces) need no 1-ring after the filter frees it, so it is built once; the result is the
    kept session's bit for bit."""
    from anatomesh.core.extract import isosurface
    from anatomesh.core.geometry import neighbors

    vol = load(shared("totalsegmentator", "example_ct.nii.gz"))
    surfaces = SurfaceSet.from_meshes([isosurface(vol, 250.0)], vol.affine)
    kept, _ = SmoothingSession(surfaces).run("organ")
    built = []
    one_ring = neighbors._k.one_ring
    monkeypatch.setattr(neighbors._k, "one_ring", lambda *a: built.append(1) or one_ring(*a))
    neighbors.clear_cache()  # a structure of its own, not the kept session's
    session = SmoothingSession(surfaces)
    once, _ = session.run("organ", keep=False)
    np.testing.assert_array_equal(once, kept)
    assert len(built) == 1 and session.structure._ring is None
