"""Connectors across the interface of two touching parts: pins on A, pockets wider and deeper by
the clearance in B; both stay closed solids; the pins' volume is added to A and the pockets'
taken from B; pin and pocket walls are the clearance apart."""
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
