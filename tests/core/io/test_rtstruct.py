"""RTSTRUCT → surfaces: MIRP's sts_001 voxel mask reproduced exactly by the even-odd rasteriser,
contour points exactly where the file puts them, the breast case's 10 ROIs (holes, several pieces
per plane, an empty ROI, no CT series) meshed both ways and compared, bad contours refused with
the ROI and plane named."""
from __future__ import annotations

import numpy as np
import nibabel as nib
import pydicom
import pytest

from anatomesh.core import load
from anatomesh.core.extract.contours import tile_roi
from anatomesh.core.geometry.topology import topology
from anatomesh.core.io.contour_raster import contour_grid, rasterise_roi
from anatomesh.core.io.dicom import scan_dicom
from anatomesh.core.io.dicom_objects import reference_grid
from anatomesh.core.io.rtstruct import read_rois
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import signed_volume
from anatomesh.core.model.segmentation import as_layers
from conftest import shared

STS = shared("rtstruct", "sts_001")
BREAST = shared("rtstruct", "dicompyler_breast")


def test_sts001_rasterised_on_the_ct_grid_equals_mirp_mask():
    scan = scan_dicom(STS)
    ds = pydicom.dcmread(STS / "RS.dcm")
    ref = reference_grid(scan, ds, "RTSTRUCT")
    assert "shares its frame of reference" in ref.note  # referenced UIDs do not match: linked by FoR
    rois, _ = read_rois(ds, STS / "RS.dcm", np.cross(ref.plane["row"], ref.plane["col"]))
    grid = contour_grid(rois, ref, True, factor=1)
    mask = rasterise_roi(rois[0], grid)
    full = np.zeros(ref.shape, bool)
    shift = np.linalg.inv(ref.affine) @ grid.affine
    np.testing.assert_allclose(shift[:3, :3], np.eye(3), atol=1e-6)
    lo = np.round(shift[:3, 3]).astype(int) + np.asarray(mask.offset)
    hi = lo + np.asarray(mask.data.shape)
    full[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = mask.data
    truth = np.asanyarray(nib.load(str(STS / "reference_mask.nii.gz")).dataobj) > 0
    assert int(truth.sum()) == 117145
    np.testing.assert_array_equal(full, truth)


def test_sts001_folder_meshes_the_roi_with_its_name_and_colour():
    seg = load(STS)
    assert "meshing the RTSTRUCT object RS.dcm" in seg.meta["notes"][0]
    assert seg.labels[1].name == "GTV_Mass_CT" and seg.labels[1].color == (1.0, 0.0, 0.0)
    roi = seg.meta["contours"][0]
    assert len(roi.contours) == 32 and len(roi.plane_t) == 31
    m = tile_roi(roi)
    pts = {tuple(p) for p in np.concatenate(roi.contours).astype(np.float32)}
    assert all(tuple(v) in pts for v in m.vertices)  # exactly the contour points, LPS mm
    vox = int((seg.data == 1).sum()) * seg.voxel_volume_mm3()
    assert abs(signed_volume(m.vertices, m.faces) - vox) / vox < 0.02


def test_breast_rois_without_ct_series_both_ways():
    seg = load(BREAST / "rtss.dcm")
    assert "single slice" in " ".join(seg.meta["notes"])  # grid from ct.0's plane + contour planes
    assert any("Areola" in w and "skipped" in w for w in seg.warnings)
    names = [i.name for i in seg.labels.values()]
    assert names == ["BODY", "Borders", "Breast", "Heart", "Lt Lung", "Nodes", "Scar", "Tumor Bed",
                     "Tumor Bed Block"]
    assert seg.labels[5].color == pytest.approx((1.0, 128 / 255, 0.0), abs=0.01)  # Heart, ROIDisplayColor
    assert len(seg.layers) >= 2  # the lung and heart lie inside the body
    voxels = {v: int((layer.data == v).sum()) for layer in as_layers(seg) for v in layer.labels}
    for roi in seg.meta["contours"]:
        m = tile_roi(roi)
        topo = topology(m.vertices, m.faces)
        assert topo.closed and topo.manifold and topo.oriented, roi.info.name
        if len(set(roi.planes.tolist())) >= 10:
            raster = voxels[roi.info.value] * seg.layers[0].voxel_volume_mm3()
            assert abs(signed_volume(m.vertices, m.faces) - raster) / raster < 0.02, roi.info.name
    lung = next(r for r in seg.meta["contours"] if r.info.name == "Lt Lung")
    assert max(len(lung.on_plane(p)) for p in range(len(lung.plane_t))) == 7


def _edited(tmp_path, edit):
    ds = pydicom.dcmread(STS / "RS.dcm")
    item = ds.ROIContourSequence[0].ContourSequence[5]
    edit(item)
    path = tmp_path / "RS.dcm"
    ds.save_as(path)
    return path


def test_bad_contours_are_refused_naming_roi_and_plane(tmp_path):
    def open_contour(c):
        c.ContourGeometricType = "OPEN_PLANAR"

    def bow_tie(c):
        pts = np.asarray(c.ContourData, float).reshape(-1, 3)
        n = len(pts)
        pts[[n // 4, 3 * n // 4]] = pts[[3 * n // 4, n // 4]]
        c.ContourData = [f"{x:.4f}" for x in pts.ravel()]

    def off_plane(c):
        pts = np.asarray(c.ContourData, float).reshape(-1, 3)
        pts[:, 2] += 1.3
        c.ContourData = [f"{x:.4f}" for x in pts.ravel()]

    def tilted(c):
        pts = np.asarray(c.ContourData, float).reshape(-1, 3)
        pts[0, 2] += 2.0
        c.ContourData = [f"{x:.4f}" for x in pts.ravel()]

    for edit, words in ((open_contour, "not closed"), (bow_tie, "crosses itself"),
                        (off_plane, "off the slice lattice"), (tilted, "off any slice plane")):
        with pytest.raises(AnatomeshError, match=words) as err:
            load(_edited(tmp_path, edit))
        assert "GTV_Mass_CT" in str(err.value) or "plane" in str(err.value)
        assert "\n" not in str(err.value)
