"""What a batch's INPUTS name (folder, manifest, glob) and how much memory a study needs, read
from headers only; the progress text."""
import shutil

import nibabel as nib
import numpy as np
import pytest

from anatomesh.app.batch import memory
from anatomesh.app.batch.progress import BatchProgress
from anatomesh.app.batch.studies import find_studies, parse_labels, study_id
from anatomesh.core.io import load
from anatomesh.core.model.errors import AnatomeshError
from conftest import shared

SEG = ("totalsegmentator", "example_seg.nii.gz")


def test_folder_of_studies_files_subfolders_and_totalsegmentator_layout(tmp_path):
    shutil.copy(shared(*SEG), tmp_path / "s01.nii.gz")
    shutil.copy(shared("pyradiomics_brain1", "brain1_label.nrrd"), tmp_path / "tumour 2.nrrd")
    (tmp_path / "s03" / "segmentations").mkdir(parents=True)       # TotalSegmentator dataset layout
    (tmp_path / "s03" / "ct.nii.gz").write_bytes(b"")
    (tmp_path / "s04").mkdir()                                     # --ml output beside the CT
    (tmp_path / "s04" / "segmentations.nii.gz").write_bytes(b"")
    (tmp_path / "s05_dicom").mkdir()                                # read as it is (DICOM, masks)
    (tmp_path / "README.md").write_text("no study")
    (tmp_path / ".hidden").mkdir()
    studies = find_studies(tmp_path)
    assert [(s.id, s.path) for s in studies] == [
        ("s01", str(tmp_path / "s01.nii.gz")),
        ("s03", str(tmp_path / "s03" / "segmentations")),
        ("s04", str(tmp_path / "s04" / "segmentations.nii.gz")),
        ("s05_dicom", str(tmp_path / "s05_dicom")),
        ("tumour_2", str(tmp_path / "tumour 2.nrrd"))]


def test_a_totalsegmentator_mask_folder_is_one_study_not_many(tmp_path):
    for organ in ("liver", "spleen", "kidney_left", "aorta"):
        (tmp_path / f"{organ}.nii.gz").write_bytes(b"")
    with pytest.raises(AnatomeshError, match="one TotalSegmentator output folder"):
        find_studies(tmp_path)


def test_manifest_csv_without_header_and_bad_rows(tmp_path):
    (tmp_path / "m.csv").write_text("a,x/a.nii.gz,\"liver, spleen\"\nb,/abs/b.nrrd\n\n# done\n")
    studies = find_studies(tmp_path / "m.csv")
    assert [(s.id, s.path, s.labels) for s in studies] == [
        ("a", str(tmp_path / "x" / "a.nii.gz"), ("liver", "spleen")), ("b", "/abs/b.nrrd", None)]
    (tmp_path / "bad.csv").write_text("id,path\nonly-an-id\n")
    with pytest.raises(AnatomeshError, match="line 2"):
        find_studies(tmp_path / "bad.csv")
    (tmp_path / "dup.csv").write_text("a,1.nii.gz\na,2.nii.gz\n")
    with pytest.raises(AnatomeshError, match="two studies get the id 'a'"):
        find_studies(tmp_path / "dup.csv")


def test_glob_ids_are_the_parts_that_differ(tmp_path):
    for case in ("p1", "p2"):
        (tmp_path / "cohort" / case).mkdir(parents=True)
        (tmp_path / "cohort" / case / "seg.nii.gz").write_bytes(b"")
    studies = find_studies(str(tmp_path / "cohort" / "*" / "seg.nii.gz"))
    assert [(s.id, s.path) for s in studies] == [(c, str(tmp_path / "cohort" / c / "seg.nii.gz"))
                                                 for c in ("p1", "p2")]
    with pytest.raises(AnatomeshError, match="matches nothing"):
        find_studies(str(tmp_path / "cohort" / "*" / "none.nii.gz"))


def test_labels_and_ids():
    assert parse_labels("liver; spleen 3") == ("liver", "spleen", 3)
    assert parse_labels(" ALL ") == "all" and parse_labels("") is None
    assert study_id("case 01.seg.nrrd") == "case_01" and study_id("..") == "study"


@pytest.mark.parametrize("parts", [SEG, ("totalsegmentator", "example_seg_mr.nii.gz"),
                                   ("pyradiomics_brain1", "brain1_label.nrrd"), ("slicer_ctheadaxial",)])
def test_voxels_from_headers_match_the_volume(parts):
    path = shared(*parts)
    assert memory.volume_voxels(path) == int(np.prod(load(path).shape))


def test_voxels_of_a_mask_folder_and_the_estimate(tmp_path):
    img = nib.load(shared(*SEG))
    for name in ("liver", "spleen"):
        nib.save(nib.Nifti1Image((np.asarray(img.dataobj) == 5).astype(np.uint8), img.affine),
                 tmp_path / f"{name}.nii.gz")
    assert memory.volume_voxels(tmp_path) == 122 * 101 * 30
    assert memory.estimate_bytes(tmp_path) == memory.WORKER_BYTES + memory.BYTES_PER_VOXEL * 122 * 101 * 30
    assert memory.estimate_bytes(tmp_path / "missing.nii.gz") == memory.UNKNOWN_BYTES
    (tmp_path / "big.nhdr").write_text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 300 200 100\n"
                                       "encoding: raw\ndata file: big.raw\n")
    assert memory.volume_voxels(tmp_path / "big.nhdr") == 300 * 200 * 100  # no data file needed


def test_pool_size_keeps_to_cores_and_memory():
    gb = 2**30
    cores, free = memory.machine()
    assert cores >= 1 and free > 0
    assert memory.pool_size([3 * gb] * 4, workers=4, memory=7 * gb) == (2, 7 * gb)
    assert memory.pool_size([3 * gb] * 4, workers=1, memory=7 * gb) == (1, 7 * gb)
    assert memory.pool_size([9 * gb], workers=4, memory=7 * gb) == (1, 7 * gb)   # runs alone
    assert memory.pool_size([gb] * 2, workers=8, memory=64 * gb) == (2, 64 * gb)  # no idle workers


def test_progress_text_counts_eta_and_stages():
    seen = []
    bar = BatchProgress(10, done=3, failed=1, emit=lambda f, t: seen.append((f, t)))
    bar.stage("s7", 0.5, "smoothing (organ)")
    bar.finished("s7", ok=True)
    bar.stage("s8", 0.2, "reading")
    bar.finished("s8", ok=False)
    fraction, text = seen[-1]
    assert fraction == pytest.approx(0.6)
    assert text.startswith("4 done, 2 failed, 4 left, ETA ")
    bar.stage("s9", 0.1, "extracting surfaces")
    bar._last = 0.0  # let the next stage through at once
    bar.stage("s9", 0.2, "extracting surfaces")
    assert seen[-1][1].endswith("| s9: extracting surfaces")
