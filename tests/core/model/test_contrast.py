"""CIELAB, CIE76 ΔE and moving the colours of touching structures apart."""
import numpy as np
import pytest

from anatomesh.core.model.contrast import (BONE_DELTA_E, delta_e, lab_to_srgb, separate_colors,
                                           srgb_to_lab, touching_pairs)
from anatomesh.core.model.labels import LabelInfo
from anatomesh.core.model.mesh import Mesh
from anatomesh.core.model.surfaceset import SurfaceSet
from helpers.meshes import icosphere


def test_cielab_of_known_colours():
    # D65 reference values (Lindbloom's calculator; CSS Color 4 gives the same)
    assert srgb_to_lab((1, 1, 1)) == pytest.approx((100, 0, 0), abs=0.01)
    assert srgb_to_lab((1, 0, 0)) == pytest.approx((53.24, 80.09, 67.20), abs=0.05)
    assert srgb_to_lab((0, 0, 1)) == pytest.approx((32.30, 79.19, -107.86), abs=0.05)
    assert srgb_to_lab((0.5, 0.5, 0.5)) == pytest.approx((53.39, 0, 0), abs=0.05)
    rgb = np.random.default_rng(0).random((50, 3))
    assert lab_to_srgb(srgb_to_lab(rgb)) == pytest.approx(rgb, abs=1e-6)
    assert delta_e((1, 1, 1), (0, 0, 0)) == pytest.approx(100, abs=0.01)


def test_a_chain_of_one_colour_is_pulled_apart_and_a_given_colour_stays():
    brown = (0.6, 0.3, 0.2)
    table = {v: LabelInfo(v, f"part {v}", brown, "parenchyma") for v in range(1, 6)}
    pairs = [(1, 2), (2, 3), (3, 4), (4, 5), (1, 3)]
    out = separate_colors(table, pairs, fixed=[3])
    assert out[3].color == brown
    for a, b in pairs:
        assert delta_e(out[a].color, out[b].color) >= 12
    for v in out:  # still recognisably the same colour: a lightness step, a small hue turn
        assert delta_e(out[v].color, brown) <= 32
    assert separate_colors(table, pairs, fixed=[3]) == out  # deterministic
    assert {v: i.name for v, i in out.items()} == {v: i.name for v, i in table.items()}


def test_two_bones_need_only_a_small_step_and_lone_labels_stay():
    ivory = (0.94, 0.84, 0.57)
    table = {1: LabelInfo(1, "a", ivory, "bone"), 2: LabelInfo(2, "b", ivory, "bone"),
             3: LabelInfo(3, "c", ivory, "muscle")}
    out = separate_colors(table, [(1, 2)])
    assert BONE_DELTA_E <= delta_e(out[1].color, out[2].color) < 12
    assert out[3].color == ivory


def test_touching_pairs_of_independent_surfaces():
    v, f = icosphere(3, 10.0)
    shifts = ([0, 0, 0], [20.5, 0, 0], [60, 0, 0])  # b 0.5 mm from a (1 mm voxels); c far away
    s = SurfaceSet.from_meshes([Mesh(v + np.float32(d), f) for d in shifts], np.eye(4))
    assert touching_pairs(s) == [(1, 2)]


def test_touching_pairs_of_a_label_map_are_its_interfaces():
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.io.load import load
    from conftest import shared

    s = label_surfaces(load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")))
    assert touching_pairs(s) == [(a, b) for a, b, _ in s.interfaces()]
    assert len(touching_pairs(s)) > 100
