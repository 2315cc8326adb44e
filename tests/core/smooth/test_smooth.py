"""Smoothing: each filter against a slow numpy reference, constraints, seams, analytic shapes, real maps."""
import json

import numpy as np
import pytest

from anatomesh.core.geometry import neighbors as N
from anatomesh.core.smooth import driver as S
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.model.mesh import Mesh, signed_volume
from conftest import shared
from helpers.meshes import icosphere, torus

RNG = np.random.default_rng(7)


# ---------------------------------------------------------------------------------------------
# small meshes
# ---------------------------------------------------------------------------------------------
def noisy_sphere(sub=2, noise=0.05, seed=1):
    v, f = icosphere(sub, radius=10.0)
    rng = np.random.default_rng(seed)
    return v + rng.normal(scale=noise * 10 / 2 ** sub, size=v.shape), f


def three_labels(shape=(8, 8, 6)):
    """Labels 1 | 2 / 3 meeting along a straight junction line x = 4, y = 4 (index space)."""
    lab = np.zeros(shape, np.int32)
    lab[1:-1, 1:-1, 1:-1] = 1
    lab[4:-1, 1:4, 1:-1] = 2
    lab[4:-1, 4:-1, 1:-1] = 3
    return lab


def voxel_ball(radius, spacing=(1.0, 1.0, 1.0), centre_offset=0.0):
    sp = np.asarray(spacing, float)
    n = (np.ceil(2 * radius / sp) + 6).astype(int)
    c = (n - 1) / 2 * sp + centre_offset
    pos = np.indices(n).reshape(3, -1).T * sp
    lab = (np.linalg.norm(pos - c, axis=1) < radius).reshape(n).astype(np.int32)
    return lab, np.diag([*sp, 1.0]), c


def voxel_torus(R=9.0, r=3.5):
    n = int(2 * (R + r)) + 6
    pos = np.indices((n, n, int(2 * r) + 6)).reshape(3, -1).T.astype(float)
    c = np.array([(n - 1) / 2, (n - 1) / 2, (int(2 * r) + 5) / 2])
    p = pos - c
    d = np.hypot(np.hypot(p[:, 0], p[:, 1]) - R, p[:, 2])
    return (d < r).reshape(n, n, -1).astype(np.int32), c


def torus_distance(v, c, R, r):
    p = v - c
    return np.abs(np.hypot(np.hypot(p[:, 0], p[:, 1]) - R, p[:, 2]) - r)


# ---------------------------------------------------------------------------------------------
# slow references (plain python / numpy)
# ---------------------------------------------------------------------------------------------
def ref_rings(faces, n):
    rings = [set() for _ in range(n)]
    for a, b, c in faces:
        rings[a] |= {b, c}
        rings[b] |= {a, c}
        rings[c] |= {a, b}
    return [sorted(r) for r in rings]


def ref_feature_rings(faces, n, groups):
    edge_faces = {}
    for fi, (a, b, c) in enumerate(faces):
        for u, w in ((a, b), (b, c), (c, a)):
            edge_faces.setdefault((min(u, w), max(u, w)), []).append(fi)
    rings = ref_rings(faces, n)
    out, kind = [], []
    for i, r in enumerate(rings):
        feat = []
        for j in r:
            fs = edge_faces[(min(i, j), max(i, j))]
            if len(fs) != 2 or len({groups[x] for x in fs}) > 1:
                feat.append(j)
        if not feat:
            out.append(r)
            kind.append(0)
        elif len(feat) == 2:
            out.append(feat)
            kind.append(1)
        else:
            out.append([])
            kind.append(2)
    return out, np.array(kind)


def ref_project(p, center, A3, half, kind, radius, start):
    """Reference constraint: clamp (box) or L1-project by bisection (diamond) in u = A3⁻¹(p − c)/half."""
    p = p.copy()
    if kind != "none":
        u = np.linalg.solve(A3, p - center) / half
        if kind == "box":
            u = np.clip(u, -1, 1)
        elif np.abs(u).sum() > 1:
            lo, hi = 0.0, np.abs(u).max()
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if np.maximum(np.abs(u) - mid, 0).sum() > 1:
                    lo = mid
                else:
                    hi = mid
            u = np.sign(u) * np.maximum(np.abs(u) - hi, 0)
        p = center + A3 @ (u * half)
    if radius is not None:
        d = p - start
        if np.linalg.norm(d) > radius:
            p = start + d * radius / np.linalg.norm(d)
    return p


def ref_umbrella(pos, rings, factor, weights="uniform", gain=None, axis=None, cons=None, w=None):
    out = pos.copy()
    for i, r in enumerate(rings):
        if not r:
            continue
        d = pos[r] - pos[i]
        if w is not None:
            ww = np.array([w[i][j] for j in r])
        elif weights == "uniform":
            ww = np.ones(len(r))
        else:
            ww = 1.0 / np.linalg.norm(d, axis=1)
        if ww.sum() <= 0:
            continue
        step = factor * (ww[:, None] * d).sum(0) / ww.sum()
        if gain is not None:
            step = step * gain[i]
        if axis is not None:
            step = axis @ step
        out[i] = pos[i] + step
        if cons is not None:
            out[i] = ref_project(out[i], *cons(i))
    return out


def ref_cotan(pos, faces, n):
    w = [dict() for _ in range(n)]
    for f in faces:
        for k in range(3):
            i, j, o = f[k], f[(k + 1) % 3], f[(k + 2) % 3]
            a, b = pos[i] - pos[o], pos[j] - pos[o]
            cot = a @ b / np.linalg.norm(np.cross(a, b))
            w[i][j] = w[i].get(j, 0.0) + 0.5 * cot
            w[j][i] = w[j].get(i, 0.0) + 0.5 * cot
    return [{j: max(x, 0.0) for j, x in d.items()} for d in w]


def ref_face_ring(faces, n):
    vf = [[] for _ in range(n)]
    for fi, f in enumerate(faces):
        for v in f:
            vf[v].append(fi)
    return [sorted(set(vf[a]) | set(vf[b]) | set(vf[c])) for a, b, c in faces], vf


def ref_normal_filter(pos, faces, iterations, kind, step):
    fr, vf = ref_face_ring(faces, len(pos))
    p = pos.copy()
    for _ in range(iterations):
        cr = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
        area = 0.5 * np.linalg.norm(cr, axis=1)
        nrm = cr / np.linalg.norm(cr, axis=1)[:, None]
        cen = p[faces].mean(axis=1)
        filt = np.empty_like(nrm)
        for fi, ring in enumerate(fr):
            if kind == "mean":
                m = (area[ring, None] * nrm[ring]).sum(0)
                filt[fi] = m / np.linalg.norm(m)
            else:
                ang = np.arccos(np.clip(nrm[ring] @ nrm[ring].T, -1, 1)).sum(1)
                filt[fi] = nrm[ring[int(np.argmin(ang))]]
        new = p.copy()
        for i in range(len(p)):
            fs = vf[i]
            s = sum(area[f] * filt[f] * (filt[f] @ (cen[f] - p[i])) for f in fs)
            new[i] = p[i] + step * s / area[fs].sum()
        p = new
    return p


def ref_hc(pos, rings, iterations, lam, alpha, beta):
    o = pos.copy()
    p = pos.copy()
    for _ in range(iterations):
        q = p.copy()
        p = q.copy()
        for i, r in enumerate(rings):
            if r:
                p[i] = q[i] + lam * (q[r].mean(0) - q[i])
        b = p - (alpha * o + (1 - alpha) * q)
        new = p.copy()
        for i, r in enumerate(rings):
            if r:
                new[i] = p[i] - (beta * b[i] + (1 - beta) * b[r].mean(0))
            else:
                new[i] = q[i]
        p = new
    return p


# ---------------------------------------------------------------------------------------------
# neighbourhoods
# ---------------------------------------------------------------------------------------------
def csr_rows(offsets, idx):
    return [list(idx[offsets[i]:offsets[i + 1]]) for i in range(len(offsets) - 1)]


def test_rings_match_reference():
    v, f = noisy_sphere()
    s = N.MeshStructure(f, len(v))
    assert csr_rows(s.ring_offsets, s.ring) == ref_rings(f, len(v))
    two = [sorted(set(sum((ref_rings(f, len(v))[j] for j in r), r)) - {i})
           for i, r in enumerate(ref_rings(f, len(v)))]
    assert csr_rows(*s.two_ring()) == two
    fr, vf = ref_face_ring(f, len(v))
    assert csr_rows(*s.face_ring()) == fr
    assert csr_rows(s.vf_offsets, s.vf) == vf
    assert s.valence().sum() == 3 * len(f)  # closed triangle mesh: 2E = 3F


def test_feature_rings_match_reference_on_three_labels():
    ss = label_surfaces(three_labels())
    groups = S.face_groups_of(ss.face_labels)
    offsets, idx, kind = N.structure(ss.faces, ss.n_vertices).feature_ring(groups)
    ref, ref_kind = ref_feature_rings(ss.faces, ss.n_vertices, groups)
    assert csr_rows(offsets, idx) == ref
    assert np.array_equal(kind, ref_kind)
    assert np.count_nonzero(kind == 1) > 10 and np.count_nonzero(kind == 2) > 0


def test_rings_of_a_real_map_match_the_references():
    """The parallel ring kernels (one_ring, feature_rings: every vertex writes its own rows) on
    the 41-label TotalSegmentator map, junctions of 3+ labels and non-manifold seams included."""
    from anatomesh.core.io import load

    ss = label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))
    groups = S.face_groups_of(ss.face_labels)
    s = N.MeshStructure(ss.faces, ss.n_vertices)
    assert csr_rows(s.ring_offsets, s.ring) == ref_rings(ss.faces, ss.n_vertices)
    offsets, idx, kind = s.feature_ring(groups)
    ref, ref_kind = ref_feature_rings(ss.faces, ss.n_vertices, groups)
    assert csr_rows(offsets, idx) == ref and np.array_equal(kind, ref_kind)
    assert np.count_nonzero(kind == 1) > 1000 and np.count_nonzero(kind == 2) > 100
    # the set's (inside, outside) labels as unordered pairs: the same rings, no group table
    swapped = ss.face_labels[:, ::-1].copy()  # unordered: the sides swapped change nothing
    for pairs in (ss.face_labels, swapped, groups.astype(np.int64) + 2**40):  # ids past int32
        p_offsets, p_idx, p_kind = s.feature_ring(pairs)
        assert np.array_equal(p_offsets, offsets) and np.array_equal(p_idx, idx)
        assert np.array_equal(p_kind, kind)
    with pytest.raises(AnatomeshError, match="integer group ids"):
        s.feature_ring(np.zeros((ss.n_faces, 3), np.int32))


def test_structure_is_cached_per_faces_array():
    v, f = noisy_sphere()
    s1 = N.structure(f, len(v))
    assert N.structure(f, len(v)) is s1
    assert N.structure(f.copy(), len(v)) is not s1
    with pytest.raises(AnatomeshError, match="vertices"):
        N.structure(f, 10)


# ---------------------------------------------------------------------------------------------
# filters == references
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("weights", ["uniform", "edge_length"])
def test_laplacian_matches_reference(weights):
    v, f = noisy_sphere()
    rings = ref_rings(f, len(v))
    ref = v.copy()
    for _ in range(4):
        ref = ref_umbrella(ref, rings, 0.6, weights)
    out = S.laplacian(v, f, iterations=4, lam=0.6, weights=weights)
    np.testing.assert_allclose(out, ref, atol=1e-9)


def test_taubin_with_lattice_box_junctions_gain_and_slice_axis_matches_reference():
    aff = np.array([[0.8, 0.1, 0, -20], [0, 0.9, 0, 5], [0, 0, 2.5, 30], [0, 0, 0, 1.0]])
    ss = label_surfaces(three_labels(), affine=aff)
    v, f = ss.vertices.astype(np.float64), ss.faces
    groups = S.face_groups_of(ss.face_labels)
    gain = RNG.uniform(0.3, 1.0, len(v))
    cons = S.lattice_constraint(aff, ss.lattice, half=0.4, max_deviation=0.9)
    rings, _ = ref_feature_rings(f, len(v), groups)
    A3 = aff[:3, :3]
    centre = (ss.lattice - 0.5) @ A3.T + aff[:3, 3]
    np.testing.assert_allclose(cons.center, centre, rtol=0, atol=1e-12)  # the cells' centres, mm
    with pytest.raises(AnatomeshError, match="integer corners"):
        S.lattice_constraint(aff, ss.lattice + 0.25)

    def c(i):
        return centre[i], A3, 0.4, "box", 0.9, v[i]

    axis = aff[:3, 2] / np.linalg.norm(aff[:3, 2])
    ref = np.array([ref_project(v[i], *c(i)) for i in range(len(v))])
    for it in range(3):
        ax = np.outer(axis, axis) if it < 1 else None
        for factor in (0.5, -0.53):
            ref = ref_umbrella(ref, rings, factor, gain=gain, axis=ax, cons=c)
    out = S.taubin(v, f, iterations=2, lam=0.5, mu=-0.53, constraint=cons, gain=gain,
                   face_groups=groups, slice_axis=axis, slice_iterations=1)
    np.testing.assert_allclose(out, ref, atol=1e-6)


def test_diamond_constraint_matches_reference():
    v, f = noisy_sphere()
    cons = S.Constraint(kind="diamond", half=(0.3, 0.2, 0.25))
    rings = ref_rings(f, len(v))

    def c(i):
        return v[i], np.eye(3), np.array([0.3, 0.2, 0.25]), "diamond", None, v[i]

    ref = v.copy()
    for _ in range(5):
        ref = ref_umbrella(ref, rings, 0.9, cons=c)
    out = S.laplacian(v, f, iterations=5, lam=0.9, constraint=cons)
    np.testing.assert_allclose(out, ref, atol=1e-6)
    u = np.abs(out - v) / [0.3, 0.2, 0.25]
    assert u.sum(1).max() <= 1 + 1e-9
    assert u.sum(1).max() > 0.99  # the bound is reached, so the test can fail


def test_hc_matches_reference():
    v, f = noisy_sphere()
    ref = ref_hc(v, ref_rings(f, len(v)), 5, 0.8, 0.1, 0.6)
    np.testing.assert_allclose(S.hc_laplacian(v, f, iterations=5, lam=0.8, alpha=0.1, beta=0.6),
                               ref, atol=1e-9)


def test_mean_curvature_flow_matches_reference():
    v, f = noisy_sphere(noise=0.2)
    ref = v.copy()
    rings = ref_rings(f, len(v))
    for _ in range(3):
        ref = ref_umbrella(ref, rings, 0.5, w=ref_cotan(ref, f, len(v)))
    np.testing.assert_allclose(S.mean_curvature_flow(v, f, iterations=3, step=0.5), ref, atol=1e-9)


@pytest.mark.parametrize("kind", ["mean", "median"])
def test_normal_filter_matches_reference(kind):
    v, f = noisy_sphere(sub=1, noise=0.1)
    ref = ref_normal_filter(v, f, 3, kind, 0.8)
    np.testing.assert_allclose(S.normal_filter(v, f, iterations=3, kind=kind, step=0.8), ref,
                               atol=1e-9)


def test_output_dtype_follows_input_and_input_is_untouched():
    v, f = noisy_sphere()
    v32 = v.astype(np.float32)
    keep = v32.copy()
    out = S.taubin(v32, f)
    assert out.dtype == np.float32 and np.array_equal(v32, keep)
    assert S.taubin(v, f).dtype == np.float64


# ---------------------------------------------------------------------------------------------
# analytic shapes: closer to the true surface, volume kept, bounds held
# ---------------------------------------------------------------------------------------------
def test_voxel_sphere_gets_closer_to_the_true_sphere_and_keeps_its_volume():
    R = 9.0
    lab, aff, c = voxel_ball(R)
    ss = label_surfaces(lab, affine=aff)
    raw = np.abs(np.linalg.norm(ss.vertices - c, axis=1) - R).mean()
    out, rep = S.smooth_surfaces(ss)
    err = np.abs(np.linalg.norm(out.vertices - c, axis=1) - R).mean()
    assert raw > 0.3 and err < 0.35 * raw
    assert abs(rep.shells[1]["volume_change_pct"]) < 0.1
    # every vertex inside its lattice cell (Gibson's box), checked one by one
    assert np.abs(out.vertices - (ss.lattice - 0.5)).max() <= 0.5 + 1e-5
    assert rep.shells[1]["topology_changed"] == [] and rep.shells[1]["flipped_faces"] == 0


def test_voxel_torus_gets_closer_to_the_true_torus_keeping_genus():
    lab, c = voxel_torus()
    ss = label_surfaces(lab)
    raw = torus_distance(ss.vertices, c, 9.0, 3.5).mean()
    out, rep = S.smooth_surfaces(ss)
    assert torus_distance(out.vertices, c, 9.0, 3.5).mean() < 0.45 * raw
    sh = rep.shells[1]
    assert sh["topology_after"]["genus"] == 1 and sh["topology_changed"] == []
    assert abs(sh["volume_change_pct"]) < 0.1


def test_every_filter_improves_a_voxel_sphere_and_respects_the_cell():
    R = 7.0
    lab, aff, c = voxel_ball(R)
    ss = label_surfaces(lab, affine=aff)
    raw = np.abs(np.linalg.norm(ss.vertices - c, axis=1) - R).mean()
    box = S.lattice_constraint(aff, ss.lattice)
    for method in ("laplacian", "taubin", "hc", "mean_curvature", "normal_mean", "normal_median"):
        out = S.smooth(ss.vertices, ss.faces, method, iterations=10, constraint=box)
        err = np.abs(np.linalg.norm(out - c, axis=1) - R).mean()
        assert err < 0.8 * raw, method
        assert np.abs(out - (ss.lattice - 0.5)).max() <= 0.5 + 1e-5, method


def test_isosurface_mesh_stays_in_its_voxel_box_and_keeps_its_volume():
    from anatomesh.core.extract import isosurface

    sp = np.array([0.8, 0.8, 2.0])
    pos = np.indices((30, 30, 14)).reshape(3, -1).T * sp
    data = (9.0 - np.linalg.norm(pos - [12.0, 12.0, 13.0], axis=1)).reshape(30, 30, 14)
    aff = np.diag([*sp, 1.0])
    mesh = isosurface(data, 0.0, affine=aff)
    out, rep = S.smooth_mesh(mesh, affine=aff)
    u = np.abs(out.vertices - mesh.vertices) / sp
    assert u.max() <= 0.5 + 1e-4 and u.max() > 0.05
    sh = rep.shells[0]
    assert abs(sh["volume_change_pct"]) < 0.1 and sh["flipped_faces"] == 0
    assert rep.params["slice_iterations"] > 0  # 2 mm slices, 0.8 mm pixels: staircase passes on


def test_max_deviation_is_a_hard_bound_and_honest_distance_is_reported():
    v, f = torus(nu=40, nv=20)
    v = v + RNG.normal(scale=0.05, size=v.shape)
    out = S.laplacian(v, f, iterations=50, lam=0.9, constraint=S.Constraint(max_deviation=0.07))
    d = np.linalg.norm(out - v, axis=1)
    assert d.max() <= 0.07 + 1e-9 and d.max() > 0.069
    m = Mesh(v, f)
    out2, rep = S.smooth_mesh(m, "laplacian", iterations=50, lam=0.9, max_deviation=0.07)
    assert rep.shells[0]["max_displacement_mm"] <= 0.07 + 1e-6
    assert 0 < rep.shells[0]["hausdorff_mm"] <= 0.07 + 1e-6


def test_laplacian_shrinks_taubin_does_not():
    v, f = icosphere(3, radius=10.0)
    v0 = signed_volume(v, f)
    lap = signed_volume(S.laplacian(v, f, iterations=20, lam=0.5), f)
    tau = signed_volume(S.taubin(v, f, iterations=20), f)
    assert lap < 0.97 * v0
    assert abs(tau - v0) < 0.5 * abs(lap - v0)


def test_thin_tube_keeps_its_volume():
    """A 2.5 mm vessel: vtkSurfaceNets3D's smoothing loses 22 % (38 % on 3 mm slices); ≤ 5 % here."""
    for spacing, n in (((1.0, 1.0, 1.0), (32, 14, 14)), ((1.0, 1.0, 3.0), (32, 14, 5))):
        sp = np.array(spacing)
        n = np.array(n)
        pos = np.indices(n).reshape(3, -1).T * sp
        cc = (n - 1) / 2 * sp
        r = np.hypot(pos[:, 1] - cc[1], pos[:, 2] - cc[2])
        lab = ((r < 1.25) & (pos[:, 0] > 3) & (pos[:, 0] < 27)).reshape(n).astype(np.int32)
        ss = label_surfaces(lab, affine=np.diag([*sp, 1.0]))
        _, rep = S.smooth_surfaces(ss, distances=False)
        assert abs(rep.shells[1]["volume_change_pct"]) <= 5.0, spacing
        _, plain = S.smooth_surfaces(ss, "taubin", distances=False)
        assert plain.shells[1]["volume_change_pct"] < -10.0  # without the volume step it shrinks


def test_staircase_passes_smooth_thick_slices_without_moving_in_plane():
    lab, aff, c = voxel_ball(20.0, spacing=(1.0, 1.0, 5.0))
    ss = label_surfaces(lab, affine=aff)
    params = S.staircase_params(aff, 20)
    assert params["slice_iterations"] > 0 and np.allclose(params["slice_axis"], [0, 0, 1])
    only_z = S.taubin(ss.vertices, ss.faces, iterations=0, slice_axis=params["slice_axis"],
                      slice_iterations=10, constraint=S.lattice_constraint(aff, ss.lattice))
    assert np.array_equal(only_z[:, :2], ss.vertices[:, :2])
    assert np.abs(only_z[:, 2] - ss.vertices[:, 2]).max() > 1.0

    def err(v):
        return np.abs(np.linalg.norm(v - c, axis=1) - 20.0).mean()

    with_stairs, _ = S.smooth_surfaces(ss, measure=False)
    without, _ = S.smooth_surfaces(ss, staircase=False, measure=False)
    assert err(with_stairs.vertices) < 0.9 * err(without.vertices) < 0.6 * err(ss.vertices)
    # each vertex stays in its anisotropic cell: ±0.5 mm in plane, ±2.5 mm across slices
    u = np.abs(with_stairs.vertices - (ss.lattice - 0.5) * [1, 1, 5])
    assert np.all(u <= np.array([0.5, 0.5, 2.5]) + 1e-5)


# ---------------------------------------------------------------------------------------------
# multi-label seams and junctions
# ---------------------------------------------------------------------------------------------
def test_seams_stay_shared_and_junctions_slide_along_their_curve():
    lab = three_labels((10, 10, 8))
    ss = label_surfaces(lab)
    out, rep = S.smooth_surfaces(ss)
    shells = {m.value: m for m in out.shells()}
    # two touching labels: the interface vertices of both shells are the very same positions
    ids1 = shells[1].meta["vertex_ids"]
    ids2 = shells[2].meta["vertex_ids"]
    common = np.intersect1d(ids1, ids2)
    assert common.size > 20
    p1 = dict(zip(ids1.tolist(), shells[1].vertices))
    p2 = dict(zip(ids2.tolist(), shells[2].vertices))
    assert all(np.array_equal(p1[i], p2[i]) for i in common.tolist())
    # the straight junction of labels 1, 2, 3 (x = y = 4.5 - 0.5 in index space) stays straight
    _, _, kind = N.structure(ss.faces, ss.n_vertices).feature_ring(S.face_groups_of(ss.face_labels))
    # (the filter's doing; the volume step may then nudge it by microns)
    line = (kind == 1) & (ss.lattice[:, 0] == 4) & (ss.lattice[:, 1] == 4)
    assert line.sum() >= 4
    filtered, _ = S.smooth_surfaces(ss, preserve_volume=False, measure=False)
    np.testing.assert_allclose(filtered.vertices[line, :2], ss.vertices[line, :2], atol=1e-5)
    loose, _ = S.smooth_surfaces(ss, junctions=False, preserve_volume=False, measure=False)
    assert np.abs(loose.vertices[line, :2] - ss.vertices[line, :2]).max() > 0.05
    np.testing.assert_allclose(out.vertices[line, :2], ss.vertices[line, :2], atol=0.01)
    for value, sh in rep.shells.items():
        assert abs(sh["volume_change_pct"]) < 1.0 and sh["flipped_faces"] == 0, value


def test_distance_gain_matches_brute_force_and_keeps_a_gap():
    v = RNG.uniform(0, 10, (400, 3))
    g = RNG.integers(0, 3, 400)
    gain = S.distance_gain(v, g, 2.0)
    d = np.linalg.norm(v[:, None] - v[None], axis=2)
    d[g[:, None] == g[None]] = np.inf
    np.testing.assert_allclose(gain, np.minimum(d.min(1), 2.0) / 2.0, atol=1e-12)
    # two balls one voxel apart: damping keeps the surfaces from moving where they are close
    lab = np.zeros((26, 14, 14), np.int32)
    pos = np.indices(lab.shape).reshape(3, -1).T
    for cx, value in ((6.5, 1), (17.5, 2)):
        lab.reshape(-1)[np.linalg.norm(pos - [cx, 6.5, 6.5], axis=1) < 5.3] = value
    assert not lab[12].any() and lab[11].any() and lab[13].any()  # a one-voxel gap at x = 12
    ss = label_surfaces(lab)
    free, _ = S.smooth_surfaces(ss, measure=False, preserve_volume=False)
    damped, _ = S.smooth_surfaces(ss, damping_distance=4.0, measure=False, preserve_volume=False)
    near = np.abs(ss.vertices[:, 0] - 12.0) < 1.0
    move_free = np.linalg.norm(free.vertices - ss.vertices, axis=1)[near].mean()
    move_damped = np.linalg.norm(damped.vertices - ss.vertices, axis=1)[near].mean()
    assert move_damped < 0.5 * move_free


# ---------------------------------------------------------------------------------------------
# fold guard and volume restoration
# ---------------------------------------------------------------------------------------------
def test_unfold_undoes_a_fold_and_nothing_else():
    v, f = icosphere(2, radius=5.0)
    bent = v.copy()
    bent[0] = -0.5 * v[0]  # push one vertex through the sphere: its fan folds
    far = int(np.argmax(np.linalg.norm(v - v[0], axis=1)))
    bent[far] += 0.01      # a harmless move elsewhere
    fixed, n = S.unfold(bent, v, f)
    cr0 = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    cr1 = np.cross(fixed[f[:, 1]] - fixed[f[:, 0]], fixed[f[:, 2]] - fixed[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", cr0, cr1) > 0)
    assert n >= 1 and np.array_equal(fixed[far], bent[far])


def test_restore_volumes_gives_each_label_its_volume_back():
    ss = label_surfaces(three_labels((12, 12, 9)))
    shrunk = S.laplacian(ss.vertices, ss.faces, iterations=15, lam=0.6,
                         face_groups=S.face_groups_of(ss.face_labels))
    sides = np.where(ss.face_labels == 0, -1, ss.face_labels - 1)
    target = S.region_volumes(ss.vertices, ss.faces, sides, 3)
    before = S.region_volumes(shrunk, ss.faces, sides, 3)
    assert np.all(np.abs(before / target - 1) > 0.02)
    back = S.restore_volumes(shrunk, ss.faces, sides, target)
    np.testing.assert_allclose(S.region_volumes(back, ss.faces, sides, 3), target, rtol=1e-3)


# ---------------------------------------------------------------------------------------------
# real label maps: the named default
# ---------------------------------------------------------------------------------------------
def test_organ_default_on_totalsegmentator_map():
    from anatomesh.core import load

    vol = load(shared("totalsegmentator", "example_seg.nii.gz"))
    ss = label_surfaces(vol)
    out, rep = S.smooth_surfaces(ss)  # DEFAULT = "organ"
    assert rep.method == "taubin" and S.DEFAULT == "organ"
    names = {v.name: k for k, v in ss.labels.items()}
    for organ in ("liver", "spleen", "kidney_left", "kidney_right", "stomach", "aorta"):
        assert abs(rep.shells[names[organ]]["volume_change_pct"]) <= 1.0, organ
    summary = rep.summary()
    assert summary["flipped_faces"] == 0 and summary["topology_changed"] == []
    json.loads(json.dumps(rep.as_dict()))  # the report goes into the JSON run report as is
    # no vertex leaves its voxel cell: 3 mm voxels, so at most half a voxel diagonal away
    A = ss.affine
    u = (out.vertices - ((ss.lattice - 0.5) @ A[:3, :3].T + A[:3, 3])) @ np.linalg.inv(A[:3, :3]).T
    assert np.abs(u).max() <= 0.5 + 1e-4
    assert summary["max_hausdorff_mm"] <= 0.5 * np.sqrt(3) * 3.0 + 1e-3
    assert 0.2 < summary["mean_distance_mm"] < 1.0
    # smoother: the mean curvature magnitude drops a lot
    from anatomesh.core.geometry.measure import curvature_summary

    assert curvature_summary(out.vertices, out.faces)["mean_abs_H"] < \
        0.5 * curvature_summary(ss.vertices, ss.faces)["mean_abs_H"]


# ---------------------------------------------------------------------------------------------
# the fast path: padded rows, cached buffers, one numba call for all passes
# ---------------------------------------------------------------------------------------------
def spiky_bipyramid(k=13, seed=3):
    """Two apexes of valence k (> the padded width 8) over a k-gon; noisy, closed."""
    t = 2 * np.pi * np.arange(k) / k
    ring = np.c_[5 * np.cos(t), 5 * np.sin(t), np.zeros(k)]
    v = np.vstack([ring, [[0, 0, 4.0], [0, 0, -4.0]]])
    v += np.random.default_rng(seed).normal(scale=0.3, size=v.shape)
    f = [[i, (i + 1) % k, k] for i in range(k)] + [[(i + 1) % k, i, k + 1] for i in range(k)]
    return v, np.array(f, np.int32)


@pytest.mark.parametrize("k", [13, 30])
def test_padded_columns_sum_every_neighbour_through_helper_columns(k):
    """Apexes of valence 13 (a chain of two helper columns) and 30 (a chain of eight): the
    padded columns plus the helper sums give exactly the sum over every 1-ring neighbour."""
    from anatomesh.core.smooth import _pass_kernels as K

    v, f = spiky_bipyramid(k)
    n = len(v)
    s = N.MeshStructure(f, n)
    ring = s.padded(s.ring_offsets, s.ring, 8)
    assert ring.cols.shape == (8, n) and ring.cols.dtype == np.uint32
    chain = 2 if k == 13 else 8  # helpers per apex: 7 in the columns, 3 per helper, 4 in the last
    assert ring.ext.shape[1] == ring.level_at[-1] == 2 * chain and len(ring.level_at) == chain + 1
    P = np.zeros((3, ring.n_columns))
    P[:, :n] = v.T
    K.helper_sums(P, ring.ext, ring.level_at, n)
    sums = P[:, ring.cols].sum(axis=1).T  # (n, 3): padded columns, helpers included
    for i, r in enumerate(csr_rows(s.ring_offsets, s.ring)):
        np.testing.assert_allclose(sums[i], v[r].sum(axis=0), atol=1e-12)
        assert ring.inv_count[i] == pytest.approx(1 / len(r))
        if len(r) <= 8:
            assert list(ring.cols[:len(r), i]) == r and np.all(ring.cols[len(r):, i] == n)
    assert s.padded(s.ring_offsets, s.ring, 8) is s.padded(s.ring_offsets, s.ring, 8)
    assert s.padded(s.ring_offsets, s.ring, 8, np.float32).inv_count.dtype == np.float32
    out = S.laplacian(v, f, iterations=3, lam=0.7)
    ref = v.copy()
    rings = ref_rings(f, n)
    for _ in range(3):
        ref = ref_umbrella(ref, rings, 0.7)
    np.testing.assert_allclose(out, ref, atol=1e-12)


def test_long_rows_oblique_box_and_cap_match_reference():
    """Vertices with more neighbours than the padded width, an oblique box (smoothed in the
    box's frame) and a max_deviation cap: same as the slow reference."""
    v, f = spiky_bipyramid()
    A3 = np.array([[0.9, 0.3, 0.0], [0.0, 1.1, 0.2], [0.1, 0.0, 0.7]])
    cons = S.Constraint("box", frame=np.linalg.inv(A3), half=(0.5, 0.4, 0.6), max_deviation=0.45)
    rings = ref_rings(f, len(v))

    def c(i):
        return v[i], A3, np.array([0.5, 0.4, 0.6]), "box", 0.45, v[i]

    ref = np.array([ref_project(v[i], *c(i)) for i in range(len(v))])
    for _ in range(6):
        for factor in (0.6, -0.63):
            ref = ref_umbrella(ref, rings, factor, cons=c)
    out = S.taubin(v, f, iterations=6, lam=0.6, mu=-0.63, constraint=cons)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    assert np.linalg.norm(out - v, axis=1).max() > 0.44  # the cap binds: the test can fail
    plain = S.laplacian(v, f, iterations=3, lam=0.7)
    ref = v.copy()
    for _ in range(3):
        ref = ref_umbrella(ref, rings, 0.7)
    np.testing.assert_allclose(plain, ref, atol=1e-12)


def test_cached_buffers_do_not_leak_between_calls_and_progress_changes_nothing():
    v, f = noisy_sphere()
    s = N.MeshStructure(f, len(v))
    first = S.taubin(v, f, iterations=5, lam=0.5, structure=s)
    keep = first.copy()
    second = S.taubin(v, f, iterations=5, lam=0.6, mu=-0.64, structure=s)
    np.testing.assert_array_equal(first, keep)  # the result is not a view of a reused buffer
    np.testing.assert_array_equal(S.taubin(v, f, iterations=5, lam=0.5, structure=s), first)
    assert not np.allclose(first, second)
    seen = []
    stepped = S.taubin(v, f, iterations=5, lam=0.6, mu=-0.64, structure=s,
                       progress=lambda x, t: seen.append(x))
    np.testing.assert_array_equal(stepped, second)
    assert seen == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])
    f32 = S.taubin(v.astype(np.float32), f, iterations=5, lam=0.5, structure=s)
    assert f32.dtype == np.float32
    np.testing.assert_allclose(f32, first, atol=1e-4)  # float32 in, float64 inside


def test_parallel_passes_on_a_real_map_match_a_vectorised_reference():
    """The 41-label map (61k vertices: every thread gets a large share) with its lattice box
    and junction curves: same as a numpy reference over the feature-ring CSR (itself checked
    against a python reference above)."""
    from anatomesh.core import load

    ss = label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))
    assert ss.n_vertices > 50000
    v = ss.vertices.astype(np.float64)
    groups = S.face_groups_of(ss.face_labels)
    offsets, idx, _ = N.structure(ss.faces, len(v)).feature_ring(groups)
    A3 = ss.affine[:3, :3]
    centre = (ss.lattice - 0.5) @ A3.T + ss.affine[:3, 3]
    count = np.diff(offsets)
    has = count > 0
    starts = offsets[:-1][has]

    def ref_pass(p, factor):
        sums = np.zeros_like(p)
        sums[has] = np.add.reduceat(p[idx], starts, axis=0)
        new = p.copy()
        new[has] += factor * (sums[has] / count[has, None] - p[has])
        u = np.clip(np.linalg.solve(A3, (new - centre).T).T / 0.45, -1, 1)
        return centre + (u * 0.45) @ A3.T

    ref = v
    for _ in range(3):
        for factor in (0.5, -0.53):
            ref = ref_pass(ref, factor)
    box = S.lattice_constraint(ss.affine, ss.lattice, half=0.45)
    out = S.taubin(v, ss.faces, iterations=3, constraint=box, face_groups=groups)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    assert np.abs(out - v).max() > 0.5  # vertices did move


@pytest.mark.parametrize("half, cap", [(0.45, 0.8), (0.15, None)])
def test_passes_along_one_frame_axis_match_the_general_axis_map(monkeypatch, half, cap):
    """Staircase passes across the slices of an axis-aligned lattice move along one axis of the
    box frame: they gather that coordinate alone and give the positions of the general axis
    map (per-vertex gain, cell box and cap included), on the 41-label map. Without a cap, the
    third and later passes in a row read and write the moving coordinate alone (a small box,
    so that it stops some of them)."""
    from anatomesh.core import load
    from anatomesh.core.smooth import passes

    ss = label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))
    v = ss.vertices.astype(np.float64)
    box = S.lattice_constraint(ss.affine, ss.lattice, half=half, max_deviation=cap)
    axis = ss.affine[:3, 2] / np.linalg.norm(ss.affine[:3, 2])
    kw = dict(iterations=2, constraint=box, gain=RNG.uniform(0.3, 1.0, len(v)), slice_axis=axis,
              slice_iterations=3)
    seen, projector_axis = [], passes._projector_axis
    monkeypatch.setattr(passes, "_projector_axis", lambda a: seen.append(projector_axis(a)) or seen[-1])
    along = S.taubin(v, ss.faces, **kw)
    assert seen == [2]  # the fast path ran
    monkeypatch.setattr(passes, "_projector_axis", lambda a: -1)
    np.testing.assert_allclose(along, S.taubin(v, ss.faces, **kw), rtol=0, atol=1e-12)
    without = S.taubin(v, ss.faces, **dict(kw, slice_iterations=0))
    assert np.abs(along - without).max() > 0.1  # the passes along the axis moved vertices


def test_float32_precision_stays_in_the_box_and_near_float64():
    """The live sliders' float32 arithmetic on the 41-label map (lattice box, junction curves,
    a cap): within 1e-3 mm of float64, inside every voxel cell, the cap kept, seams shared."""
    from anatomesh.core import load

    ss = label_surfaces(load(shared("totalsegmentator", "example_seg.nii.gz")))
    groups = S.face_groups_of(ss.face_labels)
    box = S.lattice_constraint(ss.affine, ss.lattice, max_deviation=0.6)
    kw = dict(iterations=20, lam=0.55, mu=-0.58, constraint=box, face_groups=groups)
    ref = S.taubin(ss.vertices.astype(np.float64), ss.faces, **kw)
    fast = S.taubin(ss.vertices, ss.faces, precision="float32", **kw)
    assert fast.dtype == np.float32
    assert np.abs(fast - ref).max() < 1e-3 and np.abs(ref - ss.vertices).max() > 0.5
    centre = (ss.lattice - 0.5) @ ss.affine[:3, :3].T + ss.affine[:3, 3]
    u = np.linalg.solve(ss.affine[:3, :3], (fast.astype(np.float64) - centre).T)
    assert np.abs(u).max() <= 0.5 + 1e-5  # in its cell, up to float32 rounding of mm
    assert np.linalg.norm(fast - ss.vertices, axis=1).max() <= 0.6 + 1e-4
    with pytest.raises(AnatomeshError, match="precision"):
        S.taubin(ss.vertices, ss.faces, precision="half")


def test_face_groups_are_hashed_once_per_array_and_changes_are_seen():
    ss = label_surfaces(three_labels())
    s = N.structure(ss.faces, ss.n_vertices)
    groups = S.face_groups_of(ss.face_labels)
    a = s.feature_ring(groups)
    assert s.feature_ring(groups) is a
    other = np.arange(len(groups))  # every face its own group: every vertex is a corner
    assert np.all(s.feature_ring(other)[2] == 2)
    other[:] = 0  # edited in place (sampled rows change): seen
    assert np.array_equal(s.feature_ring(other)[2], s.feature_ring(None)[2])
    assert s.feature_ring(groups.copy()) is a  # same content, same rings


# ---------------------------------------------------------------------------------------------
# input errors are one-line AnatomeshErrors
# ---------------------------------------------------------------------------------------------
def test_bad_inputs_raise_anatomesh_errors():
    v, f = noisy_sphere()
    with pytest.raises(AnatomeshError, match="unknown smoothing method"):
        S.smooth(v, f, "wiggle")
    with pytest.raises(AnatomeshError, match="mu"):
        S.taubin(v, f, mu=-0.2)
    with pytest.raises(AnatomeshError, match=r"\(N, 3\)"):
        S.taubin(v[:, :2], f)
    with pytest.raises(AnatomeshError, match="NaN"):
        S.laplacian(np.full_like(v, np.nan), f)
    with pytest.raises(AnatomeshError, match="iterations"):
        S.laplacian(v, f, iterations=2.5)
    with pytest.raises(AnatomeshError, match="gain"):
        S.laplacian(v, f, gain=np.full(len(v), 2.0))
    with pytest.raises(AnatomeshError, match="center"):
        S.laplacian(v, f, constraint=S.Constraint("box", center=np.zeros((3, 3))))
    with pytest.raises(AnatomeshError, match="iterationz"):
        S.smooth(v, f, "taubin", iterationz=3)  # noqa
    with pytest.raises(AnatomeshError, match="needs a SurfaceSet"):
        S.smooth_surfaces((v, f))
    with pytest.raises(AnatomeshError, match="needs a Mesh"):
        S.smooth_mesh((v, f))


def test_a_stronger_lambda_alone_keeps_the_presets_pass_band():
    """λ given without μ to a Taubin preset (the Blender strength slider, `--lambda`): μ follows
    Taubin's pass-band k_pb = 1/λ + 1/μ of the preset, so λ above the preset's |μ| is no error."""
    from anatomesh.core.smooth.presets import resolve

    k_pb = 1 / 0.5 - 1 / 0.53
    for lam in (0.3, 0.55, 0.7):
        _, p = resolve("organ", lam=lam)
        assert p["lam"] == lam and 1 / lam + 1 / p["mu"] == pytest.approx(k_pb) and -1 <= p["mu"] < -lam
    assert resolve("organ", lam=0.5)[1]["mu"] == pytest.approx(-0.53)
    assert resolve("organ", lam=0.6, mu=-0.8)[1]["mu"] == -0.8      # an explicit μ wins
    assert resolve("organ", lam=0.95)[1]["mu"] == -1.0              # the filter's bound
    v, f = icosphere(3, radius=20.0)
    rough = v * (1 + 0.03 * np.sin(7 * v[:, :1]))            # a bumpy sphere
    out = S.smooth(rough, f, "taubin", lam=0.7)               # an error before: μ = −0.53 > −λ
    assert np.all(np.isfinite(out))
    radius = lambda p: np.linalg.norm(p, axis=1)  # noqa: E731
    assert radius(out).std() < 0.5 * radius(rough).std()  # the bumps are smoothed away
    assert radius(out).mean() == pytest.approx(radius(rough).mean(), rel=0.05)  # no shrinking
