"""SurfaceSet: independent surfaces as one set (from_meshes), each shell giving its mesh back; the
label values with faces."""
import dataclasses

import numpy as np
import pytest
from helpers.meshes import icosphere, torus

from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import Mesh, signed_volume
from anatomesh.core.model.surfaceset import SurfaceSet


def test_from_meshes_gives_each_mesh_back_as_its_shell():
    sv, sf = icosphere(3, 10.0)
    tv, tf = torus(30.0, 5.0)
    meshes = [Mesh(sv, sf, name="skin", value=-500.0, color=(0.9, 0.7, 0.6)),
              Mesh(tv + 100.0, tf, name="bone", value=300.0, color=(0.9, 0.9, 0.8))]
    s = SurfaceSet.from_meshes(meshes, affine=np.eye(4), space="LPS")
    assert s.lattice is None and s.n_faces == len(sf) + len(tf) and s.values() == [1, 2]
    shells = s.shells()
    for m, sh in zip(meshes, shells):
        assert (sh.name, sh.value, sh.color, sh.space) == (m.name, m.value, m.color, "LPS")
        assert sh.n_faces == m.n_faces
        np.testing.assert_allclose(signed_volume(sh.vertices, sh.faces), signed_volume(m.vertices, m.faces),
                                   rtol=1e-6)
        assert topology(sh.vertices, sh.faces).genus == topology(m.vertices, m.faces).genus
        np.testing.assert_array_equal(s.vertices[sh.meta["vertex_ids"]], sh.vertices)
    assert topology(shells[1].vertices, shells[1].faces).genus == 1


def test_from_meshes_stacks_int32_faces_without_transient_copies():
    """The faces land in the set's int32 array offset by the vertices before them, face labels
    (k + 1, 0); memory: nothing is allocated beyond what the set keeps (an int64 copy of the
    faces to convert would show as 2x the faces' bytes; tracemalloc sees numpy's arrays)."""
    import tracemalloc

    sv, sf = icosphere(6, 10.0)  # 81,920 faces
    tv, tf = torus(30.0, 5.0)
    meshes = [Mesh(sv, sf.astype(np.int64)), Mesh(tv, tf.astype(np.int32))]
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        s = SurfaceSet.from_meshes(meshes, affine=np.eye(4))
        kept, peak = (x - base for x in tracemalloc.get_traced_memory())
    finally:
        tracemalloc.stop()
    assert s.faces.dtype == np.int32 and s.face_labels.dtype == np.int32
    np.testing.assert_array_equal(s.faces[:len(sf)], sf)
    np.testing.assert_array_equal(s.faces[len(sf):], tf + len(sv))
    np.testing.assert_array_equal(s.face_labels[:, 0], np.repeat([1, 2], [len(sf), len(tf)]))
    assert not s.face_labels[:, 1].any()
    assert peak <= kept + (1 << 16), (peak, kept)


def test_values_are_the_labels_with_faces():
    """The 61-label map's set: the label values on the faces' sides but the background, as
    np.unique finds them; a label absent from the faces is not listed; negative labels are
    refused."""
    from anatomesh.core import label_surfaces, load
    from anatomesh.core.model.errors import AnatomeshError
    from conftest import shared

    s = label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))
    want = [int(v) for v in np.unique(s.face_labels) if v != s.background]
    assert s.values() == want and len(want) == 61
    fewer = dataclasses.replace(s, face_labels=np.where(s.face_labels == want[3], 0,
                                                        s.face_labels))
    assert fewer.values() == want[:3] + want[4:]
    with pytest.raises(AnatomeshError, match="non-negative"):
        dataclasses.replace(s, face_labels=-s.face_labels).values()
