"""The tapering-rim rule of :mod:`anatomesh.core.printing.features`: the closed-form cut-back of a
wedge and the limits of a printable rim, then phantoms with known answers — a lens whose rim
opens at 47° passes with a warning stating the cut-back, rims at 35° and 20° fail as edges, and
a 0.3 mm plate fails as a sheet. Units are mm and degrees."""
import re

import numpy as np
import pytest

from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.mesh import Mesh, signed_volume
from anatomesh.core.printing import checks as pc
from anatomesh.core.printing.features import taper_limits, wedge_cut_back

#: the fdm profile: minimum wall, and its smallest detail (the line width and the tolerance)
MIN_WALL, LINE = 0.8, 0.4
WARNING = re.compile(r"rim tapering to (\d+)° at \((-?\d+), (-?\d+), (-?\d+)\): "
                     r"a printer blunts it by about (\d+\.\d\d) mm")


# ---------------------------------------------------------------------------------------------
# phantoms
# ---------------------------------------------------------------------------------------------
def revolve(profile, segments):
    """Closed surface of revolution about z of ``profile`` (P, 2) rows (r, z), running from a
    pole (r = 0) to a pole; outward."""
    prof = np.asarray(profile, float)
    inner = prof[1:-1]
    phi = np.arange(segments) * 2 * np.pi / segments
    rings = [np.c_[r * np.cos(phi), r * np.sin(phi), np.full(segments, z)] for r, z in inner]
    v = np.vstack(rings + [[[0.0, 0.0, prof[0, 1]], [0.0, 0.0, prof[-1, 1]]]])
    j = np.arange(segments)
    j1 = (j + 1) % segments
    top, bottom = len(v) - 2, len(v) - 1
    faces = [np.c_[np.full(segments, top), j, j1]]
    for k in range(len(inner) - 1):
        a, b = k * segments, (k + 1) * segments
        faces += [np.c_[a + j, b + j, b + j1], np.c_[a + j, b + j1, a + j1]]
    last = (len(inner) - 1) * segments
    faces.append(np.c_[last + j, np.full(segments, bottom), last + j1])
    f = np.concatenate(faces)
    if signed_volume(v, f) < 0:
        f = f[:, ::-1]
    return v, f.astype(np.int32)


def lens_radii(rim_radius, rim_angle):
    """(sphere radius, distance of its centre from the rim plane) of the caps of :func:`lens`."""
    half = np.radians(rim_angle / 2)
    big = rim_radius / np.sin(half)
    return big, big * np.cos(half)


def lens(rim_radius, rim_angle, rows=30, segments=240, power=1.5):
    """Two spherical caps meeting at a rim of radius ``rim_radius`` in z = 0 that opens at the
    full angle ``rim_angle``; ``rows`` rings per cap, spaced finer towards the rim (the first
    row ~0.1 mm from it), ``segments`` around."""
    big, depth = lens_radii(rim_radius, rim_angle)
    half = np.radians(rim_angle / 2)
    phi = half * (1 - (np.arange(rows + 1) / rows) ** power)[::-1]  # the pole (0) .. the rim
    upper = np.c_[big * np.sin(phi), big * np.cos(phi) - depth]
    lower = upper[::-1][1:] * [1, -1]
    return revolve(np.vstack([upper, lower]), segments)


def lens_cut_back(rim_radius, rim_angle, line=LINE):
    """How far the lens's opening by a ball of diameter ``line`` lies behind its rim: that ball,
    touching both spheres, is centred in the rim plane at x with |(x, depth)| = big − line/2
    (a straight wedge's :func:`wedge_cut_back` is a little less: the caps bend inwards)."""
    big, depth = lens_radii(rim_radius, rim_angle)
    return rim_radius - np.sqrt((big - line / 2) ** 2 - depth ** 2) - line / 2


def cells_mesh(xs, ys, zs, solid):
    """Closed outward surface of the union of the grid cells ``solid[i, j, k]`` (the cell from
    ``xs[i]`` to ``xs[i + 1]``, ...): the faces between solid and empty cells, corners shared."""
    axes = [np.asarray(a, float) for a in (xs, ys, zs)]
    size = [len(a) for a in axes]
    occ = np.pad(np.asarray(solid, bool), 1)
    faces = []
    for ax in range(3):
        u, w = [a for a in range(3) if a != ax]
        step = np.diff(occ.astype(np.int8), axis=ax)  # +1: empty to solid going up along ax
        for sign in (1, -1):
            plane = np.argwhere(step == sign)  # the grid plane of the face, in grid-point indices
            plane[:, [u, w]] -= 1

            def corner(du, dw, p=plane, u=u, w=w):
                q = p.copy()
                q[:, u] += du
                q[:, w] += dw
                return (q[:, 0] * size[1] + q[:, 1]) * size[2] + q[:, 2]

            a, b, c, d = corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)
            quad = np.concatenate([np.c_[a, b, c], np.c_[a, c, d]])  # normal +ax when (ax, u, w) cyclic
            out_up = sign == -1  # solid below, empty above: the outside is +ax
            faces.append(quad if ((u - ax) % 3 == 1) == out_up else quad[:, ::-1])
    f = np.concatenate(faces)
    points = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    used, f = np.unique(f, return_inverse=True)
    return points[used], f.reshape(-1, 3).astype(np.int32)


def plate_on_cube(thickness=0.3):
    """The cube [0, 10]³ with a plate ``thickness`` thick (z centred on 5) and 20 x 20 mm
    (x = 10..30, y = -5..15) standing out of its +x face: one side 400 mm², centred at (20, 5, 5)."""
    z0, z1 = 5 - thickness / 2, 5 + thickness / 2
    xs, ys = np.arange(0, 30.5, 1.0), np.arange(-5, 15.5, 1.0)
    zs = np.unique(np.r_[np.arange(0, 10.5, 1.0), z0, z1])
    x, y, z = np.meshgrid(*[(a[:-1] + a[1:]) / 2 for a in (xs, ys, zs)], indexing="ij")
    cube = (x < 10) & (y > 0) & (y < 10)
    plate = (x > 10) & (z > z0) & (z < z1)
    return cells_mesh(xs, ys, zs, cube | plate)


def part_report(v, f):
    """check_parts' entry for the mesh as one part, fdm profile."""
    return pc.check_parts([Mesh(v, f, name="part")], "fdm")["parts"][0]


# ---------------------------------------------------------------------------------------------
# closed forms
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("angle, cut", [(90, 0.083), (60, 0.20), (47, 0.30), (30, 0.57)])
def test_wedge_cut_back_closed_form(angle, cut):
    """b = (e/2)(1/sin(θ/2) − 1) for e = 0.4 mm, and the module docstring's figures."""
    b = wedge_cut_back(angle, LINE)
    assert b == pytest.approx(0.5 * LINE * (1 / np.sin(np.radians(angle) / 2) - 1), rel=1e-12)
    assert b == pytest.approx(cut, abs=0.005)


def test_wedge_cut_back_takes_arrays():
    """Angles as an array give the cut-backs element by element."""
    angles = np.array([90.0, 60.0, 47.0, 30.0])
    assert np.allclose(wedge_cut_back(angles, LINE), [wedge_cut_back(a, LINE) for a in angles])


def test_taper_limits_of_the_fdm_profile():
    """θmin = 2·asin(e/(e + 2·tol)) ≈ 38.9° and the cap w·tol/e = 0.8 mm for w = 0.8, e = tol = 0.4."""
    angle, cap = taper_limits(MIN_WALL, LINE)
    assert angle == pytest.approx(2 * np.degrees(np.arcsin(LINE / (LINE + 2 * LINE))), rel=1e-12)
    assert angle == pytest.approx(38.94, abs=0.01)
    assert cap == pytest.approx(0.8, rel=1e-12)


@pytest.mark.parametrize("wall, tol, line", [(0.8, 0.4, None), (0.8, 0.4, 0.2), (0.4, 0.1, 0.1), (1.0, 0.3, 0.5)])
def test_theta_min_is_where_a_straight_wedge_is_cut_back_by_the_tolerance(wall, tol, line):
    """At θmin a straight wedge loses exactly ``tol``; the cap is w·tol/e (e defaults to tol)."""
    angle, cap = taper_limits(wall, tol, line)
    e = tol if line is None else line
    assert wedge_cut_back(angle, e) == pytest.approx(tol, rel=1e-9)
    assert cap == pytest.approx(wall * tol / e, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# the phantoms are what they claim
# ---------------------------------------------------------------------------------------------
def test_lens_is_a_closed_outward_solid_with_its_rim_angle():
    """The lens is closed, 2-manifold, oriented, of the two caps' volume, and the faces along its
    rim meet at the full angle asked for."""
    v, f = lens(15.0, 47.0)
    t = topology(v, f)
    assert t.closed and t.manifold and t.oriented and t.components == 1
    big, depth = lens_radii(15.0, 47.0)
    h = big - depth
    assert signed_volume(v, f) == pytest.approx(2 * np.pi * h * h * (3 * big - h) / 3, rel=2e-3)
    on_rim = np.abs(v[:, 2]) < 1e-12
    rim_faces = f[on_rim[f].any(axis=1)]
    n = np.cross(v[rim_faces[:, 1]] - v[rim_faces[:, 0]], v[rim_faces[:, 2]] - v[rim_faces[:, 0]])
    elevation = np.degrees(np.arcsin(np.abs(n[:, 2]) / np.linalg.norm(n, axis=1)))
    assert np.allclose(2 * (90 - elevation), 47.0, atol=0.3)


def test_plate_on_cube_is_a_closed_outward_solid():
    """The plate on the cube is one closed, 2-manifold, oriented solid of 1000 + 0.3·400 mm³."""
    v, f = plate_on_cube(0.3)
    t = topology(v, f)
    assert t.closed and t.manifold and t.oriented and t.components == 1
    assert signed_volume(v, f) == pytest.approx(1000 + 0.3 * 400, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# the rule on the phantoms
# ---------------------------------------------------------------------------------------------
def test_lens_with_a_47_degree_rim_passes_with_a_warning_stating_the_cut_back():
    """A 3 cm lens whose rim opens at 47° (above θmin, cut back 0.30 mm ≤ 0.4) passes with fdm;
    its one rim is blunted, the warning names it (47°, a point on the rim) and states a cut-back
    within 0.05 mm of wedge_cut_back(47°), within 0.03 of the lens's own."""
    part = part_report(*lens(15.0, 47.0))
    assert part["passed"] and part["reasons"] == [] and part["thin_regions"] == []
    assert part["rims"]["blunted"] == 1
    cut = part["rims"]["max_cut_back_mm"]
    assert cut == pytest.approx(wedge_cut_back(47, LINE), abs=0.05)
    assert cut == pytest.approx(lens_cut_back(15.0, 47.0), abs=0.03)
    (warning,) = part["warnings"]
    m = WARNING.fullmatch(warning)
    assert m, warning
    angle, x, y, z, stated = (float(g) for g in m.groups())
    assert angle == pytest.approx(47, abs=2)
    assert np.hypot(x, y) == pytest.approx(15.0, abs=1.0) and abs(z) <= 0.5  # on the rim
    assert stated == pytest.approx(cut, abs=0.005)


def test_lens_with_a_35_degree_rim_fails_as_an_edge_cut_back_too_far():
    """A rim opening at 35° (below θmin = 38.9°) is cut back by ~0.49 mm, more than the 0.4 mm
    detail: it fails as an edge, with that angle and cut-back."""
    part = part_report(*lens(10.0, 35.0, segments=160))
    assert not part["passed"] and part["rims"]["blunted"] == 0
    (edge,) = part["thin_regions"]
    assert edge["kind"] == "edge" and edge["reason"] in part["reasons"]
    assert edge["angle_deg"] == pytest.approx(35, abs=2)
    assert edge["cut_back_mm"] == pytest.approx(lens_cut_back(10.0, 35.0), abs=0.05)
    assert edge["cut_back_mm"] > LINE
    assert "sharp edge" in edge["reason"]


def test_lens_with_a_20_degree_rim_fails_as_an_edge():
    """A rim opening at 20° (a straight wedge there loses 0.95 mm, more than the 0.8 mm wall) fails
    as an edge, its angle measured, its cut-back beyond the wall (None in the report)."""
    assert wedge_cut_back(20, LINE) > MIN_WALL
    part = part_report(*lens(10.0, 20.0, segments=160))
    assert not part["passed"]
    (edge,) = part["thin_regions"]
    assert edge["kind"] == "edge" and edge["reason"] in part["reasons"]
    assert edge["angle_deg"] == pytest.approx(20, abs=2)
    assert edge["cut_back_mm"] is None
    assert np.hypot(*edge["cut_back_location"][:2]) == pytest.approx(10.0, abs=0.5)


def test_plate_thinner_than_the_min_wall_fails_as_a_sheet():
    """A 0.3 mm plate of 20 x 20 mm on a cube fails as a sheet 0.3 mm thick, ~400 mm² a side,
    centred on the plate; the crease where it meets the cube is no pinch."""
    part = part_report(*plate_on_cube(0.3))
    assert not part["passed"]
    (sheet,) = part["thin_regions"]
    assert sheet["kind"] == "sheet" and sheet["reason"] in part["reasons"]
    assert sheet["thickness_mm"] == pytest.approx(0.3, abs=0.02)
    assert sheet["sheet_area_mm2"] == pytest.approx(400, rel=0.05)
    assert sheet["location"] == pytest.approx([20.0, 5.0, 5.0], abs=0.5)
    assert re.match(r"sheet 0\.30 mm thick over 40\d mm² at \(20, 5, 5\)", sheet["reason"]), sheet["reason"]
