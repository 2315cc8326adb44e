"""Hollowing with drain holes: a ball's shell has the chosen wall everywhere (the inner surface
never crosses the outer one, checked by our intersection test and pymeshlab's), drain holes at
the lowest points, the volume saved is the inner ball's; a real kidney hollowed stays closed and
manifold and PrusaSlicer reads it without repairs."""
import shutil
import subprocess

import numpy as np
import pytest
from conftest import SAMPLE
from helpers.meshes import icosphere

from anatomesh.core.export.mesh_files import write_stl
from anatomesh.core.geometry.intersections import self_intersections
from anatomesh.core.geometry.spatial import TriangleGrid
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh, degenerate_faces
from anatomesh.core.printing.hollow import hollow
from anatomesh.core.printing.offset import inner_offset

PRUSA = shutil.which("prusa-slicer")


def test_inner_offset_of_a_ball_is_the_smaller_ball_facing_inward():
    v, f = icosphere(4, 10.0)
    vi, fi, h = inner_offset(v, f, 2.0)
    t = topology(vi, fi)
    assert t.closed and t.manifold and t.oriented and t.components == 1 and t.genus == 0
    r = np.linalg.norm(vi, axis=1)
    # the icosphere's flat facets lie up to 0.06 mm inside its 10 mm sphere
    assert r.min() > 8.0 - 0.1 * h - 0.1 and r.max() < 8.0 + 0.02
    from anatomesh.core.model.mesh import signed_volume
    assert signed_volume(vi, fi) == pytest.approx(-4 / 3 * np.pi * 8 ** 3, rel=0.03)  # faces inward
    assert inner_offset(v, f, 6.0)[1].shape == (0, 3)  # thinner than two walls: no cavity


def test_hollow_ball_wall_holes_and_volume_saved():
    v, f = icosphere(4, 12.0)
    out, info = hollow(Mesh(v, f, name="ball"), 2.0, holes=2, hole_diameter=3.0)
    ov, of = out.vertices.astype(np.float64), out.faces
    t = topology(ov, of)
    # one solid: the outer sphere and the cavity joined by two tubes (genus 1)
    assert t.closed and t.manifold and t.oriented and t.components == 1 and t.genus == 1
    assert self_intersections(ov, of).shape == (0, 2) and degenerate_faces(ov, of, 1e-10).size == 0
    assert info["cavities"] == 1 and len(info["drain_holes"]) == 2
    assert info["saved_mm3"] == pytest.approx(4 / 3 * np.pi * 10 ** 3, rel=0.03)
    # the holes are at the lowest points (-z), the first at the very bottom
    z = [h["location"][2] for h in info["drain_holes"]]
    assert z[0] < -11.9 and z[1] < -6
    # the cavity stays a full wall away from the outer surface, except at the drain tubes
    cavity = np.linalg.norm(ov, axis=1) < 11.0
    d, _, _ = TriangleGrid(v, f).closest(ov[cavity])
    away = np.all(np.linalg.norm(ov[cavity][:, None] - np.array([h["location"] for h in info["drain_holes"]])[None],
                                 axis=2) > 4.0, axis=1)
    assert d[away].min() >= 2.0 - 0.02


def test_hollow_needs_sensible_holes():
    v, f = icosphere(3, 10.0)
    with pytest.raises(AnatomeshError):
        hollow(Mesh(v, f), 2.0, holes=2, hole_diameter=0)
    with pytest.raises(AnatomeshError):
        hollow(Mesh(v, f), -1.0)


def test_pymeshlab_sees_one_closed_manifold_shell_without_self_intersections():
    import pymeshlab as ml

    v, f = icosphere(4, 12.0)
    out, _ = hollow(Mesh(v, f, name="ball"), 2.0, holes=2, hole_diameter=3.0)
    ms = ml.MeshSet()
    ms.add_mesh(ml.Mesh(out.vertices.astype(np.float64), out.faces.astype(np.int32)))
    topo = ms.get_topological_measures()
    assert topo["boundary_edges"] == 0 and topo["non_two_manifold_edges"] == 0
    assert topo["connected_components_number"] == 1 and topo["genus"] == 1
    ms.compute_selection_by_self_intersections_per_face()
    assert ms.current_mesh().selected_face_number() == 0


def test_real_kidney_hollowed_reads_clean_in_prusaslicer(tmp_path):
    from anatomesh.core.extract.multilabel import label_surfaces
    from anatomesh.core.io.load import load
    from anatomesh.core.smooth.driver import smooth_surfaces

    vol = load(SAMPLE / "example_seg.nii.gz")
    value = next(k for k, lab in vol.labels.items() if lab.name == "kidney_right")
    sm, _ = smooth_surfaces(label_surfaces(vol, values=[value]), "organ", distances=False)
    kidney = sm.shells()[0]
    out, info = hollow(kidney, 2.0, holes=2, hole_diameter=3.0)
    t = topology(out.vertices, out.faces)
    assert t.closed and t.manifold and t.oriented and t.components == 1
    assert self_intersections(out.vertices.astype(np.float64), out.faces).shape == (0, 2)
    assert 40 < info["saved_pct"] < 90 and len(info["drain_holes"]) == 2
    if PRUSA is None:
        pytest.skip("prusa-slicer (Debian package) is not installed")
    stl = tmp_path / "kidney.stl"
    write_stl(out, stl)
    res = subprocess.run([PRUSA, "--info", str(stl)], capture_output=True, text=True, timeout=300)
    assert "manifold = yes" in res.stdout and "degenerate_facets" not in res.stdout, res.stdout
    assert float(res.stdout.split("volume = ")[1].split()[0]) == pytest.approx(info["volume_after_mm3"], rel=0.01)
