"""Pinches (:mod:`anatomesh.core.printing.pinch`) on phantoms with known answers: cubes touching
along an edge or at a corner, cubes 0.05 mm and 2 mm apart, a prism whose two lobes meet at a
waist thinner or thicker than the minimum wall, and plain solids that have none. Units are mm."""
import re

import numpy as np
import pytest
from helpers.meshes import box, icosphere

from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import Mesh, signed_volume
from anatomesh.core.printing import checks as pc
from anatomesh.core.printing.pinch import pinches
from anatomesh.core.printing.thickness import wall_thickness

#: the fdm profile's limits
MIN_WALL, MIN_GAP = 0.8, 0.5
#: a reason says what to do: thicken the part, join the pieces or print them apart
WHAT_TO_DO = re.compile(r"thicken|join|apart|separate")


# ---------------------------------------------------------------------------------------------
# phantoms
# ---------------------------------------------------------------------------------------------
def join(*parts):
    """One mesh of several shells, each keeping its own vertices (positions may coincide)."""
    vs, fs, n = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(np.asarray(f) + n)
        n += len(v)
    return np.vstack(vs), np.vstack(fs).astype(np.int32)


def two_cubes(offset):
    """The cube [0, 10]³ and a second 10 mm cube whose lowest corner is ``offset``."""
    o = np.asarray(offset, float)
    return join(box((0, 0, 0), (10, 10, 10)), box(o, o + 10))


def bowtie(waist, half_length=10.0, half_width=5.0, height=10.0, step=0.25, layers=20):
    """A prism z = 0..``height`` over a hexagon with two V notches meeting at x = 0, ``waist`` mm
    apart there: two lobes 2·``half_width`` wide at x = ±``half_length`` joined by a neck
    ``waist`` wide (along y) and ``height`` long (along z). Walls split every ``step`` mm around
    and into ``layers`` rows; each cap a fan from its lobe's centre."""
    corners = np.array([[-half_length, -half_width], [0, -waist / 2], [half_length, -half_width],
                        [half_length, half_width], [0, waist / 2], [-half_length, half_width]])
    ring = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        k = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
        ring.append(a + np.linspace(0, 1, k, endpoint=False)[:, None] * (b - a))
    ring = np.concatenate(ring)  # counter-clockwise seen from +z
    m = len(ring)
    z = np.linspace(0, height, layers + 1)
    v = np.concatenate([np.c_[ring, np.full(m, h)] for h in z])
    i = np.arange(m)
    j = (i + 1) % m
    faces = []
    for k in range(layers):
        a, b, c, d = k * m + i, k * m + j, (k + 1) * m + j, (k + 1) * m + i
        faces += [np.c_[a, b, c], np.c_[a, c, d]]
    low, high = (int(np.flatnonzero(np.all(ring == c, axis=1))[0]) for c in corners[[1, 4]])
    halves = ((np.r_[np.arange(high, m), np.arange(0, low + 1)], -half_length / 2),
              (np.arange(low, high + 1), half_length / 2))
    centres = []
    for loop, cx in halves:  # each lobe's loop ends on the notch-to-notch edge that closes it
        for level, up in ((0, False), (layers, True)):
            c = len(v) + len(centres)
            centres.append([cx, 0.0, z[level]])
            tri = np.c_[np.full(len(loop), c), level * m + loop, level * m + np.roll(loop, -1)]
            faces.append(tri if up else tri[:, ::-1])
    return np.vstack([v, centres]), np.concatenate(faces).astype(np.int32)


def bowtie_volume(waist, half_length=10.0, half_width=5.0, height=10.0):
    return 2 * half_length * (waist / 2 + half_width) * height


def measure(v, f, min_wall=MIN_WALL, min_gap=MIN_GAP):
    """The pinches of one part, with the wall-thickness details check_parts gives them."""
    g = TriangleGrid(v, f)
    _, det = wall_thickness(v, f, grid=g, max_thickness=5.0, return_details=True)
    return pinches(v, f, det, min_wall, min_gap, grid=g)


def part_report(v, f):
    """check_parts' entry for the mesh as one part, fdm profile."""
    return pc.check_parts([Mesh(v, f, name="part")], "fdm")["parts"][0]


def pinch_entries(part):
    return [r for r in part["thin_regions"] if r["kind"] == "pinch"]


@pytest.fixture(scope="module")
def thin_bowtie():
    return bowtie(0.5)


# ---------------------------------------------------------------------------------------------
# the phantoms are what they claim
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape, shells, volume", [
    (lambda: two_cubes((10, 10, 0)), 2, 2000.0),
    (lambda: two_cubes((10, 10, 10)), 2, 2000.0),
    (lambda: two_cubes((10.05, 10, 0)), 2, 2000.0),
    (lambda: bowtie(0.5), 1, bowtie_volume(0.5)),
    (lambda: bowtie(2.0), 1, bowtie_volume(2.0)),
], ids=["edge", "corner", "near", "neck", "wide-waist"])
def test_phantoms_are_closed_outward_solids(shape, shells, volume):
    """Each phantom is closed, 2-manifold by index, consistently oriented, outward, of its volume."""
    v, f = shape()
    t = topology(v, f)
    assert t.closed and t.manifold and t.oriented and t.components == shells
    assert signed_volume(v, f) == pytest.approx(volume, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# touching pieces
# ---------------------------------------------------------------------------------------------
def test_cubes_sharing_an_edge_touch_along_it():
    """Two cubes with coincident vertices along a 10 mm edge: one pinch 0 mm thick, 10 mm long,
    centred on that edge, its vertices all on it."""
    v, f = two_cubes((10, 10, 0))
    (p,) = measure(v, f)
    assert p["kind"] == "pinch" and p["fails"]
    assert p["thickness_mm"] == 0.0 and p["gap_mm"] == 0.0
    assert p["extent"]["length_mm"] == pytest.approx(10.0, abs=0.01)
    assert p["location"] == pytest.approx([10.0, 10.0, 5.0], abs=0.01)
    assert np.allclose(v[p["vertices"], :2], 10.0)


def test_check_parts_fails_a_part_whose_pieces_touch_along_an_edge():
    """check_parts lists the edge pinch with its numbers and fails the part with its reason, which
    says what to do."""
    part = part_report(*two_cubes((10, 10, 0)))
    assert not part["passed"]
    (p,) = pinch_entries(part)
    assert p["thickness_mm"] == 0.0 and p["gap_mm"] == 0.0
    assert p["length_mm"] == pytest.approx(10.0, abs=0.01)
    assert p["location"] == pytest.approx([10.0, 10.0, 5.0], abs=0.01)
    assert p["reason"] in part["reasons"]
    assert "touch" in p["reason"] and "10.0 mm" in p["reason"] and "(10, 10, 5)" in p["reason"]
    assert WHAT_TO_DO.search(p["reason"]), p["reason"]


def test_cubes_sharing_a_corner_touch_at_a_point():
    """Two cubes sharing one corner: a point pinch (length 0) at that corner."""
    v, f = two_cubes((10, 10, 10))
    (p,) = measure(v, f)
    assert p["thickness_mm"] == 0.0 and p["gap_mm"] == 0.0
    assert p["extent"]["length_mm"] == 0.0
    assert p["location"] == pytest.approx([10.0, 10.0, 10.0], abs=1e-9)
    part = part_report(v, f)
    (entry,) = pinch_entries(part)
    assert not part["passed"] and entry["length_mm"] == 0.0
    assert "at a point" in entry["reason"] and WHAT_TO_DO.search(entry["reason"])


# ---------------------------------------------------------------------------------------------
# nearly touching pieces
# ---------------------------------------------------------------------------------------------
def test_cubes_0_05_mm_apart_along_an_edge_nearly_touch():
    """Edges 0.05 mm apart (under the 0.5 mm minimum gap): a pinch 0 mm thick with gap 0.05 mm,
    10 mm long, between the two edges; check_parts reports the gap and fails the part."""
    v, f = two_cubes((10.05, 10, 0))
    (p,) = measure(v, f)
    assert p["thickness_mm"] == 0.0
    assert p["gap_mm"] == pytest.approx(0.05, abs=1e-6)
    assert p["extent"]["length_mm"] == pytest.approx(10.0, abs=0.01)
    assert p["location"] == pytest.approx([10.025, 10.0, 5.0], abs=0.01)
    part = part_report(v, f)
    (entry,) = pinch_entries(part)
    assert not part["passed"] and entry["gap_mm"] == pytest.approx(0.05, abs=1e-3)
    assert "0.05 mm apart" in entry["reason"] and WHAT_TO_DO.search(entry["reason"])


@pytest.mark.parametrize("offset, why", [
    ((12.0, 10.0, 0.0), "edges 2 mm apart: wider than the minimum gap, the gap stays open"),
    ((10.05, 0.0, 0.0), "faces 0.05 mm apart: they meet over a face, not a point or a line"),
])
def test_cubes_apart_or_facing_each_other_are_no_pinch(offset, why):
    """No pinch where the gap stays open or the pieces meet over a whole face."""
    v, f = two_cubes(offset)
    assert measure(v, f) == [], why
    assert pinch_entries(part_report(v, f)) == [], why


def test_a_gap_wider_than_the_printers_minimum_gap_is_no_pinch():
    """The same 0.05 mm gap stays open for a printer whose minimum gap is 0.02 mm."""
    v, f = two_cubes((10.05, 10, 0))
    assert measure(v, f, min_gap=0.02) == []


# ---------------------------------------------------------------------------------------------
# necks
# ---------------------------------------------------------------------------------------------
def test_waist_thinner_than_the_min_wall_is_a_neck(thin_bowtie):
    """Two lobes joined by a 0.5 mm waist running 10 mm along z: one neck 0.5 mm across, about
    10 mm long (the rows at the caps aside: 0.5 mm each), located on the waist."""
    v, f = thin_bowtie
    (p,) = measure(v, f)
    assert p["gap_mm"] == 0.0
    assert p["thickness_mm"] == pytest.approx(0.5, abs=0.02)
    assert p["extent"]["length_mm"] == pytest.approx(10.0, abs=1.0)
    x, y, z = p["location"]
    assert abs(x) < 0.01 and abs(abs(y) - 0.25) < 0.01 and 0.0 <= z <= 10.0


def test_check_parts_fails_a_part_with_a_neck(thin_bowtie):
    """check_parts lists the neck once (both notches are one place) and fails the part with a
    reason that says what to do; nothing else fails it."""
    part = part_report(*thin_bowtie)
    (p,) = pinch_entries(part)
    assert not part["passed"] and part["reasons"] == [p["reason"]]
    assert p["thickness_mm"] == pytest.approx(0.5, abs=0.02) and p["gap_mm"] == 0.0
    assert "0.50 mm across" in p["reason"] and WHAT_TO_DO.search(p["reason"])


def test_the_same_waist_is_no_neck_for_a_thinner_min_wall(thin_bowtie):
    """A 0.5 mm waist is no neck for the resin printer's 0.4 mm minimum wall."""
    v, f = thin_bowtie
    assert measure(v, f, min_wall=0.4, min_gap=0.2) == []


def test_waist_thicker_than_the_min_wall_is_no_neck():
    """A 2 mm waist holds: no pinch, and the part passes."""
    v, f = bowtie(2.0)
    assert measure(v, f) == []
    part = part_report(v, f)
    assert part["passed"] and pinch_entries(part) == []


# ---------------------------------------------------------------------------------------------
# no false positives
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [lambda: box((0, 0, 0), (10, 10, 10)), lambda: icosphere(4, 10.0)],
                         ids=["cube", "sphere"])
def test_plain_solids_have_no_pinch(shape):
    """A plain cube or sphere has no pinch and passes."""
    v, f = shape()
    assert measure(v, f) == []
    part = part_report(v, f)
    assert part["passed"] and part["thin_regions"] == []
