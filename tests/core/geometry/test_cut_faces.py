"""Cut faces: the triangles where the scan's field of view closed a structure, counted against the
label map's own border voxels (each voxel face on the volume's outer boundary is one quad of the
label's shell, two triangles)."""
import numpy as np
import pytest
from conftest import SAMPLE

from anatomesh.core import load
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.cut_faces import cut_faces


def _border_voxel_faces(data: np.ndarray, value: int) -> int:
    """Voxel faces of label ``value`` on the six outer planes of the volume."""
    return sum(int((np.take(data, i, axis=ax) == value).sum())
               for ax in range(3) for i in (0, data.shape[ax] - 1))


@pytest.fixture(scope="module")
def sample():
    vol = load(str(SAMPLE / "example_seg.nii.gz"))
    return vol, label_surfaces(vol).shells()


def test_every_border_voxel_face_and_nothing_else(sample):
    vol, shells = sample
    data = np.asarray(vol.data)
    touching = 0
    for m in shells:
        cut = cut_faces(m.vertices, m.faces, vol.affine, vol.shape)
        assert int(cut.sum()) == 2 * _border_voxel_faces(data, int(m.value)), m.name
        touching += bool(cut.any())
    assert len(shells) == 41 and 25 < touching < 41  # the 30-slice sample cuts most organs, not all


def test_cut_faces_lie_on_the_volume_boundary(sample):
    vol, shells = sample
    liver = next(m for m in shells if m.name == "liver")
    cut = cut_faces(liver.vertices, liver.faces, vol.affine, vol.shape)
    inv = np.linalg.inv(vol.affine)
    ijk = liver.vertices[liver.faces[cut]].reshape(-1, 3) @ inv[:3, :3].T + inv[:3, 3]
    outer = np.isclose(ijk, -0.5, atol=1e-3) | np.isclose(ijk, np.array(vol.shape) - 0.5, atol=1e-3)
    assert outer.any(axis=1).all()
    # the liver leaves the sample through its first and last slices (mostly the top), not its sides
    top, bottom = (np.isclose(ijk[:, 2], k, atol=1e-3) for k in (vol.shape[2] - 0.5, -0.5))
    assert (top | bottom).all() and top.mean() > 0.5 > bottom.mean() > 0


def test_tilted_and_inner_faces_are_not_cut():
    """A unit-voxel grid 4 x 4 x 4: a face on the plane z = -0.5 is cut; the same face tilted 45
    degrees, or moved one voxel inward, is not; an oblique affine changes nothing."""
    tri = np.array([[0.0, 0.0, -0.5], [1.0, 0.0, -0.5], [0.0, 1.0, -0.5],       # on the plane
                    [0.0, 0.0, -0.5], [1.0, 0.0, 0.5], [0.0, 1.0, -0.5],        # tilted 45 deg
                    [0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [0.0, 1.0, 0.5],          # one voxel in
                    [3.5, 1.0, 1.0], [3.5, 2.0, 1.0], [3.5, 1.0, 2.0]])         # far x plane
    faces = np.arange(12).reshape(4, 3)
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for affine in (np.eye(4), np.block([[rot * [0.7, 0.7, 2.5], np.array([[100.0], [-40.0], [900.0]])],
                                        [np.zeros((1, 3)), np.ones((1, 1))]])):
        mm = tri @ affine[:3, :3].T + affine[:3, 3]
        assert cut_faces(mm, faces, affine, (4, 4, 4)).tolist() == [True, False, False, True]
    assert cut_faces(tri, np.zeros((0, 3), int), np.eye(4), (4, 4, 4)).shape == (0,)
