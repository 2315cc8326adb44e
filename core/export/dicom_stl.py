"""Surfaces back into the patient's DICOM study: one **Encapsulated STL** object per surface.

The Encapsulated STL IOD (DICOM PS3.3 A.85.1, SOP Class 1.2.840.10008.5.1.4.1.1.104.3, one of the
Encapsulated 3D Manufacturing Model IODs) carries a binary STL file in the patient coordinate
system (LPS, mm) of a Frame of Reference, so a PACS archives a printable model with the images it
was made from. Each object is built with pydicom and holds the modules of that IOD: Patient,
General Study, Encapsulated Document Series (modality ``M3D``), Frame of Reference, General and
Enhanced General Equipment, Encapsulated Document (MIME type ``model/stl``), Manufacturing 3D
Model (units: mm, UCUM) and SOP Common, with the source series in the Source Instance Sequence.

The study, patient and frame of reference come from ``volume.meta["dicom_reference"]`` (set by the
DICOM readers); a source that is not DICOM gets a new study and frame of reference (the report
says so through the reference's ``note``).
"""
from __future__ import annotations

import datetime
import io
from typing import Dict, Optional

import numpy as np

from ..model.mesh import Mesh
from ..model.volume import space_flip

ENCAPSULATED_STL = "1.2.840.10008.5.1.4.1.1.104.3"
#: attributes copied from the source into every object (Patient and General Study modules)
COPIED = ("PatientName", "PatientID", "PatientBirthDate", "PatientSex", "StudyInstanceUID",
          "StudyDate", "StudyTime", "StudyID", "AccessionNumber", "ReferringPhysicianName")
SOFTWARE = "anatomesh"


def dicom_reference(volume) -> Dict:
    """The study facts new objects join: ``volume.meta["dicom_reference"]`` when the source was
    DICOM, else a fresh study and frame of reference (with a ``note`` saying so). The same dict
    is given to every surface of a run, so all land in one new series."""
    from pydicom.uid import generate_uid

    ref = dict(volume.meta.get("dicom_reference") or {})
    if not ref.get("StudyInstanceUID"):
        ref.update(StudyInstanceUID=generate_uid(), note="the source is not DICOM: a new study "
                   "and frame of reference were made for the Encapsulated STL objects")
    if not ref.get("FrameOfReferenceUID"):
        ref["FrameOfReferenceUID"] = generate_uid()
    ref.setdefault("SeriesInstanceUID_out", generate_uid())
    return ref


def stl_bytes(mesh: Mesh, title: str) -> bytes:
    """Binary STL of ``mesh`` in LPS mm (converted from its space), facet normals from winding."""
    v = mesh.vertices.astype(np.float64)
    if mesh.space != "LPS":
        v = v @ space_flip(mesh.space, "LPS")[:3, :3].T
    f = mesh.faces.astype(np.int64)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = n / np.where(norm > 0, norm, 1.0)
    rec["v"] = tri
    head = f"anatomesh {title} SPACE=LPS UNITS=mm".encode("ascii", "replace")[:80].ljust(80, b" ")
    return head + np.uint32(len(f)).tobytes() + rec.tobytes()


def encapsulated_stl(mesh: Mesh, reference: Dict, instance: int = 1,
                     now: Optional[datetime.datetime] = None):
    """The Encapsulated STL data set (pydicom ``FileDataset``) of one surface."""
    from pydicom.dataset import Dataset, FileDataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, PYDICOM_IMPLEMENTATION_UID, generate_uid

    now = now or datetime.datetime.now()
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = ENCAPSULATED_STL
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    meta.ImplementationClassUID = PYDICOM_IMPLEMENTATION_UID
    ds = FileDataset("", Dataset(), file_meta=meta, preamble=b"\0" * 128)
    ds.SpecificCharacterSet = "ISO_IR 192"
    ds.SOPClassUID = ENCAPSULATED_STL
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    for key in COPIED:  # Patient, General Study (type 2: present, maybe empty)
        value = reference.get(key, "")
        setattr(ds, key, str(value)[:16] if key == "StudyID" else value)  # SH: some carry more
    ds.Modality = "M3D"  # Encapsulated Document Series
    ds.SeriesInstanceUID = reference["SeriesInstanceUID_out"]
    ds.SeriesNumber = int(reference.get("SeriesNumber_out", 9001))
    ds.SeriesDescription = "Anatomesh surfaces"
    ds.FrameOfReferenceUID = reference["FrameOfReferenceUID"]
    ds.PositionReferenceIndicator = reference.get("PositionReferenceIndicator", "")
    ds.Manufacturer = ds.ManufacturerModelName = SOFTWARE
    ds.DeviceSerialNumber = "0"
    ds.SoftwareVersions = "0.1.0"
    ds.InstanceNumber = int(instance)
    ds.ContentDate, ds.ContentTime = now.strftime("%Y%m%d"), now.strftime("%H%M%S")
    ds.InstanceCreationDate, ds.InstanceCreationTime = ds.ContentDate, ds.ContentTime
    ds.AcquisitionDateTime = now.strftime("%Y%m%d%H%M%S")
    ds.BurnedInAnnotation = "NO"
    ds.DocumentTitle = str(mesh.name or "surface")[:64]
    ds.ConceptNameCodeSequence = []
    ds.MIMETypeOfEncapsulatedDocument = "model/stl"
    data = stl_bytes(mesh, str(mesh.name))
    ds.EncapsulatedDocumentLength = len(data)
    ds.EncapsulatedDocument = data + (b"\0" if len(data) % 2 else b"")
    ds.MeasurementUnitsCodeSequence = [_code("mm", "UCUM", "mm")]
    if reference.get("SourceSOPInstanceUID"):
        src = Dataset()
        src.ReferencedSOPClassUID = reference["SourceSOPClassUID"]
        src.ReferencedSOPInstanceUID = reference["SourceSOPInstanceUID"]
        ds.SourceInstanceSequence = [src]
        if reference.get("SourceSeriesInstanceUID"):  # Common Instance Reference module
            series = Dataset()
            series.SeriesInstanceUID = reference["SourceSeriesInstanceUID"]
            series.ReferencedInstanceSequence = [src]
            ds.ReferencedSeriesSequence = [series]
    return ds


def _code(value: str, scheme: str, meaning: str):
    from pydicom.dataset import Dataset

    c = Dataset()
    c.CodeValue, c.CodingSchemeDesignator, c.CodeMeaning = value, scheme, meaning
    return c


def write_encapsulated_stl(mesh: Mesh, path, reference: Dict, instance: int = 1) -> None:
    """Write one surface as an Encapsulated STL file at ``path`` (atomically)."""
    from .common import atomic_write

    ds = encapsulated_stl(mesh, reference, instance)
    buf = io.BytesIO()
    ds.save_as(buf, enforce_file_format=True)
    with atomic_write(path) as fh:
        fh.write(buf.getvalue())
