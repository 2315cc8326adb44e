"""Connectors across the interface of two touching parts: pins on A, pockets wider and deeper by
the clearance in B; both stay closed solids; the pins' volume is added to A and the pockets'
taken from B; pin and pocket walls are the clearance apart."""
import json

import numpy as np
import pytest

from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.geometry.intersections import self_intersections
from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.model.volume import Volume
from anatomesh.core.printing.connectors import add_connectors, interface_faces


@pytest.fixture(scope="module")
def blocks():
    d = np.zeros((44, 24, 24), np.int16)
    d[2:22, 2:22, 2:22] = 1   # A: 20 mm cube
    d[22:42, 2:22, 2:22] = 2  # B beside it: a 20 x 20 mm interface at x = 21.5
    return label_surfaces(Volume(d, np.eye(4))).shells()


def test_pins_and_pockets_keep_both_parts_solid(blocks):
    a0, b0 = blocks
    assert interface_faces(a0, b0).size == 2 * 20 * 20
    a, b, info = add_connectors(a0, b0, clearance=0.2, diameter=5.0)
    pins = info["pins"]
    assert len(pins) == 2
    first = pins[0]
    assert first["location"] == pytest.approx([21.5, 11.5, 11.5], abs=0.7)  # the interface's centre
    assert first["diameter_mm"] == 5.0 and first["pocket_diameter_mm"] == pytest.approx(5.4)
    assert first["pocket_depth_mm"] == pytest.approx(first["length_mm"] + 0.2 + 0.05 * 2.5, abs=0.3)
    for m in (a, b):
        t = topology(m.vertices, m.faces)
        assert t.closed and t.manifold and t.oriented and t.components == 1 and t.genus == 0
        assert self_intersections(m.vertices.astype(np.float64), m.faces).shape == (0, 2)
    pin_vol = sum(np.pi * (p["diameter_mm"] / 2) ** 2 * p["length_mm"] for p in pins)
    pocket_vol = sum(np.pi * (p["pocket_diameter_mm"] / 2) ** 2 * p["pocket_depth_mm"] for p in pins)
    assert signed_volume(a.vertices, a.faces) - signed_volume(a0.vertices, a0.faces) == pytest.approx(pin_vol, rel=0.05)
    assert signed_volume(b0.vertices, b0.faces) - signed_volume(b.vertices, b.faces) == pytest.approx(pocket_vol, rel=0.05)
    # the pins stand in the pockets with the clearance all round (away from the interface plane)
    va = a.vertices.astype(np.float64)
    pin_pts = va[(va[:, 0] > 22.0) & (va[:, 0] < 21.5 + first["length_mm"] - 0.1)]
    d, _, _ = TriangleGrid(b.vertices, b.faces).closest(pin_pts)
    assert d.min() == pytest.approx(0.2, abs=0.03)


def test_parts_that_do_not_touch_get_no_connectors(blocks):
    a0, b0 = blocks
    far = type(b0)(b0.vertices + 50.0, b0.faces, name="far")
    with pytest.raises(AnatomeshError, match="share no interface"):
        add_connectors(a0, far, 0.2)


def test_prusaslicer_reads_both_connected_parts_as_manifold(blocks, tmp_path):
    """The connected parts load in PrusaSlicer's command line as manifold solids."""
    import shutil
    import subprocess

    from anatomesh.core.export.mesh_files import write_stl

    a, b, _ = add_connectors(*blocks, clearance=0.2, diameter=5.0)
    prusa = shutil.which("prusa-slicer")
    if prusa is None:
        pytest.skip("prusa-slicer (Debian package) is not installed: its manifold check is skipped")
    for m, name in ((a, "pins"), (b, "pockets")):
        stl = tmp_path / f"{name}.stl"
        write_stl(m, stl)
        res = subprocess.run([prusa, "--info", str(stl)], capture_output=True, text=True, timeout=300)
        assert "manifold = yes" in res.stdout, res.stdout


# ---------------------------------------------------------------------------------------------
# the print check on connected parts: a pin in its pocket is contact, not a crossing
# ---------------------------------------------------------------------------------------------
def test_pins_in_their_pockets_are_not_crossings_but_overlaps_next_to_them_are(blocks):
    from anatomesh.core.model.mesh import Mesh
    from anatomesh.core.printing import checks as pc
    from anatomesh.core.printing.solid import part_intersections

    a, b, info = add_connectors(*blocks, clearance=0.2, diameter=5.0)
    rep = pc.check_parts([a, b], "fdm")
    assert rep["intersections"] == [] and rep["passed"], [p["reasons"] for p in rep["parts"]]
    (gap,) = rep["gaps"]
    assert gap["touching"] and not gap["fuses"] and not gap["intersecting"]
    # a pin without its pocket overlaps the other part: reported where the pins are
    (c,) = part_intersections([a, blocks[1]])
    pins = np.array([p["location"] for p in info["pins"]])
    assert min(np.linalg.norm(pins - c["location"], axis=1)) < 6.0
    assert c["location"][0] > 21.5  # inside the second block, where the pins stand
    # the pocket part pushed 0.5 mm into the pin part: the overlap is reported, pins and all
    pushed = Mesh(b.vertices - np.array([0.5, 0, 0], np.float32), b.faces, name=b.name)
    rep = pc.check_parts([a, pushed], "fdm")
    (c,) = rep["intersections"]
    assert not rep["passed"] and c["faces_a"] > 100 and 20.5 < c["location"][0] < 24.0


def test_touching_faces_are_told_from_crossing_faces():
    """Face pairs of two parts that only touch: a shared plane triangulated differently on each
    side, a face meeting another along an edge; crossing: coplanar with the same normal (one
    part inside the other) or reaching into the other part."""
    from anatomesh.core.geometry.intersections import crossing_pairs
    from anatomesh.core.geometry.spatial import TriangleGrid
    from anatomesh.core.printing.solid import touching_pairs
    from helpers.meshes import box

    lower = box((0, 0, 0), (6, 6, 3), 3)   # top face z = 3 split into 3 x 3 squares
    upper = box((0, 0, 3), (6, 6, 5), 4)   # bottom face z = 3 split into 4 x 4 squares
    rv, rf = box((1, -1, -1), (5, 1, 1), 2)
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    rv = rv @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T + [0, 3, 3 + np.sqrt(2)]
    on_edge = (rv, rf)                      # a box resting on lower along one of its edges
    sunk = box((1, 1, 2.5), (5, 5, 4), 2)  # reaches 0.5 mm into lower
    assert np.isclose(rv[:, 2].min(), 3.0)
    for (p, q), touching in (((lower, upper), True), ((lower, on_edge), True), ((lower, sunk), False)):
        cr = crossing_pairs([p, q])
        assert len(cr.pairs), "the coplanar faces are found as a crossing by the face test"
        flags = touching_pairs(cr, [TriangleGrid(*p), TriangleGrid(*q)])
        assert flags.all() if touching else not flags.all()
    # a box lying inside the other against its top face: coplanar, same normal, overlapping
    nested = box((1, 1, 1), (5, 5, 3), 2)
    cr = crossing_pairs([lower, nested])
    flags = touching_pairs(cr, [TriangleGrid(*lower), TriangleGrid(*nested)])
    assert len(flags) and not flags.any()


@pytest.fixture(scope="module")
def vertebrae():
    """L1 and L2 of the 61-label TotalSegmentator map, smoothed as `anatomesh mesh` does: two
    touching labels sharing a curved interface."""
    from conftest import shared

    from anatomesh.core import label_surfaces, load
    from anatomesh.core.smooth.driver import smooth_surfaces

    names = json.loads(shared("totalsegmentator", "label_names_total_and_total_mr.json").read_text())["total"]
    value = {n: int(k) for k, n in names.items()}
    vol = load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz"))
    sm, _ = smooth_surfaces(label_surfaces(vol, values=[value["vertebrae_L1"], value["vertebrae_L2"]]),
                            "organ", distances=False)
    by_value = {int(m.value): m for m in sm.shells()}
    l1, l2 = by_value[value["vertebrae_L1"]], by_value[value["vertebrae_L2"]]
    l1.name, l2.name = "vertebrae_L1", "vertebrae_L2"
    return l1, l2


def test_real_vertebrae_with_pins_pass_the_print_check(vertebrae):
    from anatomesh.core.printing import checks as pc
    from anatomesh.core.printing.solid import part_intersections

    l1, l2 = vertebrae
    assert pc.check_parts([l1, l2], "fdm")["intersections"] == []
    a, b, info = add_connectors(l1, l2, clearance=0.2)
    assert len(info["pins"]) == 2
    rep = pc.check_parts([a, b], "fdm")
    assert rep["intersections"] == [], rep["intersections"]
    for p in rep["parts"]:
        assert p["part_intersections"] == 0 and p["self_intersections"] == 0, p["reasons"]
    (gap,) = rep["gaps"]
    assert gap["touching"] and not gap["fuses"]
    # each pocket stays inside L2 with a wall around it: it breaks out nowhere
    assert self_intersections(b.vertices.astype(np.float64), b.faces).shape == (0, 2)
    # the pins pushed into L2 without their pockets: a crossing, where the pins are
    (c,) = part_intersections([a, l2])
    pins = np.array([p["location"] for p in info["pins"]])
    faces = a.vertices[a.faces[c["faces_a"]]].mean(axis=1)
    assert np.all(np.min(np.linalg.norm(faces[:, None] - pins[None], axis=2), axis=1) < 10.0)
