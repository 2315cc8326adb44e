"""Benchmark: segmentations as users have them, on the real files in ../shared/data.

For each input: reading (``anatomesh.core.load``) and the whole run (``app.run.run``: extraction,
default "organ" smoothing, STL writing), best of N, plus the accuracy figures that have a ground
truth: DICOM SEG vs dcmqi's NRRD label maps (voxels differing), RTSTRUCT sts_001 vs MIRP's mask
(voxels differing, rasterised on the CT grid), raster vs tiled volume of every RT ROI.

Run: ``python benchmarks/bench_segmentations.py [N]`` (default N = 3). Timings are noisy on a
shared machine: compare them with each other, not across machines.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
INPUTS = [
    ("TotalSegmentator aorta folder (9 masks + CT)", DATA / "totalsegmentator/aorta", {}),
    ("TotalSegmentator pulmonary (2 grids)", DATA / "totalsegmentator/pulmonary", {}),
    ("DICOM SEG liver (CT folder)", DATA / "dicom_seg/dcmqi_ct3slice/liver.dcm", {}),
    ("DICOM SEG 5 overlapping segments", DATA / "dicom_seg/dcmqi_ct3slice/partial_overlaps.dcm", {}),
    ("DICOM SEG JPEG 2000", DATA / "dicom_seg/dcmqi_ct3slice/variants/liver_j2k.dcm", {}),
    ("RTSTRUCT sts_001 folder (raster)", DATA / "rtstruct/sts_001", {}),
    ("RTSTRUCT sts_001 folder (tile)", DATA / "rtstruct/sts_001", {"contours": "tile"}),
    ("RTSTRUCT breast, 10 ROIs (raster)", DATA / "rtstruct/dicompyler_breast/rtss.dcm", {}),
    ("RTSTRUCT breast, 10 ROIs (tile)", DATA / "rtstruct/dicompyler_breast/rtss.dcm", {"contours": "tile"}),
]


def best(fn, n):
    t = []
    for _ in range(n):
        t0 = time.perf_counter()
        out = fn()
        t.append(time.perf_counter() - t0)
    return min(t), out


def main(n: int = 3) -> None:
    import warnings

    warnings.simplefilter("ignore")
    from anatomesh.app.flow.recipe import Recipe
    from anatomesh.app.flow.run import run
    from anatomesh.core import load

    print(f"{'input':<46} {'read s':>8} {'run s':>8} surfaces")
    for name, path, extra in INPUTS:
        t_read, _ = best(lambda: load(path), n)
        with tempfile.TemporaryDirectory() as tmp:
            t_run, res = best(lambda: run(Recipe(input=str(path), out_dir=tmp, overwrite=True, **extra)), n)
        closed = sum(1 for s in res.report["surfaces"] if s["closed"])
        print(f"{name:<46} {t_read:8.2f} {t_run:8.2f} {len(res.surfaces)} ({closed} closed)")
    accuracy()


def accuracy() -> None:
    import nibabel as nib
    import pydicom

    from anatomesh.core import load
    from anatomesh.core.extract.contours import tile_roi
    from anatomesh.core.io.contour_raster import contour_grid, rasterise_roi
    from anatomesh.core.io.dicom import scan_dicom
    from anatomesh.core.io.dicom_objects import reference_grid
    from anatomesh.core.io.nrrd import read_nrrd
    from anatomesh.core.io.rtstruct import read_rois
    from anatomesh.core.model.mesh import signed_volume
    from anatomesh.core.model.segmentation import as_layers

    seg = load(DATA / "dicom_seg/dcmqi_ct3slice/liver.dcm")
    truth = read_nrrd(DATA / "dicom_seg/dcmqi_ct3slice/labelmaps/liver_seg.nrrd", label_map=True)
    print(f"SEG liver vs dcmqi NRRD: {int(((seg.data == 1) != (truth.data == 1)).sum())} voxels differ "
          f"of {int((truth.data == 1).sum())}")
    sts = DATA / "rtstruct/sts_001"
    ds = pydicom.dcmread(sts / "RS.dcm")
    ref = reference_grid(scan_dicom(sts), ds, "RTSTRUCT")
    rois, _ = read_rois(ds, sts / "RS.dcm", np.cross(ref.plane["row"], ref.plane["col"]))
    grid = contour_grid(rois, ref, True, factor=1)
    m = rasterise_roi(rois[0], grid)
    full = np.zeros(ref.shape, bool)
    lo = np.round((np.linalg.inv(ref.affine) @ grid.affine)[:3, 3]).astype(int) + np.asarray(m.offset)
    full[lo[0]:lo[0] + m.data.shape[0], lo[1]:lo[1] + m.data.shape[1], lo[2]:lo[2] + m.data.shape[2]] = m.data
    mirp = np.asanyarray(nib.load(str(sts / "reference_mask.nii.gz")).dataobj) > 0
    print(f"RTSTRUCT sts_001 vs MIRP mask: {int((full != mirp).sum())} voxels differ of {int(mirp.sum())}")
    for path in (sts / "RS.dcm", DATA / "rtstruct/dicompyler_breast/rtss.dcm"):
        vol = load(path)
        vox = {v: int((lay.data == v).sum()) * lay.voxel_volume_mm3() for lay in as_layers(vol) for v in lay.labels}
        for roi in vol.meta["contours"]:
            t0 = time.perf_counter()
            mesh = tile_roi(roi)
            dt = time.perf_counter() - t0
            tv = signed_volume(mesh.vertices, mesh.faces)
            print(f"  {roi.info.name:<18} raster {vox[roi.info.value]:12.0f} mm3  tiled {tv:12.0f} mm3  "
                  f"({100 * (tv / vox[roi.info.value] - 1):+.1f} %, tiling {dt:.2f} s)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
