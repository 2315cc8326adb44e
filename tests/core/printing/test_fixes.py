"""Print fixes with known answers: tiny shells, small holes, separating touching labels by a
clearance, fusing labels (in the SurfaceSet and in the label map), thickening thin labels."""
from pathlib import Path

import numpy as np
import pytest
from helpers.meshes import box

from anatomesh.core.printing.gaps import part_gaps
from anatomesh.core.printing.solid import part_intersections
from anatomesh.core.printing.thickness import wall_thickness
from anatomesh.core.printing import fixes as fx
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.model.mesh import Mesh, signed_volume, weld_ids
from anatomesh.core.geometry.intersections import self_intersections
from anatomesh.core.geometry.topology import topology
from anatomesh.core.model.volume import Volume

SAMPLE_SEG = Path(__file__).resolve().parents[3] / "data" / "sample" / "example_seg.nii.gz"


def solid(m):
    t = topology(m.vertices, m.faces)
    return t.closed and t.manifold and t.oriented


def blocks_volume(spacing=(1.0, 1.0, 1.0)):
    """Labels 1 and 2 side by side (touching over a 6 x 6 voxel face), label 3 on top of both
    (a junction line where all three meet), 1 mm voxels unless ``spacing``."""
    d = np.zeros((16, 10, 12), np.int16)
    d[2:8, 2:8, 2:8] = 1
    d[8:14, 2:8, 2:8] = 2
    d[4:12, 3:7, 8:10] = 3
    a = np.diag(list(spacing) + [1.0])
    a[:3, 3] = (-20.0, 5.0, 40.0)
    return Volume(d, a)


# ---------------------------------------------------------------------------------------------
def test_remove_tiny_reports_the_removed_volume():
    v, f = box((0, 0, 0), (8, 8, 8), 2)
    tv, tf = box((20, 0, 0), (20.5, 0.5, 0.5), 1)
    m = Mesh(np.concatenate([v, tv]), np.concatenate([f, tf + len(v)]), name="c")
    out, info = fx.remove_tiny(m, 1.0)
    assert info["removed"] == 1 and info["volumes_mm3"] == [pytest.approx(0.125)]
    assert out.n_faces == len(f) and signed_volume(out.vertices, out.faces) == pytest.approx(512)
    same, info = fx.remove_tiny(m, 0.1)
    assert info["removed"] == 0 and same.n_faces == m.n_faces
    with pytest.raises(AnatomeshError):
        fx.remove_tiny(m, -1)


def test_close_holes_fills_small_loops_only():
    v, f = box((0, 0, 0), (8, 8, 8), 4)
    z = v[f][:, :, 2]
    top = np.flatnonzero(np.all(z == 8, axis=1))
    partner = top[[len(np.intersect1d(f[t], f[top[0]])) == 2 for t in top]][0]
    m = Mesh(v, np.delete(f, [top[0], partner], axis=0), name="c")  # a 4-edge hole (one quad)
    out, info = fx.close_holes(m, 8)
    assert info["closed"] == 1 and info["added_faces"] == 4 and info["left_open"] == 0
    assert solid(out) and signed_volume(out.vertices, out.faces) == pytest.approx(512)
    assert info["locations"][0][2] == pytest.approx(8.0)
    big = Mesh(v, np.delete(f, top, axis=0), name="open top")  # the whole 16-edge top is open
    out, info = fx.close_holes(big, 8)
    assert info["closed"] == 0 and info["left_open"] == 1 and out.n_faces == big.n_faces
    out, info = fx.close_holes(big, 16)
    assert info["closed"] == 1 and solid(out)
    assert signed_volume(out.vertices, out.faces) == pytest.approx(512)


@pytest.mark.parametrize("clearance", [0.4, 1.0])
def test_separate_parts_opens_every_seam_by_the_clearance(clearance):
    s = label_surfaces(blocks_volume())
    before = part_gaps(s.shells(), min_gap=0.5)
    assert {(g["a"], g["b"]) for g in before if g["touching"]} == {
        ("label_1", "label_2"), ("label_1", "label_3"), ("label_2", "label_3")}
    parts, info = fx.separate_parts(s, clearance)
    assert info["pairs"] == [[1, 2], [1, 3], [2, 3]] and info["moved_vertices"] > 0
    allv = np.concatenate([p.vertices for p in parts])
    owner = np.repeat(np.arange(len(parts)), [p.n_vertices for p in parts])
    wid = weld_ids(allv)
    assert all(np.unique(owner[wid == w]).size == 1 for w in np.unique(wid))  # no shared vertex
    for p in parts:
        assert solid(p)
        assert self_intersections(p.vertices, p.faces).shape[0] == 0
    gaps = part_gaps(parts, min_gap=clearance)
    assert len(gaps) == 3 and not any(g["touching"] for g in gaps)
    # the flat 1|2 interface opens by exactly the clearance; where 3 sits on 1 and 2 the other
    # part's surface runs on past the interface's rim: the bevel there would narrow the gap to
    # clearance * sqrt(2/3), and the rim vertices are pushed apart to the clearance
    gap = {(g["a"], g["b"]): g["min_gap_mm"] for g in gaps}
    assert gap[("label_1", "label_2")] == pytest.approx(clearance, abs=0.01)
    for g in gaps:
        assert g["min_gap_mm"] >= 0.95 * clearance, g
    assert not part_intersections(parts)


def test_separate_parts_only_between_chosen_labels():
    s = label_surfaces(blocks_volume())
    parts, info = fx.separate_parts(s, 0.6, labels=[1, 2])
    assert info["pairs"] == [[1, 2]]
    gaps = {(g["a"], g["b"]): g for g in part_gaps(parts)}
    # 1 and 2 share no face any more; where label 3 (not chosen) meets both, the junction
    # line stays put, so they still meet along it
    g12 = gaps[("label_1", "label_2")]
    assert g12["seam_area_mm2"] == 0 and g12["clearance_mm"] >= np.sqrt(2 / 3) * 0.6 - 0.01
    for pair in (("label_1", "label_3"), ("label_2", "label_3")):
        assert gaps[pair]["touching"] and gaps[pair]["seam_area_mm2"] == pytest.approx(16.0)
    with pytest.raises(AnatomeshError):
        fx.separate_parts(s, 0.0)


def test_fuse_parts_and_fuse_labels_give_the_same_closed_solid():
    vol = blocks_volume(spacing=(0.8, 1.0, 1.5))
    s = label_surfaces(vol)
    fused, info = fx.fuse_parts(s, [1, 2], name="block")
    assert info["labels"] == [1, 2] and info["dropped_faces"] == 2 * 6 * 6
    assert solid(fused) and topology(fused.vertices, fused.faces).components == 1
    voxel = 0.8 * 1.0 * 1.5
    assert signed_volume(fused.vertices, fused.faces) == pytest.approx(2 * 216 * voxel, rel=1e-6)
    merged, info = fx.fuse_labels(vol, [1, 2])
    assert info == {"labels": [1, 2], "into": 1, "voxels": 2 * 216}
    assert set(np.unique(merged.data)) == {0, 1, 3} and set(np.unique(vol.data)) == {0, 1, 2, 3}
    shell = label_surfaces(merged).shell(1)
    assert signed_volume(shell.vertices, shell.faces) == pytest.approx(
        signed_volume(fused.vertices, fused.faces), rel=1e-6)
    with pytest.raises(AnatomeshError):
        fx.fuse_parts(s, [1, 7])


def test_thicken_labels_brings_a_thin_plate_to_the_minimum_wall():
    # a 0.5 mm plate (one voxel of 0.5 mm) on a thick block, anisotropic voxels
    d = np.zeros((40, 30, 24), np.int16)
    d[5:35, 5:25, 4:6] = 1   # thick base: 1 mm
    d[5:35, 5:25, 6:20] = 0
    d[18:19, 5:25, 6:20] = 1  # fin: 1 voxel = 0.5 mm thick in x
    d[2:6, 2:6, 2:6] = 2     # another label: untouched
    a = np.diag([0.5, 0.5, 0.5, 1.0])
    vol = Volume(d, a)

    def fin_wall(v):
        m = label_surfaces(v).shell(1)
        t = wall_thickness(m.vertices, m.faces, max_thickness=5.0)
        on_fin = (m.vertices[:, 2] > 0.5 * 8) & (m.vertices[:, 2] < 0.5 * 17)  # fin, away from ends
        return np.nanmin(t[on_fin]), np.nanmedian(t[on_fin])

    lo, med = fin_wall(vol)
    assert med == pytest.approx(0.5, abs=0.15)
    thick, info = fx.thicken_labels(vol, 1.2)
    assert info["labels"].get(1, 0) > 0 and 2 not in info["labels"]
    assert np.array_equal(thick.data == 2, vol.data == 2)
    assert np.all(thick.data[vol.data == 1] == 1)  # only grows
    lo, med = fin_wall(thick)
    assert lo >= 1.2 - 0.25 and med >= 1.2 - 0.15
    with pytest.raises(AnatomeshError):
        fx.thicken_labels(vol, 0)


def test_clearance_holds_at_the_rim_of_a_smoothed_interface():
    """The sample's liver and gallbladder, smoothed: pulled 0.4 mm apart, the rim of their
    interface (where the gallbladder's outer surface runs on past the liver at a shallow angle)
    kept 0.13 mm before the rim step; now every sampled point is >= 0.38 mm from the other part,
    both stay solid, and neither crosses itself or the other."""
    from anatomesh.core.geometry.measure import point_to_surface, sample_points
    from anatomesh.core.io import load
    from anatomesh.core.smooth.driver import smooth_surfaces

    vol = load(str(SAMPLE_SEG))
    liver, gall = (next(v for v, i in vol.labels.items() if i.name == n) for n in ("liver", "gallbladder"))
    smoothed, _ = smooth_surfaces(label_surfaces(vol, values=[liver, gall]))
    parts, info = fx.separate_parts(smoothed, 0.4)
    assert info["pairs"] == [sorted([liver, gall])] and info["rim_vertices"] > 0
    a, b = parts
    gap = min(point_to_surface(sample_points(a.vertices, a.faces), b.vertices, b.faces).min(),
              point_to_surface(sample_points(b.vertices, b.faces), a.vertices, a.faces).min())
    assert gap >= 0.38
    for p in parts:
        assert solid(p) and self_intersections(p.vertices, p.faces).shape[0] == 0
    assert not part_intersections(parts)
