"""Thin features a printer would mind versus the rims of smooth shapes: analytic lenses and
ellipsoids with sharp rims pass; a 0.5 mm sheet and a 0.6 mm rod fail with their true thickness,
place and size; the rule's reach (how far thin material sticks out of the full-wall body) is
exact on a wedge."""
import re

import numpy as np
import pytest
from helpers.meshes import box, icosphere
from helpers.print_shapes import body_with_fin_and_rod, lens

from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import Mesh
from anatomesh.core.printing import checks as pc
from anatomesh.core.printing.features import thin_features
from anatomesh.core.printing.reach import reach_beyond_body
from anatomesh.core.printing.thickness import wall_thickness


def features(v, f, min_wall=0.8, tolerance=0.4):
    g = TriangleGrid(v, f)
    t, det = wall_thickness(v, f, grid=g, max_thickness=5.0, return_details=True)
    return thin_features(v, f, t, det, min_wall, tolerance, grid=g)


@pytest.mark.parametrize("half_angle", [35.0, 45.0, 60.0])
def test_lens_with_sharp_rim_passes(half_angle):
    v, f = lens(10.0, half_angle)
    assert topology(v, f).closed
    feats = features(v, f)
    # the rim is thinner than the wall (it tapers to nothing) but a rim, not a thin spot
    assert all(not r["fails"] and r["kind"] == "rim" for r in feats)
    if half_angle == 35.0:
        assert feats and min(r["min_mm"] for r in feats) < 0.3
    rep = pc.check_parts([Mesh(v, f, name="lens")], "fdm")
    part = rep["parts"][0]
    assert part["passed"] and part["reasons"] == []
    assert part["rims"]["count"] == len(feats)


def test_knife_edge_sharper_than_the_tolerance_fails_as_an_edge():
    # a 20° half-angle wedge sticks 0.4 (1/sin 20° - 1) = 0.77 mm out of the 0.8 mm body
    v, f = lens(10.0, 20.0)
    feats = [r for r in features(v, f) if r["fails"]]
    assert len(feats) == 1 and feats[0]["kind"] == "edge"
    assert "sharp edge" in feats[0]["reason"]
    # the band thinner than 0.8 mm runs around the whole rim (2π·10 mm long)
    assert np.hypot(*feats[0]["location"][:2]) < 1.0


@pytest.mark.parametrize("axes", [(20.0, 20.0, 2.0), (15.0, 10.0, 2.5)])
def test_flat_ellipsoids_pass(axes):
    v, f = icosphere(4, 1.0)
    v = v * axes
    rep = pc.check_parts([Mesh(v, f, name="ellipsoid")], "fdm")
    assert rep["parts"][0]["passed"], rep["parts"][0]["reasons"]


def test_reach_of_a_lens_rim_is_exact():
    # the lens rim (a wedge of half-angle a between spheres of radius R = 10 / sin a): the
    # deepest ball of radius 0.4 in the rim plane sits at x with R - |(x, R cos a)| = 0.4, so
    # the rim sticks out 10 - x - 0.4 (a straight wedge: 0.4 (1/sin a - 1), a little less)
    for a in (25.0, 40.0):
        v, f = lens(10.0, a, rings=60, segments=240)
        big = 10.0 / np.sin(np.radians(a))
        x = np.sqrt((big - 0.4) ** 2 - (big * np.cos(np.radians(a))) ** 2)
        tip = np.array([[10.0, 0.0, 0.0]])
        reach = reach_beyond_body(TriangleGrid(v, f), tip, np.array([[-1.0, 0.0, 0.0]]), 0.8, 3.0)
        assert reach[0] == pytest.approx(10.0 - x - 0.4, abs=0.02)


def test_sheet_and_rod_fail_with_their_true_thickness_place_and_size():
    v, f = body_with_fin_and_rod(sheet=0.5, rod=0.6)
    rep = pc.check_parts([Mesh(v, f, name="phantom")], "fdm")
    part = rep["parts"][0]
    assert not part["passed"]
    kinds = {r["kind"]: r for r in part["thin_regions"]}
    sheet, rod = kinds["sheet"], kinds["rod"]
    assert sheet["thickness_mm"] == pytest.approx(0.5, abs=0.1)
    assert sheet["sheet_area_mm2"] == pytest.approx(64.0, rel=0.15)  # 8 x 8 mm, one side
    assert sheet["location"] == pytest.approx([5.0, 5.0, 10.0], abs=0.6)
    assert rod["thickness_mm"] == pytest.approx(0.6, abs=0.1)
    assert rod["length_mm"] == pytest.approx(12.0, abs=1.5)
    assert rod["location"] == pytest.approx([16.0, 5.0, 3.0], abs=0.6)
    reasons = " | ".join(part["reasons"])
    assert re.search(r"sheet 0\.[45]\d mm thick over 6\d mm² at \(5, 5, 10\)", reasons), reasons
    assert re.search(r"rod 0\.[56]\d mm across, 1[234] mm long at \(16, 5, 3\)", reasons), reasons
    # the block itself is no thin spot: nothing else is listed
    assert len(part["thin_regions"]) == 2


def test_plate_alone_is_one_sheet_both_sides_together():
    v, f = box((0, 0, 0), (12, 10, 0.5), 8)
    (r,) = [r for r in features(v, f) if r["fails"]]
    assert r["kind"] == "sheet" and r["thickness_mm"] == pytest.approx(0.5, abs=1e-3)
    assert r["extent"]["sheet_area_mm2"] == pytest.approx(12 * 10, rel=0.1)  # one side
