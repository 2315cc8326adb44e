"""DICOM input of any kind: an image series, a DICOM SEG or an RT Structure Set, alone or in a folder.

A folder (or list of files) is scanned once (headers only, :func:`~.dicom.scan_dicom`): image
series and segmentation objects are listed apart (:func:`list_dicom`, what ``anatomesh inspect``
prints). Without ``series=``, a folder holding one segmentation object gives that object (with a
note saying so); ``series=`` picks by the 1-based number in the listing (image series first, then
segmentation objects), a SeriesNumber, a SeriesInstanceUID or an object's SOPInstanceUID.

One file given (a SEG, an RTSTRUCT or an image slice) is read alone: its folder is searched only
for its referenced series (or the other slices of its series), and files there that cannot be read
are skipped (named in a note when the series was not found whole), never an error.

A SEG or RTSTRUCT is meshed on the grid of its referenced image series when that series is found
beside it (by SeriesInstanceUID, else by FrameOfReferenceUID: archives crop and re-number series),
so the surfaces land on the CT voxel for voxel; otherwise (``grid="native"``, or the series absent
or unusable) on a grid built from the object's own geometry, with a note saying what was missing
and what the grid was built from.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.progress import Progress, sub
from .dicom import read_dicom, scan_dicom, single_header, unreadable_note
from .dicom_geometry import series_geometry
from .dicom_sop import segmentation_kind
from .dicom_values import floats, int_or, text_of
from .library_messages import add_notes

GRID_IMAGE, GRID_NATIVE = "image", "native"
#: attributes of the source kept for writing surfaces back into its study (never reported)
REFERENCE_KEYS = ("PatientName", "PatientID", "PatientBirthDate", "PatientSex", "StudyInstanceUID",
                  "StudyDate", "StudyTime", "StudyID", "AccessionNumber", "ReferringPhysicianName",
                  "FrameOfReferenceUID", "PositionReferenceIndicator")


@dataclass
class ReferenceGrid:
    """The referenced image series as far as it was found.

    ``affine`` (4x4, LPS, voxel (column, row, slice) → mm) and ``shape`` when its slices form a
    volume; ``plane`` (dict: ``origin``, ``row``, ``col`` unit vectors, ``spacing`` (dx, dy) mm,
    ``size`` (cols, rows), ``positions`` (n, 3)) for any slice found, even a lone one; ``note``
    says what was found or missing; ``header`` is one of its headers (or None); ``incomplete``
    says which of the images the object references are missing or were unreadable ("" when all
    were found)."""

    affine: Optional[np.ndarray] = None
    shape: Optional[Tuple[int, int, int]] = None
    plane: Optional[Dict] = None
    note: str = ""
    header: object = None
    series_uid: str = ""
    files: List[Path] = field(default_factory=list)
    incomplete: str = ""


def read_dicom_any(path, series=None, grid: Optional[str] = None, progress: Optional[Progress] = None):
    """Read what a DICOM path holds (see the module docstring): a Volume or a Segmentation.

    One file given: only that file is read. An image slice gives its series (found in its
    folder); a SEG or RTSTRUCT gives its structures, its referenced series being looked up in
    its folder only when the grid needs it (damaged or unrelated files there are skipped)."""
    if not isinstance(path, (list, tuple)) and Path(path).is_file():
        p = Path(path)
        ds = single_header(p)
        kind = segmentation_kind(ds)
        if not kind:
            return _with_reference(read_dicom(p, series=series, progress=progress), ds)
        return read_object(p, ds, kind, lambda: scan_dicom(p.parent, sub(progress, 0.0, 0.3), tolerant=True),
                           grid, [], progress)
    scan = scan_dicom(path, sub(progress, 0.0, 0.3))
    if not scan.objects:
        return _with_series_reference(read_dicom(path, series=series, progress=progress, scan=scan), scan)
    _check_one_study(scan)
    entries = listing(scan)
    pick = _pick(entries, series, scan.source)
    if pick["kind"] == "image":
        vol = read_dicom(path, series=str(pick["series_index"]), progress=progress, scan=scan)
        return _with_series_reference(vol, scan)
    notes = []
    if series is None:
        others = [e for e in entries if e["kind"] == "image"]
        notes.append(f"meshing the {pick['kind']} object {Path(pick['path']).name} ({pick['description']})"
                     + (f"; --series {others[0]['number']} meshes the image series instead" if others else ""))
    p = Path(pick["path"])
    ds = dict((q, d) for q, d in scan.objects)[p]
    out = read_object(p, ds, pick["kind"], scan, grid, notes, progress)
    add_notes(out, scan.library)
    return out


def read_object(path: Path, header, kind: str, scan, grid, notes: List[str],
                progress: Optional[Progress] = None):
    """Read one SEG or RTSTRUCT with the referenced grid looked up in ``scan`` (a folder scan,
    or a function returning one, called only when the grid needs the referenced series)."""
    if grid not in (None, "", GRID_IMAGE, GRID_NATIVE):
        raise AnatomeshError(f"--grid {grid!r} is not a grid for a DICOM {kind}: use 'image' (the "
                             "referenced series) or 'native' (the object's own planes)", path)
    own_only = grid == GRID_NATIVE and kind.startswith("SEG")  # a SEG's own grid needs no image
    ref = ReferenceGrid() if own_only else reference_grid(scan() if callable(scan) else scan, header, kind)
    if grid == GRID_IMAGE and ref.affine is None:
        raise AnatomeshError(f"--grid image cannot be used: {ref.note}; leave --grid out to mesh on "
                             "the object's own geometry", path)
    use_image = grid != GRID_NATIVE and ref.affine is not None
    if kind.startswith("SEG"):
        from .dicom_seg import read_seg
        out = read_seg(path, ref, use_image, sub(progress, 0.3, 1.0), explicit=grid == GRID_IMAGE)
    else:
        from .rtstruct import read_rtstruct
        out = read_rtstruct(path, ref, use_image, sub(progress, 0.3, 1.0))
    out.meta["notes"] = notes + ([ref.note] if ref.note else []) + list(out.meta.get("notes", []))
    out.meta["dicom_reference"] = dicom_reference(header, ref.header)
    return out


def _with_series_reference(vol, scan):
    """An image series read from a scanned folder, with its study facts for write-back."""
    uid = vol.meta.get("series_uid")
    hit = next((headers[0] for info, headers in scan.series if info.uid == uid), None)
    return _with_reference(vol, hit)


def _with_reference(vol, header):
    if header is not None:
        vol.meta["dicom_reference"] = dicom_reference(header)
        vol.meta["dicom_reference"]["SourceSOPInstanceUID"] = ""  # a series, not one instance
    return vol


def listing(scan) -> List[Dict]:
    """The image series then the segmentation objects of a scan, numbered from 1."""
    out = []
    for n, (info, headers) in enumerate(scan.series, 1):
        out.append({"number": n, "kind": "image", "series_index": n, "uid": info.uid,
                    "description": info.label(), "path": str(info.files[0].parent)})
    for path, ds in scan.objects:
        kind = segmentation_kind(ds)
        out.append({"number": len(out) + 1, "kind": kind, "uid": text_of(ds, "SOPInstanceUID"),
                    "series_uid": text_of(ds, "SeriesInstanceUID"), "path": str(path),
                    "description": f"{path.name}: {_object_label(ds, kind)}"})
    return out


def list_dicom(path) -> List[Dict]:
    """What ``anatomesh inspect`` lists for a DICOM folder: series and segmentation objects."""
    return listing(scan_dicom(path))


def _object_label(ds, kind: str) -> str:
    if kind.startswith("SEG"):
        names = [text_of(s, "SegmentLabel") for s in ds.get("SegmentSequence", [])]
        names = [n for n in names if n and n.lower() != "background"]
        what = f"{len(names)} segment{'s' * (len(names) != 1)}"
    else:
        names = [text_of(s, "ROIName") for s in ds.get("StructureSetROISequence", [])]
        what = f"{len(names)} ROI{'s' * (len(names) != 1)}"
    desc = text_of(ds, "SeriesDescription") or text_of(ds, "StructureSetLabel") or kind
    shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
    return f"'{desc}' {kind}, {what}: {shown}"


def _pick(entries: List[Dict], series, source) -> Dict:
    objects = [e for e in entries if e["kind"] != "image"]
    if series is None or (isinstance(series, str) and not series.strip()):
        if len(objects) == 1:
            return objects[0]
        raise AnatomeshError(f"{len(objects)} segmentation objects found: {_show(entries)}; choose one "
                             "with --series N", source)
    text = str(series).strip()
    if text.isdigit() and 1 <= int(text) <= len(entries):
        return entries[int(text) - 1]
    hits = [e for e in entries if text in (e["uid"], e.get("series_uid"))]
    if len(hits) == 1:
        return hits[0]
    raise AnatomeshError(f"--series {text!r} matches nothing here; found {_show(entries)}; give the "
                         "number in this list or a UID", source)


def _show(entries: List[Dict]) -> str:
    return "; ".join(f"[{e['number']}] {e['description']}" for e in entries)


def _check_one_study(scan) -> None:
    studies = {}
    for info, headers in scan.series:
        studies.setdefault(text_of(headers[0], "StudyInstanceUID"), []).append(info.files[0].name)
    for path, ds in scan.objects:
        studies.setdefault(text_of(ds, "StudyInstanceUID"), []).append(path.name)
    studies.pop("", None)
    if len(studies) > 1:
        shown = "; ".join(f"study …{uid[-8:]}: {', '.join(names[:2])}" for uid, names in studies.items())
        raise AnatomeshError(f"the folder mixes {len(studies)} unrelated studies ({shown}); give the "
                             "folder (or files) of one study", scan.source)


# -- the referenced image series -------------------------------------------------------------------
def referenced_series_uids(ds, kind: str) -> List[str]:
    """SeriesInstanceUIDs an object points at (SEG: ReferencedSeriesSequence; RTSTRUCT: the
    RT Referenced Series of its frames of reference)."""
    if kind.startswith("SEG"):
        return [text_of(s, "SeriesInstanceUID") for s in ds.get("ReferencedSeriesSequence", [])]
    out = []
    for fr in ds.get("ReferencedFrameOfReferenceSequence", []):
        for st in fr.get("RTReferencedStudySequence", []):
            out += [text_of(s, "SeriesInstanceUID") for s in st.get("RTReferencedSeriesSequence", [])]
    return out


def frame_of_reference(ds) -> str:
    uid = text_of(ds, "FrameOfReferenceUID")
    if not uid:
        for fr in ds.get("ReferencedFrameOfReferenceSequence", []):
            uid = text_of(fr, "FrameOfReferenceUID")
            if uid:
                break
    return uid


def reference_grid(scan, ds, kind: str) -> ReferenceGrid:
    """Find the referenced series among the scanned ones and build its grid (see ReferenceGrid).

    Files the scan skipped as unreadable are named in the note when the series was not found
    whole (they may have been its slices)."""
    ref = _find_reference(scan, ds, kind)
    if ref.series_uid:
        ref.incomplete = _missing_images(scan, ds, kind, ref)
    lost = ref.affine is None or ref.incomplete
    if scan.unreadable and lost:
        ref.incomplete = "; ".join(t for t in (ref.incomplete, unreadable_note(scan.unreadable, scan.source)) if t)
    if ref.incomplete:
        ref.note = "; ".join(t for t in (ref.note, ref.incomplete) if t)
    return ref


def _missing_images(scan, ds, kind: str, ref: ReferenceGrid) -> str:
    """How many of the images the object references by SOPInstanceUID, in the series found under
    its own SeriesInstanceUID, are not among the scanned files ("" when none, or when the series
    was matched by frame of reference only)."""
    if ref.series_uid not in referenced_series_uids(ds, kind):
        return ""
    wanted = referenced_instances(ds, kind)
    have = {text_of(h, "SOPInstanceUID") for info, headers in scan.series if info.uid == ref.series_uid
            for h in headers}
    missing = wanted - have
    if not missing:
        return ""
    return (f"{len(missing)} of the {len(wanted)} images the {kind} references are not among the readable "
            f"files of series …{ref.series_uid[-12:]}")


def referenced_instances(ds, kind: str) -> set:
    """SOPInstanceUIDs of the images an object references (SEG: ReferencedSeriesSequence's
    instances; RTSTRUCT: the contour images of its referenced series)."""
    if kind.startswith("SEG"):
        return {text_of(i, "ReferencedSOPInstanceUID") for s in ds.get("ReferencedSeriesSequence", [])
                for i in s.get("ReferencedInstanceSequence", [])} - {""}
    out = set()
    for fr in ds.get("ReferencedFrameOfReferenceSequence", []):
        for st in fr.get("RTReferencedStudySequence", []):
            for se in st.get("RTReferencedSeriesSequence", []):
                out |= {text_of(i, "ReferencedSOPInstanceUID") for i in se.get("ContourImageSequence", [])}
    return out - {""}


def _find_reference(scan, ds, kind: str) -> ReferenceGrid:
    wanted = [u for u in referenced_series_uids(ds, kind) if u]
    for_uid = frame_of_reference(ds)
    found = [s for s in scan.series if s[0].uid in wanted]
    shown = f"…{wanted[0][-12:]}" if wanted else "(none named)"
    own = f"the grid was built from the {kind}'s own geometry"
    if found:
        note = ""
    else:
        found = [s for s in scan.series if for_uid and text_of(s[1][0], "FrameOfReferenceUID") == for_uid]
        if not found:
            return ReferenceGrid(note=f"the referenced image series {shown} is not here: {own}")
        note = (f"the referenced series {shown} is not here; series …{found[0][0].uid[-12:]} shares its "
                "frame of reference and was used for the grid")
    info, headers = found[0]
    try:
        plane = _plane(info.files, headers)
    except AnatomeshError as err:
        return ReferenceGrid(note=(note + "; " if note else "") + f"its slices cannot be placed "
                                  f"({err.message}): {own}")
    ref = ReferenceGrid(note=note, header=headers[0], series_uid=info.uid, files=list(info.files),
                        plane=plane)
    try:
        order, affine, _, _ = series_geometry(info.files, headers, scan.source)
        ref.affine, ref.shape = affine, (info.cols, info.rows, len(info.files))
    except AnatomeshError as err:
        ref.note = (note + "; " if note else "") + (
            f"its slices do not form a volume ({err.message}): {own}"
            + (" and that slice's plane" if len(info.files) == 1 else ""))
    return ref


def _plane(files, headers) -> Dict:
    h = headers[0]
    iop = np.array(floats(h, "ImageOrientationPatient", 6, files[0]))
    ps = floats(h, "PixelSpacing", 2, files[0])
    return {"origin": np.array(floats(h, "ImagePositionPatient", 3, files[0])), "row": iop[:3],
            "col": iop[3:], "spacing": (float(ps[1]), float(ps[0])),
            "size": (int_or(h.get("Columns"), 0), int_or(h.get("Rows"), 0)),
            "positions": np.array([floats(d, "ImagePositionPatient", 3, p) for p, d in zip(files, headers)])}


def dicom_reference(ds, image_header=None) -> Dict:
    """Patient, study and frame of reference of an object, for writing surfaces back into its study."""
    out = {k: text_of(ds, k) for k in REFERENCE_KEYS}
    if not out["FrameOfReferenceUID"]:
        out["FrameOfReferenceUID"] = frame_of_reference(ds)
    if image_header is not None:
        for k in REFERENCE_KEYS:
            out[k] = out[k] or text_of(image_header, k)
    out["SourceSOPClassUID"] = text_of(ds, "SOPClassUID")
    out["SourceSOPInstanceUID"] = text_of(ds, "SOPInstanceUID")
    out["SourceSeriesInstanceUID"] = text_of(ds, "SeriesInstanceUID")
    return out
