"""Topology clean-up per label: Euler characteristic and Betti numbers of voxel sets, cavities
filled, handles closed up to a size (torus on 0.5 x 0.5 x 5 mm voxels), dents left alone."""
import numpy as np
import pytest

from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.labels import LabelInfo
from anatomesh.core.model.volume import Volume
from anatomesh.core.preprocess.label_topology import (close_handles, euler_characteristic,
                                                      fill_cavities, label_topology)
from helpers.fields import grid, label_volume


def flat_torus(hole_radius, spacing=(0.5, 0.5, 5.0)):
    """A torus lying in the slices (axis z): tube radius 9 mm, flattened 2x in z (the thick
    slices), hole of ``hole_radius`` mm."""
    (x, y, z), affine = grid((120, 120, 12), spacing)
    r = 9.0
    return label_volume((np.sqrt(x**2 + y**2) - (hole_radius + r)) ** 2 + (z / 2) ** 2 <= r**2, affine, "torus")


def mesh_genus(vol, value=1):
    m = label_surfaces(vol, [value]).shells()[0]
    return topology(m.vertices, m.faces).genus


def test_euler_characteristic_of_known_shapes():
    cube = np.pad(np.ones((3, 3, 3), bool), 1)
    assert euler_characteristic(cube) == 1
    ring = cube.copy()
    ring[2, 2, :] = False  # a tunnel through the middle
    assert label_topology(ring[1:-1, 1:-1, 1:-1]) == {"components": 1, "handles": 1, "cavities": 0, "euler": 0}
    hollow = np.pad(np.ones((5, 5, 5), bool), 1)
    hollow[3, 3, 3] = False
    assert label_topology(hollow) == {"components": 1, "handles": 0, "cavities": 1, "euler": 2}


def test_close_handles_plugs_a_small_tunnel_and_keeps_a_large_one():
    vol = flat_torus(5.0)  # hole 10 mm across
    assert label_topology(vol.data == 1)["handles"] == 1 and mesh_genus(vol) == 1
    kept, info = close_handles(vol, 6.0)  # smaller than the hole: nothing to do
    assert info[1]["after"]["handles"] == 1 and info[1]["added_voxels"] == 0 and mesh_genus(kept) == 1
    closed, info = close_handles(vol, 12.0)  # larger: the hole is plugged
    assert info[1]["before"]["handles"] == 1 and info[1]["after"]["handles"] == 0
    assert mesh_genus(closed) == 0
    # only the hole was filled: every added voxel lies inside the ring's hole
    (x, y, _), _ = grid(vol.shape, vol.spacing)
    added = (closed.data == 1) & (vol.data == 0)
    assert added.sum() == info[1]["added_voxels"] > 0
    assert np.sqrt(x**2 + y**2)[added].max() <= 5.0 + 9.0


def test_close_handles_leaves_dents_and_other_labels_alone():
    (x, y, z), affine = grid((40, 40, 40), (1.0, 1.0, 1.0))
    ball = x**2 + y**2 + z**2 <= 14**2
    dent = (x - 12) ** 2 + y**2 + z**2 <= 5**2  # a cup-shaped dent in its side
    data = np.where(ball & ~dent, 1, 0).astype(np.uint8)
    data[(x + 16) ** 2 + y**2 <= 9] = 2  # a rod of another label just beside it
    vol = Volume(data, affine, labels={1: LabelInfo(1, "ball"), 2: LabelInfo(2, "rod")})
    out, info = close_handles(vol, 12.0, values=[1])
    assert info[1]["added_voxels"] == 0 and info[1]["pieces_rejected"] >= 1
    np.testing.assert_array_equal(out.data, vol.data)


def test_fill_cavities_fills_background_pockets_only():
    (x, y, z), affine = grid((40, 40, 9), (0.5, 0.5, 5.0))
    r2 = x**2 + y**2 + (z / 2) ** 2
    shell = (r2 <= 9**2) & (r2 > 4**2)
    vol = label_volume(shell, affine, "shell")
    out, info = fill_cavities(vol)
    assert info[1]["before"]["cavities"] == 1 and info[1]["after"]["cavities"] == 0
    assert info[1]["filled_voxels"] == (r2 <= 4**2).sum() > 0
    np.testing.assert_array_equal(out.data == 1, r2 <= 9**2)
    assert topology(*_arrays(label_surfaces(out).shells()[0])).components == 1
    assert (vol.data == shell).all()  # the input is untouched
    # another label inside the pocket stays; only the background around it is filled
    data = shell.astype(np.uint8)
    inner = (x - 0.25) ** 2 + (y - 0.25) ** 2 + (z / 2) ** 2 <= 1.0
    data[inner] = 2
    vol2 = Volume(data, affine, labels={1: LabelInfo(1, "shell"), 2: LabelInfo(2, "core")})
    out2, info2 = fill_cavities(vol2)
    assert inner.sum() > 10 and (out2.data[inner] == 2).all()  # labels stay disjoint
    assert info2[1]["filled_voxels"] == ((r2 <= 4**2) & ~inner).sum()
    assert info2[1]["after"]["cavities"] == 1  # the pocket now holds label 2 alone
    assert topology(*_arrays(label_surfaces(out2, [1]).shells()[0])).components == 2  # skin + seam


def _arrays(m):
    return m.vertices, m.faces


def test_bad_settings_are_one_line_errors():
    with pytest.raises(AnatomeshError, match="mm > 0"):
        close_handles(flat_torus(5.0), 0.0)
    with pytest.raises(AnatomeshError, match="label maps"):
        fill_cavities(Volume(np.zeros((3, 3, 3), np.float32), np.eye(4)))
