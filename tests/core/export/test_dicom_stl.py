"""Surfaces back into the study: DICOM Encapsulated STL objects (PS3.3 A.85.1) in the source's study
and frame of reference, every required attribute present, the STL exact in LPS mm, and (when
Debian's dicom3tools is installed) dciodvfy finds no error."""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pydicom
import pytest

from anatomesh.core import load
from anatomesh.core.export.dicom_stl import ENCAPSULATED_STL, dicom_reference, write_encapsulated_stl
from anatomesh.core.extract.multilabel import label_surfaces
from anatomesh.core.io.mesh_files import read_stl
from conftest import shared

SEG = shared("dicom_seg", "dcmqi_ct3slice", "liver.dcm")

#: (keyword, type) of every Type 1 and Type 2 attribute of the IOD's modules that we fill
REQUIRED = [("PatientName", 2), ("PatientID", 2), ("PatientBirthDate", 2), ("PatientSex", 2),
            ("StudyInstanceUID", 1), ("StudyDate", 2), ("StudyTime", 2), ("ReferringPhysicianName", 2),
            ("StudyID", 2), ("AccessionNumber", 2), ("Modality", 1), ("SeriesInstanceUID", 1),
            ("SeriesNumber", 1), ("FrameOfReferenceUID", 1), ("PositionReferenceIndicator", 2),
            ("Manufacturer", 1), ("ManufacturerModelName", 1), ("DeviceSerialNumber", 1),
            ("SoftwareVersions", 1), ("InstanceNumber", 1), ("ContentDate", 2), ("ContentTime", 2),
            ("AcquisitionDateTime", 2), ("BurnedInAnnotation", 1), ("DocumentTitle", 2),
            ("ConceptNameCodeSequence", 2), ("MIMETypeOfEncapsulatedDocument", 1),
            ("EncapsulatedDocument", 1), ("EncapsulatedDocumentLength", 1),
            ("MeasurementUnitsCodeSequence", 1), ("SOPClassUID", 1), ("SOPInstanceUID", 1)]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    vol = load(SEG)
    shell = label_surfaces(vol).shells()[0]
    ref = dicom_reference(vol)
    path = tmp_path_factory.mktemp("dcm") / "liver.dcm"
    write_encapsulated_stl(shell, path, ref, instance=3)
    return path, shell, pydicom.dcmread(SEG, stop_before_pixels=True)


def test_required_attributes_and_same_study(written):
    path, shell, source = written
    ds = pydicom.dcmread(path)
    for key, kind in REQUIRED:
        assert key in ds, key
        if kind == 1:
            assert ds[key].value not in (None, "", b""), key
    assert ds.SOPClassUID == ENCAPSULATED_STL == ds.file_meta.MediaStorageSOPClassUID
    assert ds.Modality == "M3D" and ds.MIMETypeOfEncapsulatedDocument == "model/stl"
    assert ds.StudyInstanceUID == source.StudyInstanceUID
    assert ds.FrameOfReferenceUID == source.FrameOfReferenceUID
    assert ds.PatientID == source.PatientID
    assert ds.MeasurementUnitsCodeSequence[0].CodeValue == "mm"
    assert ds.SourceInstanceSequence[0].ReferencedSOPInstanceUID == source.SOPInstanceUID
    assert ds.ReferencedSeriesSequence[0].SeriesInstanceUID == source.SeriesInstanceUID


def test_stl_is_the_surface_in_lps_mm(written, tmp_path):
    path, shell, _ = written
    ds = pydicom.dcmread(path)
    data = bytes(ds.EncapsulatedDocument)[: int(ds.EncapsulatedDocumentLength)]
    (tmp_path / "x.stl").write_bytes(data)
    back = read_stl(tmp_path / "x.stl")
    assert shell.space == "LPS"
    tri = shell.vertices[shell.faces]
    got = back["triangles"]
    assert b"SPACE=LPS" in back["header"] and len(got) == len(tri)
    np.testing.assert_allclose(np.sort(got.reshape(-1, 9), axis=0), np.sort(tri.reshape(-1, 9), axis=0), atol=1e-4)


@pytest.mark.skipif(shutil.which("dciodvfy") is None, reason="dciodvfy (Debian dicom3tools) not installed")
def test_dciodvfy_finds_no_error(written):
    path, _, _ = written
    out = subprocess.run(["dciodvfy", str(path)], capture_output=True, text=True)
    text = out.stdout + out.stderr
    assert "EncapsulatedSTL" in text
    assert not [line for line in text.splitlines() if line.startswith("Error")], text
