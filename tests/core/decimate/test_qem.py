"""Decimation: error bound in mm against analytic surfaces, topology kept, targets reached,
multi-label seams shared and junctions kept, real TotalSegmentator map."""
import numpy as np
import pytest

from anatomesh.core.decimate.qem import decimate, decimate_mesh, decimate_surfaces
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh
from anatomesh.core.geometry.topology import topology
from conftest import shared
from helpers.meshes import icosphere, torus


def _check_closed(v, f, genus, components=1):
    t = topology(v, f)
    assert t.closed and t.manifold and t.oriented, t
    assert t.genus == genus and t.components == components, t
    assert t.degenerate_faces == 0, t


def _laplacian(v, f, iterations=8, lam=0.5):
    """Plain uniform Laplacian smoothing of a shared mesh (test helper: curved interfaces)."""
    v = v.astype(np.float64)
    e = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    deg = np.maximum(np.bincount(e.ravel(), minlength=len(v)), 1).astype(float)[:, None]
    for _ in range(iterations):
        s = np.zeros_like(v)
        np.add.at(s, e[:, 0], v[e[:, 1]])
        np.add.at(s, e[:, 1], v[e[:, 0]])
        v = v + lam * (s / deg - v)
    return v.astype(np.float32)


def _shell_faces(f, fl, value):
    return np.concatenate([f[fl[:, 0] == value], f[fl[:, 1] == value][:, ::-1]])


# ---------------------------------------------------------------------------------------------
# analytic shapes
# ---------------------------------------------------------------------------------------------
def test_sphere_max_error_is_honoured_against_the_analytic_sphere():
    r, bound = 10.0, 0.05
    v, f = icosphere(5, r)                       # 20480 faces, vertices exactly on the sphere
    vin = v[f].mean(axis=1)
    input_dev = float(np.abs(np.linalg.norm(vin, axis=1) - r).max())   # chord sag of the input
    nv, nf, fl, info = decimate(v, f, max_error=bound)
    assert fl is None
    _check_closed(nv, nf, genus=0)
    assert info["faces_after"] == len(nf) < 0.5 * len(f)          # it really decimated
    assert info["error_bound_met"] and info["hausdorff_mm"] <= bound
    pts = np.concatenate([nv, nv[nf].mean(axis=1)])
    assert np.abs(np.linalg.norm(pts, axis=1) - r).max() <= bound + input_dev
    assert abs(info["shells"][None]["volume_change_pct"]) < 1.0


def test_torus_ratio_keeps_genus_and_reaches_the_count():
    v, f = torus(30.0, 10.0, 200, 100)          # 40000 faces, genus 1
    seen = []
    nv, nf, _, info = decimate(v, f, ratio=0.05, progress=lambda x, text: seen.append(x))
    assert abs(len(nf) - 2000) <= 2 and info["target_met"]
    assert len(seen) > 3 and seen[-1] == 1.0 and np.all(np.diff(seen) >= 0)
    _check_closed(nv, nf, genus=1)
    # against the analytic torus: distance to the tube centre circle minus the tube radius
    pts = np.concatenate([nv, nv[nf].mean(axis=1)]).astype(np.float64)
    ring = np.hypot(pts[:, 0], pts[:, 1]) - 30.0
    dev = np.abs(np.hypot(ring, pts[:, 2]) - 10.0)
    assert dev.max() < 1.5 and info["hausdorff_mm"] < 1.5


def test_target_faces_flat_regions_reduce_more_than_curved_ones():
    # a sphere flattened on one side: the flat cap must end up with far fewer vertices
    v, f = icosphere(5, 10.0)
    v = v.copy()
    v[:, 2] = np.minimum(v[:, 2], 5.0)
    nv, nf, _, info = decimate(v, f, target_faces=2000)
    assert abs(len(nf) - 2000) <= 2
    _check_closed(nv, nf, genus=0)
    flat_in = np.mean(v[:, 2] >= 5.0 - 1e-6)
    flat_out = np.mean(nv[:, 2] >= 5.0 - 1e-4)
    assert flat_out < 0.5 * flat_in


def test_locked_vertices_do_not_move_and_result_is_deterministic():
    v, f = icosphere(4, 5.0)
    locked = np.arange(0, len(v), 7)
    a = decimate(v, f, ratio=0.2, locked=locked, measure=False)
    b = decimate(v, f, ratio=0.2, locked=locked, measure=False)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    ids = a[3]["vertex_ids"]
    assert set(locked) <= set(ids.tolist())
    kept = np.searchsorted(ids, locked)
    assert np.array_equal(a[0][kept], v[locked].astype(np.float32))


def test_triangle_quality_and_orientation_kept_on_a_sphere():
    # the guards: no sliver below min_quality (the input has none), no face turned inside out
    v, f = icosphere(5, 10.0)
    nv, nf, _, info = decimate(v, f, ratio=0.03, measure=False)
    _check_closed(nv, nf, genus=0)
    p = nv[nf].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    l2 = sum(np.einsum("ij,ij->i", p[:, i] - p[:, j], p[:, i] - p[:, j]) for i, j in ((0, 1), (1, 2), (2, 0)))
    quality = 2 * np.sqrt(3) * np.linalg.norm(n, axis=1) / l2
    assert quality.min() >= 0.05
    assert np.all(np.einsum("ij,ij->i", n, p.mean(axis=1)) > 0)


def test_open_grid_boundary_simplified_and_kept_on_the_border():
    # a flat 60 x 60 square: interior edges are stored once, boundary edges must still collapse
    n = 61
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float), indexing="ij")
    v = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    f = np.concatenate([np.c_[a, a + n, a + n + 1], np.c_[a, a + n + 1, a + 1]]).astype(np.int32)
    nv, nf, _, info = decimate(v, f, ratio=0.05, measure=False)
    t0, t1 = topology(v, f), topology(nv, nf)
    assert t1.manifold and t1.oriented and t1.components == 1 and t1.boundary_edges > 0
    assert t1.boundary_edges < 0.5 * t0.boundary_edges and len(nf) <= 0.05 * len(f) + 2
    border = (nv[:, 0] == 0) | (nv[:, 0] == 60) | (nv[:, 1] == 0) | (nv[:, 1] == 60)
    e = np.sort(np.concatenate([nf[:, [0, 1]], nf[:, [1, 2]], nf[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    assert np.all(border[uniq[count == 1].ravel()])            # open edges stay on the border
    assert np.all(nv[:, 2] == 0) and nv[:, :2].min() == 0 and nv[:, :2].max() == 60
    area_z = np.cross(nv[nf[:, 1]] - nv[nf[:, 0]], nv[nf[:, 2]] - nv[nf[:, 0]])[:, 2] / 2
    assert np.all(area_z > 0) and abs(area_z.sum() - 3600) < 1e-3      # all up, square covered


def test_decimate_mesh_wrapper():
    v, f = icosphere(3, 2.0)
    mesh = Mesh(v, f, name="ball", value=1)
    out, rep = decimate_mesh(mesh, ratio=0.5)
    assert isinstance(out, Mesh) and out.name == "ball" and out.n_faces == 640
    assert "vertex_ids" not in rep and rep["faces_before"] == 1280


def test_set_of_independent_surfaces_rebuilt_without_lattice():
    # SurfaceSet.from_meshes: no lattice, shell values (isovalues) kept, each shell closed
    from anatomesh.core.model.surfaceset import SurfaceSet

    a, fa = icosphere(4, 5.0)                                   # 5120 faces, genus 0
    b, fb = torus(30.0, 10.0, 80, 40)                           # 6400 faces, genus 1
    ss = SurfaceSet.from_meshes([Mesh(a, fa, name="ball", value=100.0),
                                 Mesh(b, fb, name="ring", value=250.0)], np.eye(4))
    out, rep = decimate_surfaces(ss, ratio=0.2)
    assert rep["target_met"] and rep["faces_after"] <= 0.2 * ss.n_faces + 2
    assert out.lattice is None and out.shell_values == {1: 100.0, 2: 250.0}
    assert set(rep["shells"]) == {1, 2}
    for shell, genus, name in zip(out.shells(), (0, 1), ("ball", "ring")):
        assert shell.name == name
        _check_closed(shell.vertices, shell.faces, genus=genus)
    assert [s.value for s in out.shells()] == [100.0, 250.0]


def test_decimate_surfaces_takes_a_surface_set_only():
    v, f = icosphere(2, 1.0)
    with pytest.raises(AnatomeshError, match="decimate_mesh"):
        decimate_surfaces(Mesh(v, f), ratio=0.5)
    with pytest.raises(AnatomeshError, match="decimate_surfaces"):
        decimate_mesh((v, f), ratio=0.5)


@pytest.mark.parametrize("kwargs, words", [
    (dict(ratio=0.0), "ratio"), (dict(ratio=1.5), "ratio"), (dict(), "exactly one"),
    (dict(ratio=0.5, target_faces=10), "exactly one"),
    (dict(ratio=0.5, max_error={1: 1.0}), "one number"), (dict(max_error=-1.0), "max_error"),
    (dict(target_faces=10.5), "target_faces"), (dict(ratio={1: 0.5}), "face_labels"),
    (dict(ratio=0.5, face_labels=np.zeros((3, 2), int)), "face_labels"),
    (dict(ratio=0.5, locked=np.array([10 ** 6])), "locked"),
])
def test_bad_parameters_raise_clear_errors(kwargs, words):
    v, f = icosphere(1, 1.0)
    with pytest.raises(AnatomeshError, match=words):
        decimate(v, f, **kwargs)


# ---------------------------------------------------------------------------------------------
# multi-label: shared seams, closed shells, junction curves
# ---------------------------------------------------------------------------------------------
def _three_labels():
    """Three touching blocks (labels 1, 2, 3) in a 1 mm grid with junction curves where all
    three and the background meet, smoothed so that interfaces and junctions are curved."""
    from anatomesh.core.extract.multilabel import label_surfaces

    a = np.zeros((26, 22, 20), np.uint8)
    a[3:13, 3:19, 3:17] = 1
    a[13:23, 3:19, 3:10] = 2
    a[13:23, 3:19, 10:17] = 3
    a[8:18, 8:14, 8:12] = 2                     # 2 pokes into 1 and 3: more junctions
    ss = label_surfaces(a, affine=np.eye(4))
    return ss.copy_with_vertices(_laplacian(ss.vertices, ss.faces, iterations=6))


def _junction_edges(v, f, fl):
    """Edges whose faces carry 3+ labels, as (K, 2, 3) segments."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    lab = np.repeat(fl[None], 3, axis=0).reshape(-1, 2)
    e = np.sort(e, axis=1)
    key = e[:, 0].astype(np.int64) * len(v) + e[:, 1]
    out = []
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    for s, t in zip(starts, np.r_[starts[1:], len(ks)]):
        if len(np.unique(lab[order[s:t]])) >= 3:
            out.append(e[order[s]])
    return np.array(out)


def _dist_to_segments(p, a, b):
    d = b - a
    t = np.clip(np.einsum("pkj,kj->pk", p[:, None, :] - a[None], d) / np.einsum("kj,kj->k", d, d), 0, 1)
    q = a[None] + t[..., None] * d[None]
    return np.linalg.norm(p[:, None, :] - q, axis=2).min(axis=1)


def test_multilabel_shells_closed_seams_shared_junctions_on_curve():
    ss = _three_labels()
    before = {x: topology(s.vertices, s.faces) for x, s in zip(ss.values(), ss.shells())}
    out, rep = decimate_surfaces(ss, max_error=0.25)
    assert rep["faces_after"] < 0.5 * rep["faces_before"]
    assert rep["error_bound_met"] and all(s["hausdorff_mm"] <= 0.25 for s in rep["shells"].values())
    assert set(rep["shells"]) == {1, 2, 3}                     # background not reported
    for value, shell in zip(out.values(), out.shells()):      # the SurfaceSet's own shell views
        t0 = before[value]
        _check_closed(shell.vertices, shell.faces, genus=t0.genus, components=t0.components)
    # seams: an interface face is stored once, so both shells use the very same vertices
    for lo, hi, _ in out.interfaces():
        s_lo, s_hi = out.shell(lo), out.shell(hi)
        seam = out.faces[((out.face_labels[:, 0] == lo) & (out.face_labels[:, 1] == hi))
                         | ((out.face_labels[:, 0] == hi) & (out.face_labels[:, 1] == lo))]
        pts = {tuple(p) for p in out.vertices[np.unique(seam)].tolist()}
        assert pts <= {tuple(p) for p in s_lo.vertices.tolist()}
        assert pts <= {tuple(p) for p in s_hi.vertices.tolist()}
    # junction vertices of the result lie on the original junction polyline
    seg0 = _junction_edges(ss.vertices.astype(np.float64), ss.faces, ss.face_labels)
    seg1 = _junction_edges(out.vertices.astype(np.float64), out.faces, out.face_labels)
    assert len(seg1) < len(seg0)                              # junction curves were simplified
    jv = out.vertices[np.unique(seg1)].astype(np.float64)
    a, b = ss.vertices[seg0[:, 0]].astype(np.float64), ss.vertices[seg0[:, 1]].astype(np.float64)
    assert _dist_to_segments(jv, a, b).max() < 1e-4


def test_multilabel_per_label_ratio_budgets_the_listed_label():
    ss = _three_labels()
    counts0 = {x: int(np.count_nonzero((ss.face_labels == x).any(axis=1))) for x in (1, 2, 3)}
    out, rep = decimate_surfaces(ss, ratio={1: 0.2}, measure=False)
    counts1 = {x: int(np.count_nonzero((out.face_labels == x).any(axis=1))) for x in (1, 2, 3)}
    assert counts1[1] <= 0.2 * counts0[1] + 4
    # unlisted labels only change next to label 1 (2|3 seams and far-away parts stay)
    assert counts1[2] > 0.6 * counts0[2] and counts1[3] > 0.6 * counts0[3]
    seam23 = lambda s: int(np.count_nonzero(np.isin(s.face_labels, [2, 3]).all(axis=1)))
    assert seam23(out) > 0.8 * seam23(ss)


# ---------------------------------------------------------------------------------------------
# small shells: the ratio within the error cap (pymeshlab as the oracle)
# ---------------------------------------------------------------------------------------------
def _phantom(hollow):
    """Voxel phantoms (1.5 mm voxels) extracted and smoothed with the default preset: a ball of
    radius 4.3 voxels (label 1, 732 faces) or a shell (label 1, outer radius 8 voxels) around a
    core (label 2, radius 4.5 voxels): 3,192 faces, 828 of them the 1|2 seam."""
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.smooth.driver import smooth_surfaces

    n = 22 if hollow else 14
    c = (n - 1) / 2 + 0.5
    z, y, x = np.mgrid[:n, :n, :n]
    d = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2)
    a = np.zeros((n, n, n), np.uint8)
    a[d <= (8.0 if hollow else 4.3)] = 1
    if hollow:
        a[d <= 4.5] = 2
    ss, _ = smooth_surfaces(label_surfaces(a, affine=np.diag([1.5, 1.5, 1.5, 1.0])))
    return ss


def _pymeshlab_hausdorff(ms, a, b, samples):
    """Symmetric Hausdorff distance between meshes a and b of a pymeshlab MeshSet (dense
    vertex, edge and face samples)."""
    h = [ms.get_hausdorff_distance(sampledmesh=i, targetmesh=j, samplevert=True, sampleedge=True,
                                   sampleface=True, samplenum=samples)["max"]
         for i, j in ((a, b), (b, a))]
    return max(h)


@pytest.mark.parametrize("hollow", [False, True], ids=["ball", "shell_around_core"])
def test_small_shells_reach_ten_percent_within_the_default_cap(hollow):
    """``--decimate 0.1`` (ratio 0.1, cap one 1.5 mm voxel) stopped small shells at
    12-16 % (28-29 % in the issue): the cap was checked on sqrt(quadric cost), which grows with
    the number of planes merged (4-6x the true distance here). pymeshlab's topology-preserving
    quadric collapse reaches 10 % on the same shells, closed, same genus, within the cap."""
    import pymeshlab

    ss = _phantom(hollow)
    assert ss.n_faces == (3192 if hollow else 732)
    before = {x: topology(s.vertices, s.faces) for x, s in zip(ss.values(), ss.shells())}
    out, rep = decimate_surfaces(ss, ratio=0.1, max_error=1.5)
    assert rep["target_met"] and rep["faces_after"] <= 0.105 * rep["faces_before"]
    assert rep["error_bound_met"] and rep["attempts"] == 1 and rep["hausdorff_mm"] <= 1.5
    for value, shell in zip(out.values(), out.shells()):
        t0 = before[value]
        _check_closed(shell.vertices, shell.faces, genus=t0.genus, components=t0.components)
    # seams shared: the 1|2 interface faces are the very same triangles in both shells
    if hollow:
        seam = out.faces[np.isin(out.face_labels, [1, 2]).all(axis=1)]
        assert len(seam) > 0
        key = lambda v, f: {tuple(sorted(map(tuple, v[t].tolist()))) for t in f}
        tri = [key(s.vertices, s.faces) for s in out.shells()]
        assert key(out.vertices, seam) == tri[0] & tri[1]
    for value, s0, s1 in zip(ss.values(), ss.shells(), out.shells()):
        ms = pymeshlab.MeshSet()
        for m in (s0, s1, s0):
            ms.add_mesh(pymeshlab.Mesh(m.vertices.astype(np.float64), m.faces.astype(np.int32)))
        ms.set_current_mesh(2)
        ms.meshing_decimation_quadric_edge_collapse(targetperc=0.1, preservetopology=True)
        pm = ms.current_mesh()
        # the oracle: 10 % is reachable on this shell, closed, same genus, within the cap
        _check_closed(pm.vertex_matrix(), pm.face_matrix(), genus=before[value].genus,
                      components=before[value].components)
        assert pm.face_number() <= 0.105 * s0.n_faces + 2
        assert _pymeshlab_hausdorff(ms, 0, 2, 20 * s0.n_faces) <= 1.5
        # our reported distance, checked independently
        ours, theirs = rep["shells"][value]["hausdorff_mm"], _pymeshlab_hausdorff(ms, 0, 1, 20 * s0.n_faces)
        assert abs(ours - theirs) <= max(0.05, 0.05 * theirs), (value, ours, theirs)


# ---------------------------------------------------------------------------------------------
# real data
# ---------------------------------------------------------------------------------------------
def test_totalsegmentator_map_within_one_voxel():
    """41-label TotalSegmentator map (3 mm voxels), lightly smoothed: with max_error = 3 mm
    (one voxel) at least 75 % of the faces go (measured: 83 %, 4 runs, worst shell 2.99 mm; 71 %
    when the bound was checked on sqrt(quadric cost)), every shell keeps its topology, and the
    measured symmetric Hausdorff distance of every shell stays under 3 mm."""
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.io import load

    ss = label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))
    ss = ss.copy_with_vertices(_laplacian(ss.vertices, ss.faces, iterations=10))
    before = {x: topology(s.vertices, s.faces) for x, s in zip(ss.values(), ss.shells())}
    out, rep = decimate_surfaces(ss, max_error=3.0)
    assert rep["faces_after"] <= 0.25 * rep["faces_before"]
    assert rep["error_bound_met"]
    assert max(s["hausdorff_mm"] for s in rep["shells"].values()) <= 3.0
    for value, shell in zip(out.values(), out.shells()):
        t0 = before[value]
        t1 = topology(shell.vertices, shell.faces)
        assert t1.closed and t1.manifold and t1.oriented, (value, t1)
        assert (t1.genus, t1.components) == (t0.genus, t0.components), value
    assert len(out.splits) == len(ss.splits)          # pinch points untouched


@pytest.mark.parametrize("folder, name", [("pulmonary", "heart.nii.gz"), ("aorta", "aorta.nii.gz")])
def test_totalsegmentator_masks_lose_90_percent_within_one_voxel(folder, name):
    """TotalSegmentator heart and aorta masks (1.5 mm voxels), organ-smoothed: keeping 10 % of
    the faces stays within one voxel (1.5 mm; measured 1.19 mm heart, 0.66 mm aorta), also with
    that voxel as the error cap (as ``--decimate 0.1`` runs it; the cap on sqrt(quadric cost)
    stopped them at 18 % and 12 %)."""
    from anatomesh.core import label_surfaces, load
    from anatomesh.core.smooth.driver import smooth_surfaces

    ss, _ = smooth_surfaces(label_surfaces(load(shared("totalsegmentator", folder, name))), "organ")
    out, rep = decimate_surfaces(ss, ratio=0.1, max_error=1.5)
    assert rep["target_met"] and rep["faces_after"] <= 0.1 * rep["faces_before"] + 2
    assert rep["error_bound_met"] and rep["attempts"] == 1
    assert rep["hausdorff_mm"] <= 1.5 and rep["mean_mm"] <= 0.3
    for shell in out.shells():
        t = topology(shell.vertices, shell.faces)
        assert t.closed and t.manifold and t.oriented


def test_ratio_with_an_error_cap_stops_short_instead_of_ruining_small_organs():
    """The 61-label map (3 mm voxels): 10 % of the faces is out of reach for its small and thin
    labels (ribs, vessels) within any sane error — alone, the ratio drives a shell 58 mm off. With
    a 3 mm cap the run stops short (target_met False), every shell within the cap, topology kept."""
    from anatomesh.core import label_surfaces, load
    from anatomesh.core.smooth.driver import smooth_surfaces

    ss, _ = smooth_surfaces(label_surfaces(load(shared("totalsegmentator",
                                                       "example_seg_fast_force_split.nii.gz"))), "organ")
    out, rep = decimate_surfaces(ss, ratio=0.1, max_error=3.0)
    assert rep["error_bound_mm"] == 3.0 and rep["error_bound_met"]
    assert not rep["target_met"] and rep["faces_after"] < 0.5 * rep["faces_before"]
    assert all(s["hausdorff_mm"] <= 3.0 for s in rep["shells"].values())
    for shell in out.shells():
        t = topology(shell.vertices, shell.faces)
        assert t.closed and t.manifold and t.oriented
