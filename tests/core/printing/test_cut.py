"""Cut to fit: a plane cut leaves two closed, manifold, oriented halves whose volumes add up to the
part's (a ball's halves are hemispheres of 2/3·π·r³; a torus cut through its hole gives two
C-shaped pieces, cut along its equator two rings with annular caps: holes in the cut face); a
cube of 100 mm is cut into pieces that fit a 60 mm build volume; the smoothed liver of the
41-label sample is cut to fit 120 mm, every piece closed and read as manifold by PrusaSlicer."""
import shutil
import subprocess

import numpy as np
import pytest
from conftest import SAMPLE
from helpers.meshes import box, icosphere, torus

from anatomesh.core.export.mesh_files import write_stl
from anatomesh.core.geometry.polygons import delaunay_flips, nest, signed_area, triangulate
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh, signed_volume
from anatomesh.core.printing.connectors import interface_faces
from anatomesh.core.printing.cut import (cut_by_plane, fit_part, fit_to_volume, fits, plan_cuts,
                                         section_areas)

PRUSA = shutil.which("prusa-slicer")


def _mesh(v, f, name="part"):
    return Mesh(np.asarray(v, np.float32), np.asarray(f, np.int32), name=name)


def _solid(m):
    t = topology(m.vertices, m.faces)
    assert t.closed and t.manifold and t.oriented and t.degenerate_faces == 0, (m.name, t)
    return t


def test_square_with_a_hole_triangulates_to_its_area():
    outer = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    hole = np.array([[3, 3], [3, 7], [7, 7], [7, 3]], float)  # clockwise
    tri = triangulate(outer, [hole])
    pts = np.concatenate([outer, hole])
    areas = [signed_area(pts[t]) for t in tri]
    assert min(areas) > 0 and sum(areas) == pytest.approx(100 - 16)
    assert nest([outer, hole]) == ([False, True], [-1, 0])


def test_delaunay_flips_remove_flat_triangles_of_collinear_sides():
    # a 20 x 14 rectangle with extra points on its sides: a fan from one corner has flat triangles
    pts = np.array([(0, 0), (3, 0), (7, 0), (12, 0), (20, 0), (20, 5), (20, 9), (20, 14),
                    (12, 14), (7, 14), (3, 14), (0, 14), (0, 9), (0, 5)], float)
    fan = np.array([(0, k, k + 1) for k in range(1, len(pts) - 1)])
    flipped = delaunay_flips(pts, fan, 1e-4)
    areas = [signed_area(pts[t]) for t in flipped]
    assert min(areas) > 1 and sum(areas) == pytest.approx(280.0)


def test_ball_cut_at_its_equator_gives_two_closed_hemispheres():
    r = 40.0
    ball = _mesh(*icosphere(5, r), name="ball")
    below, above = cut_by_plane(ball, (0, 0, 0), (0, 0, 1))
    for half in (below, above):
        t = _solid(half)
        assert t.components == 1 and t.genus == 0
        assert signed_volume(half.vertices, half.faces) == pytest.approx(2 / 3 * np.pi * r ** 3, rel=0.005)
    # the icosphere has vertices on z = 0: the plane moves off them by 0.015 mm
    assert np.asarray(below.vertices)[:, 2].max() <= 0.02 and np.asarray(above.vertices)[:, 2].min() >= -0.02
    total = signed_volume(below.vertices, below.faces) + signed_volume(above.vertices, above.faces)
    assert total == pytest.approx(signed_volume(ball.vertices, ball.faces), rel=1e-6)
    assert len(interface_faces(below, above)) > 0  # the shared cut face (where connectors go)
    assert section_areas(ball, 2, np.array([0.0]))[0] == pytest.approx(np.pi * r ** 2, rel=0.005)


def test_torus_cut_through_its_hole_and_along_its_equator():
    ring = _mesh(*torus(20.0, 8.0, 96, 48), name="torus")
    whole = signed_volume(ring.vertices, ring.faces)
    for normal, genus in (((1, 0, 0), 0), ((0, 0, 1), 1)):  # across the hole: two Cs; equator: two rings
        halves = cut_by_plane(ring, (0, 0, 0), normal)
        for h in halves:
            t = _solid(h)
            assert t.components == 1 and t.genus == genus
        assert sum(signed_volume(h.vertices, h.faces) for h in halves) == pytest.approx(whole, rel=1e-6)
        assert signed_volume(halves[0].vertices, halves[0].faces) == pytest.approx(whole / 2, rel=0.01)


def test_plane_missing_the_part_and_bad_input():
    ball = _mesh(*icosphere(3, 10.0))
    below, above = cut_by_plane(ball, (0, 0, 50), (0, 0, 1))
    assert len(above.faces) == 0 and len(below.faces) == len(ball.faces)
    with pytest.raises(AnatomeshError, match="closed"):
        cut_by_plane(_mesh(ball.vertices, ball.faces[1:]), (0, 0, 0), (0, 0, 1))
    with pytest.raises(AnatomeshError, match="normal"):
        cut_by_plane(ball, (0, 0, 0), (0, 0, 0))
    with pytest.raises(AnatomeshError, match="build volume"):
        plan_cuts(ball, (60, -1, 60))


def test_cube_fits_a_smaller_volume_in_eight_pieces():
    cube = _mesh(*box((0, 0, 0), (100, 100, 100), 8), name="cube")
    pieces, info = fit_part(cube, (60, 60, 60))
    assert len(info["cuts"]) == 3 and sorted(c["axis"] for c in info["cuts"]) == ["x", "y", "z"]
    assert [p.name for p in pieces] == [f"cube_{k}" for k in range(1, 9)]
    for p in pieces:
        _solid(p)
        assert fits(np.ptp(np.asarray(p.vertices), axis=0), (60, 60, 60))
    assert sum(r["volume_mm3"] for r in info["pieces"]) == pytest.approx(1e6, rel=1e-4)
    # a long bar fits lying along the volume's long side: no cut
    bar = _mesh(*box((0, 0, 0), (30, 50, 100), 2), name="bar")
    assert plan_cuts(bar, (120, 60, 40)) == [] and fit_to_volume(bar, (120, 60, 40))[0].name == "bar"


def test_cut_goes_where_the_cross_section_is_smallest():
    # two 40 mm balls joined by a thin neck along x: the one cut goes through the neck
    a, b = icosphere(4, 20.0), icosphere(4, 20.0)
    neck = box((-2, -3, -3), (62, 3, 3), 2)
    parts = [(a[0], a[1]), (b[0] + [60, 0, 0], b[1]), neck]
    v, f, n = [], [], 0
    for pv, pf in parts:
        v.append(pv)
        f.append(pf + n)
        n += len(pv)
    dumbbell = _mesh(np.concatenate(v), np.concatenate(f), name="dumbbell")
    cuts = plan_cuts(dumbbell, (60, 60, 60))
    assert len(cuts) == 1 and cuts[0][0] == 0 and 20 < cuts[0][1] < 40  # the neck, between the balls


@pytest.fixture(scope="module")
def liver():
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.io.load import load
    from anatomesh.core.smooth.driver import smooth_surfaces

    vol = load(SAMPLE / "example_seg.nii.gz")
    value = next(k for k, lab in vol.labels.items() if lab.name == "liver")
    sm, _ = smooth_surfaces(label_surfaces(vol, values=[value]), "organ", distances=False)
    return sm.shells()[0]


def test_real_liver_cut_to_fit_120_mm(liver, tmp_path):
    ext = np.ptp(np.asarray(liver.vertices), axis=0)
    assert not fits(ext, (120, 120, 120))
    pieces, info = fit_part(liver, (120, 120, 120), connectors=True)
    assert len(pieces) >= 2 and all(r["fits"] for r in info["pieces"])
    assert sum(r["volume_mm3"] for r in info["pieces"]) == pytest.approx(info["volume_mm3"], rel=0.001)
    assert any(j["pins"] for j in info["connectors"])
    for p in pieces:
        _solid(p)
        assert fits(np.ptp(np.asarray(p.vertices), axis=0), (120, 120, 120))
    if PRUSA is None:
        pytest.skip("prusa-slicer (Debian package) is not installed: the pieces' manifold check by it is skipped")
    for p in pieces:
        stl = tmp_path / f"{p.name}.stl"
        write_stl(p, stl)
        res = subprocess.run([PRUSA, "--info", str(stl)], capture_output=True, text=True, timeout=300)
        assert "manifold = yes" in res.stdout, res.stdout
