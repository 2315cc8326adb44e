"""Levels of detail (progressive mesh from one decimation run): every level is rebuilt bit for bit
as the run held it, keeps each shell closed/manifold with its topology, and seams stay shared."""
import numpy as np
import pytest

from anatomesh.core.decimate import engine, progressive as lod
from anatomesh.core.decimate.qem import decimate
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh
from anatomesh.core.geometry.topology import topology
from conftest import shared
from helpers.meshes import icosphere, torus


def _state_after(obj, final_faces, collapses):
    """The decimation run's own arrays after exactly ``collapses`` collapses (a second run of the
    same decimation, stopped there): (vertices float32 mm, faces, face_labels or None)."""
    fl = None if isinstance(obj, Mesh) else obj.face_labels
    lock = None if isinstance(obj, Mesh) else engine.surface_lock(obj)[0]
    p = engine.prepare(obj.vertices, obj.faces, fl, lock, 60.0, 0.05)
    r = lod.run(p, final_faces, stop_after=collapses)
    assert r.stats["logged"] == collapses
    return (r.v + p.centre).astype(np.float32), r.f, (None if fl is None else p.fl[r.face_ids])


def _closed(v, f, genus, components=1):
    t = topology(v, f)
    assert t.closed and t.manifold and t.oriented and t.degenerate_faces == 0, t
    assert (t.genus, t.components) == (genus, components), t


def test_sphere_levels_are_the_runs_states_bit_for_bit():
    v, f = icosphere(4, 10.0)                                  # 5120 faces
    mesh = Mesh(v, f, name="ball", value=3, color=(1.0, 0.0, 0.0))
    pm = lod.progressive(mesh, levels=4)
    assert pm.n_levels == 4
    faces = pm.faces_per_level
    assert faces[-1] == 5120 and faces[0] < 100 and np.all(np.diff(faces) > 0)
    # geometric spacing between the coarsest and the input
    assert np.allclose(np.diff(np.log(faces)), np.log(5120 / faces[0]) / 3, rtol=0.05)
    # the coarsest level is exactly what decimate() gives for the same run
    nv, nf, _, _ = decimate(mesh.vertices, f, target_faces=0, measure=False)
    m0 = pm.level(0)
    assert np.array_equal(m0.vertices, nv) and np.array_equal(m0.faces, nf)
    assert (m0.name, m0.value, m0.color) == ("ball", 3, (1.0, 0.0, 0.0))
    # intermediate levels: a second run stopped after the same number of collapses
    for k in (1, 2):
        c = int(pm.collapses_per_level[k])
        sv, sf, _ = _state_after(mesh, 0, c)
        mk = pm.level(k)
        assert mk.n_faces == faces[k]
        assert np.array_equal(mk.vertices, sv) and np.array_equal(mk.faces, sf)
    last = pm.level(-1)
    assert np.array_equal(last.vertices, mesh.vertices) and np.array_equal(last.faces, f)
    for m in pm.levels():
        _closed(m.vertices, m.faces, genus=0)


def test_torus_face_ratios_genus_and_error_shrinking_with_level():
    v, f = torus(30.0, 10.0, 200, 100)                         # 40000 faces, genus 1
    pm = lod.progressive(Mesh(v, f), face_ratios=[0.02, 0.1, 0.3])
    assert pm.n_levels == 4
    for target, got in zip([800, 4000, 12000, 40000], pm.faces_per_level):
        assert abs(got - target) <= 2
    errors = []
    for k, m in enumerate(pm.levels()):
        _closed(m.vertices, m.faces, genus=1)
        errors.append(pm.measure(k)[None]["hausdorff_mm"])
        # against the analytic torus (tube radius 10 around the circle of radius 30)
        pts = np.concatenate([m.vertices, m.vertices[m.faces].mean(axis=1)]).astype(np.float64)
        dev = np.abs(np.hypot(np.hypot(pts[:, 0], pts[:, 1]) - 30.0, pts[:, 2]) - 10.0)
        assert dev.max() <= errors[-1] + 0.1
    assert errors[-1] < 1e-6 and errors[0] > errors[1] > errors[2] > 0.0
    assert errors[1] < 1.0                                    # 10 % of a 40k torus: under 1 mm


def test_totalsegmentator_61_labels_every_level_closed_seams_shared():
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.io import load

    ss = label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))
    assert len(ss.values()) == 61
    before = {x: topology(s.vertices, s.faces) for x, s in zip(ss.values(), ss.shells())}
    pm = lod.progressive(ss, levels=3)
    assert pm.n_levels == 3 and pm.faces_per_level[-1] == ss.n_faces
    assert pm.faces_per_level[0] < 0.2 * ss.n_faces          # the floor is far below the input
    last = pm.level(-1)                                       # the input itself
    assert np.array_equal(last.vertices, ss.vertices) and np.array_equal(last.faces, ss.faces)
    for k in range(pm.n_levels - 1):
        lv = pm.level(k)
        assert lv.n_faces == pm.faces_per_level[k] and lv.values() == ss.values()
        assert len(lv.splits) == len(ss.splits)               # pinch points kept
        for value, shell in zip(lv.values(), lv.shells()):
            t0, t1 = before[value], topology(shell.vertices, shell.faces)
            assert t1.closed and t1.manifold and t1.oriented, (k, value, t1)
            assert (t1.genus, t1.components) == (t0.genus, t0.components), (k, value)
            # seams shared: every shell vertex is the set's own vertex, bit for bit
            assert np.array_equal(shell.vertices, lv.vertices[shell.meta["vertex_ids"]])
        # every interface face is stored once (so both neighbouring shells use the same one)
        key = np.sort(lv.faces, axis=1)
        assert len(np.unique(key, axis=0)) == lv.n_faces
    # the middle level is the run's own state after that many collapses
    c = int(pm.collapses_per_level[1])
    sv, sf, sfl = _state_after(ss, 0, c)
    mid = pm.level(1)
    assert np.array_equal(mid.vertices, sv) and np.array_equal(mid.faces, sf)
    assert np.array_equal(mid.face_labels, sfl)
    some = [1, 5, 26, 52, 100]                 # spleen, liver, vertebra S1, aorta, a rib
    shells = pm.measure(1, values=some)
    assert set(shells) == set(some) and all(s["faces_after"] < s["faces_before"] for s in shells.values())
    assert max(s["hausdorff_mm"] for s in shells.values()) < 6.0      # two 3 mm voxels


@pytest.mark.parametrize("kwargs, words", [
    (dict(levels=1), "levels"), (dict(levels=2.5), "levels"), (dict(face_ratios=[0.0]), "face_ratios"),
    (dict(face_ratios=[1.5]), "face_ratios"), (dict(face_ratios=["a"]), "face_ratios"),
    (dict(coarsest=2.0), "coarsest"),
])
def test_bad_parameters_raise_clear_errors(kwargs, words):
    v, f = icosphere(1, 1.0)
    with pytest.raises(AnatomeshError, match=words):
        lod.progressive(Mesh(v, f), **kwargs)


def test_level_index_and_lod_meshes():
    v, f = icosphere(3, 2.0)
    pm = lod.progressive(Mesh(v, f), levels=3, coarsest=0.25)
    assert abs(pm.faces_per_level[0] - 320) <= 2
    with pytest.raises(AnatomeshError, match="level 3"):
        pm.level(3)
    meshes = lod.lod_meshes(Mesh(v, f), levels=3, coarsest=0.25)
    assert [m.n_faces for m in meshes] == pm.faces_per_level


def test_levels_of_a_set_of_independent_surfaces():
    from anatomesh.core.model.surfaceset import SurfaceSet

    v, f = icosphere(4, 10.0)
    ss = SurfaceSet.from_meshes([Mesh(v, f, name="ball", value=300.0)], np.eye(4))
    pm = lod.progressive(ss, face_ratios=[0.1])
    coarse = pm.level(0)
    assert isinstance(coarse, SurfaceSet) and coarse.lattice is None
    assert coarse.shell_values == {1: 300.0} and abs(coarse.n_faces - 512) <= 2
    shell = coarse.shell(1)
    _closed(shell.vertices, shell.faces, genus=0)
    assert pm.measure(0)[1]["hausdorff_mm"] < 1.0
    with pytest.raises(AnatomeshError, match="Mesh or a SurfaceSet"):
        lod.progressive((v, f))
