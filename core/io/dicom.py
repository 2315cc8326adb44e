"""Read a DICOM series (a folder, searched recursively, or a list of files) into a :class:`Volume`.

Layout and geometry
-------------------
The volume is in **LPS** (DICOM patient space, mm). ``data`` has shape ``(cols, rows, slices)``
and is C-contiguous: ``data[i, j, k] = pixel_array_of_slice_k[j, i]``, so

* ``i`` runs along the image columns, i.e. along the first ImageOrientationPatient vector (the
  row direction), step ``PixelSpacing[1]`` (the *column* spacing);
* ``j`` runs along the image rows, i.e. along the second ImageOrientationPatient vector, step
  ``PixelSpacing[0]`` (the *row* spacing);
* ``k`` runs along the slice normal ``n = row × col``, slices sorted by ``ImagePositionPatient · n``
  ascending, step the median of the position differences (never SpacingBetweenSlices or
  SliceThickness, which are often wrong or signed).

``affine @ (i, j, k, 1)`` is the voxel centre: origin = ImagePositionPatient of the first sorted
slice, columns ``row·dx``, ``col·dy`` and the slice step vector. Oblique orientations are exact;
a gantry tilt (slice origins that move off the normal) gives a sheared third column, also exact.
Values are rescaled (``stored · RescaleSlope + RescaleIntercept``; CT → HU): int16 when every
slope and intercept is an integer and the values fit, float32 otherwise.

Reading happens in two passes: headers only (``stop_before_pixels``) for every file, then pixels
for the chosen series only, with a memory check before the allocation.

One slice given (not a folder): that file is read strictly (its problems are errors naming it),
then the other slices of its series are found in its folder (searched recursively); files there
that cannot be read are skipped with a note, other series and objects are ignored.

What is detected, and what happens
----------------------------------
Errors (:class:`AnatomeshError`, naming the file or folder, the problem and what to do):

* path does not exist; empty folder; no image series among the files;
* several image series and no ``series=`` choice (the message lists them); an unknown choice;
* empty (0-byte) or unreadable file named like DICOM (``.dcm``, ``.dicom``, ``.ima``); a file with
  the DICOM marker whose header cannot be parsed or names no object type; an image file whose
  header lacks Rows/Columns (truncated); pixel data that cannot be decoded (truncated/damaged);
* compressed pixel data without an installed codec (names the transfer syntax and the pip
  package), or a transfer syntax pydicom cannot decode at all;
* within the chosen series: mixed image sizes, mixed orientations, mixed pixel spacing, a single
  slice, two slices at the same position (duplicates, named), a gap larger than 1.5 x the median
  step (missing slices, located), slice origins that do not lie on one line, colour images.

Warnings (``volume.warnings``; the volume is still read):

* what pydicom itself warns about a header (one note per message, naming the file);
* files that are not DICOM (skipped), DICOM objects that are not volume slices (DICOMDIR,
  structured reports, RT structure sets, presentation states, multi-frame objects, images
  without a patient position: skipped with a note);
* slice steps that vary by more than 1 % without a gap; a gantry tilt (shear angle given);
  orientation vectors that are not orthogonal.

``series=`` is a 1-based index into :func:`list_series` order first, then a SeriesNumber, then a
SeriesInstanceUID.
"""
from __future__ import annotations

import os
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import pydicom
from pydicom import uid as _uid

from ..model.errors import AnatomeshError
from ..model.progress import Progress, report, sub
from ..model.volume import Volume
from .dicom_geometry import series_geometry
from .dicom_pixels import read_series, transfer_syntax
from .dicom_sop import segmentation_kind
from .library_messages import reason
from .dicom_values import file_names, first_float, float_or, int_or, rel_path, text_of
from .library_messages import WarningLog, collect, notes_of_library

PathLike = Union[str, os.PathLike]

#: file names that claim to be DICOM: when such a file cannot be read it is an error, not a skip
DICOM_SUFFIXES = (".dcm", ".dicom", ".ima")



@dataclass
class SeriesInfo:
    """One image series found in a folder (what the CLI and the Blender panel offer to choose).

    ``number`` is the SeriesNumber (None when absent), ``rows``/``cols`` the most common image
    size, ``files`` the slice files in folder order.
    """

    uid: str
    number: Optional[int]
    description: str
    modality: str
    n_slices: int
    rows: int
    cols: int
    files: List[Path] = field(default_factory=list, repr=False)

    def label(self) -> str:
        """One line: ``#3 'CT Body 3.0' CT, 20 slices of 512x512``."""
        num = "#?" if self.number is None else f"#{self.number}"
        desc = self.description or "no description"
        slices = f"{self.n_slices} slice{'' if self.n_slices == 1 else 's'}"
        return f"{num} '{desc}' {self.modality or '?'}, {slices} of {self.cols}x{self.rows}"


# -- public API --------------------------------------------------------------------------------
def list_series(path_or_paths: Union[PathLike, Sequence[PathLike]],
                progress: Optional[Progress] = None) -> List[SeriesInfo]:
    """The image series in a folder (searched recursively) or a list of files, in choice order.

    Sorted by SeriesNumber (absent last), then description and UID; ``series=i`` in
    :func:`read_dicom` picks the i-th (1-based). Raises :class:`AnatomeshError` when no image
    series is found.
    """
    return [info for info, _ in _scan(path_or_paths, progress).series]


@notes_of_library
def read_dicom(path_or_paths: Union[PathLike, Sequence[PathLike]], series=None,
               progress: Optional[Progress] = None, scan=None) -> Volume:
    """Read one DICOM image series into an LPS :class:`Volume` (see the module docstring).

    Parameters
    ----------
    path_or_paths : path or list of paths
        A folder (searched recursively), one image slice (the slices of its series are found in
        its folder, searched recursively; damaged files there are skipped with a note) or a list
        of files and folders.
    series : int or str, optional
        Needed when several image series are found: a 1-based index into :func:`list_series`
        order, else a SeriesNumber, else a SeriesInstanceUID (tried in that order).
    progress : callable, optional
        ``progress(fraction, text)``, called per file and per slice.

    Returns
    -------
    Volume
        ``data`` (cols, rows, slices) int16 or float32, C-contiguous; ``affine`` voxel → mm in
        LPS; ``meta`` with format, modality, series_uid, series_number, series_description,
        units, rescale, transfer_syntax, window_center/width, source, n_files, slice_spacing
        (no patient data); ``warnings`` for problems that did not stop the reading.
    """
    scan = scan or _scan(path_or_paths, sub(progress, 0.0, 0.3))  # scan: from scan_dicom, if done
    info, headers = _choose(scan, series)
    try:
        order, affine, step, geo_warnings = series_geometry(info.files, headers, scan.source)
    except AnatomeshError as err:
        if not scan.unreadable:
            raise
        raise AnatomeshError(f"{err.message}; {unreadable_note(scan.unreadable, scan.source)}",
                             err.path) from None
    files = [info.files[i] for i in order]
    headers = [headers[i] for i in order]
    slope = np.array([float_or(h, "RescaleSlope", 1.0) for h in headers])
    intercept = np.array([float_or(h, "RescaleIntercept", 0.0) for h in headers])
    data = read_series(files, headers, scan.source, sub(progress, 0.3, 0.95), slope, intercept)
    report(progress, 1.0, "DICOM series read")
    meta = _meta(info, headers, scan.source, step, slope, intercept)
    return Volume(data, affine, "LPS", meta, None, scan.notes + geo_warnings)


# -- pass 1: find files, read headers, group series ----------------------------------------------
@dataclass
class _Scan:
    source: Path                                  # the folder named in messages
    series: List[Tuple[SeriesInfo, list]]         # (info, headers) in choice order
    notes: List[str]                              # skipped files, one line per kind
    preferred: Optional[int] = None               # series of the single file given, if any
    objects: List[Tuple[Path, object]] = field(default_factory=list)  # SEG/RTSTRUCT objects
    unreadable: List[Tuple[Path, str, str]] = field(default_factory=list)  # (path, why, series uid)
    library: List[str] = field(default_factory=list)  # what pydicom said about the headers (also in notes)


def _scan(path_or_paths, progress, tolerant: bool = False) -> _Scan:
    """Read every header; group image slices by series. ``tolerant``: unreadable or damaged files
    are skipped (listed in ``.unreadable``) instead of stopping the scan, and finding no image
    series is not an error (a folder searched for a referenced series)."""
    if isinstance(path_or_paths, (str, os.PathLike)) and Path(path_or_paths).is_file():
        return _scan_single(Path(path_or_paths), progress)
    files, source = _collect_files(path_or_paths)
    if not files:
        raise AnatomeshError("the folder is empty; give the folder that holds the DICOM slices",
                             source)
    groups: Dict[object, list] = defaultdict(list)
    skipped: Dict[str, List[Path]] = defaultdict(list)
    objects: List[Tuple[Path, object]] = []
    unreadable: List[Tuple[Path, str, str]] = []
    log = WarningLog()
    for n, path in enumerate(files):
        report(progress, n / len(files), f"reading DICOM headers {n + 1}/{len(files)}")
        ds, kind, damaged, file_log = _header_of(path, tolerant)
        if damaged:
            unreadable.append((path, damaged, text_of(ds, "SeriesInstanceUID") if ds is not None else ""))
            continue
        log.merge(file_log)
        if ds is not None and segmentation_kind(ds):  # DICOM SEG / RTSTRUCT: kept apart (and noted)
            objects.append((path, ds))
        if kind:
            skipped[kind].append(path)
        else:
            groups[_series_key(ds)].append((path, ds))
    notes = [f"skipped {len(ps)} {kind}: {file_names(ps, source)}" for kind, ps in skipped.items()]
    if not groups and not objects and not tolerant:
        found = "; ".join(f"{len(ps)} {kind}" for kind, ps in skipped.items())
        raise AnatomeshError(f"no DICOM image series found among {len(files)} file(s) ({found}); "
                             "give the folder that holds the image slices", source)
    report(progress, 1.0, "DICOM headers read")
    return _Scan(source, _sorted_series(groups), notes + log.notes(), None, objects, unreadable, log.notes())


def _header_of(path: Path, tolerant: bool):
    """(header or None, why it is skipped or "", why it is damaged or "", pydicom's messages about
    it as a :class:`WarningLog`). ``damaged`` is only ever set when ``tolerant`` (else raised); the
    header is then what could be read of it, or None."""
    log, ds = WarningLog(), None
    try:
        with collect(log, path):
            ds, kind = _read_header(path)
            if ds is not None:
                _convert_values(ds)
                kind = _object_kind(ds, path)
    except AnatomeshError as err:
        if not tolerant:
            raise
        return ds, "", err.message, log
    return ds, kind, "", log


def _convert_values(ds) -> None:
    """Convert the top-level values (not sequences, not private elements: nothing here reads
    them) now, while pydicom's complaints about them can still be said to be about this file; a
    value pydicom cannot convert is left as it is (it is an error only if it is ever used)."""
    for tag in list(ds.keys()):
        if tag.is_private or getattr(ds.get_item(tag), "VR", None) == "SQ":
            continue
        try:
            ds[tag]
        except Exception:  # pydicom raises many kinds for malformed private values
            pass


def _sorted_series(groups: Dict[object, list]) -> List[Tuple[SeriesInfo, list]]:
    series = [(_series_info(members), [ds for _, ds in members]) for members in groups.values()]
    series.sort(key=lambda s: (s[0].number is None, s[0].number or 0, s[0].description, s[0].uid))
    return series


def _scan_single(path: Path, progress) -> _Scan:
    """One image slice given: the slices of its series in its folder (searched recursively).

    The given file is read strictly (its problems are errors naming it); its siblings are read
    only to find the other slices of its series: a damaged file whose header still names that
    series is an error naming it (the series cannot be read whole), other unreadable files are
    skipped with a note, other series and objects are left alone."""
    ds = single_header(path)
    kind = _object_kind(ds, path)
    if segmentation_kind(ds) or kind:
        what = segmentation_kind(ds) or kind.replace("(s)", "")
        raise AnatomeshError(f"this file is a {what}, not a slice of an image series; give a CT/MR "
                             "slice, its folder, or load() the segmentation object", path)
    key, uid = _series_key(ds), text_of(ds, "SeriesInstanceUID")
    members, unreadable, log = [(path, ds)], [], WarningLog()
    siblings = [q for q in _walk(path.parent) if q != path]
    for n, q in enumerate(siblings):
        report(progress, n / max(1, len(siblings)), f"reading DICOM headers {n + 1}/{len(siblings)}")
        other, kind, damaged, file_log = _header_of(q, tolerant=True)
        same = other is not None and bool(uid) and text_of(other, "SeriesInstanceUID") == uid
        if damaged and same:
            raise AnatomeshError(f"{damaged} (it belongs to the series of {path.name})", q)
        if damaged:
            unreadable.append((q, damaged, ""))
        elif other is not None and not kind and _series_key(other) == key:
            log.merge(file_log)
            members.append((q, other))
    members.sort(key=lambda m: str(m[0]))
    notes = log.notes() + ([unreadable_note(unreadable, path.parent)] if unreadable else [])
    return _Scan(path.parent, _sorted_series({key: members}), notes, 0, [], unreadable, log.notes())


def unreadable_note(unreadable: List[Tuple[Path, str, str]], source: Path) -> str:
    """One line naming the damaged files skipped beside the file given, and the first reason."""
    first, why = unreadable[0][:2]
    return (f"skipped {len(unreadable)} unreadable file(s) in {source.name or source}: "
            f"{file_names([u[0] for u in unreadable], source)} ({rel_path(first, source)}: {why})")


def single_header(path: Path):
    """The header of one DICOM file given by the user; an error naming it when it is not DICOM
    or cannot be read."""
    ds, why = _read_header(path)
    if ds is None:
        what = "an empty file (0 bytes)" if why.startswith("empty") else "not a DICOM file"
        raise AnatomeshError(f"{what}; give a DICOM file or the folder of a DICOM series", path)
    return ds


def scan_dicom(path_or_paths, progress: Optional[Progress] = None, tolerant: bool = False):
    """Headers of a folder (or list): ``.series`` [(SeriesInfo, headers)] in choice order,
    ``.objects`` [(path, header)] of the DICOM SEG / RTSTRUCT objects, ``.notes``, ``.source``,
    ``.unreadable`` [(path, why, series uid or "")] (``tolerant``: damaged files skipped, not errors),
    ``.library`` (what pydicom said about the headers, one note per message)."""
    return _scan(path_or_paths, progress, tolerant)


def _collect_files(path_or_paths) -> Tuple[List[Path], Path]:
    """(files, folder named in messages) of a folder or a list of files and folders."""
    if isinstance(path_or_paths, (str, os.PathLike)):
        p = Path(path_or_paths)
        if not p.exists():
            raise AnatomeshError("no such file or folder; check the path", p)
        return _walk(p), p
    paths = [Path(q) for q in path_or_paths]
    if not paths:
        raise AnatomeshError("no DICOM files given (empty list); give a DICOM folder or files")
    files: List[Path] = []
    for q in paths:
        if not q.exists():
            raise AnatomeshError("no such file or folder; check the path", q)
        files.extend(_walk(q) if q.is_dir() else [q])
    try:
        source = Path(os.path.commonpath([str(q if q.is_dir() else q.parent) for q in paths]))
    except ValueError:  # different drives
        source = paths[0].parent
    return files, source


def _walk(folder: Path) -> List[Path]:
    """All files below ``folder``, sorted, hidden files and folders (``.name``) left out."""
    out: List[Path] = []
    for root, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        out.extend(Path(root) / n for n in sorted(names) if not n.startswith("."))
    return out


def _read_header(path: Path):
    """(header dataset, "") for a DICOM file, (None, why) for a file that is not DICOM.

    Raises for a file that claims to be DICOM (marker or ``.dcm`` name) but cannot be read.
    """
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(132)
    except OSError as err:
        raise AnatomeshError(f"cannot read the file ({err.strerror}); check its permissions",
                             path) from None
    claims = path.suffix.lower() in DICOM_SUFFIXES
    if size == 0:
        if claims:
            raise AnatomeshError("empty file (0 bytes) named like a DICOM file: an incomplete copy; "
                                 "copy it again or delete it", path)
        return None, "empty file(s)"
    marker = len(head) == 132 and head[128:132] == b"DICM"
    # without the marker, a bare DICOM data set starts with a group 0002 or 0008 tag
    if not marker and head[:2] not in (b"\x02\x00", b"\x08\x00"):
        if claims:
            raise AnatomeshError("not a DICOM file (no DICM marker, no DICOM header) although "
                                 "named like one: damaged; copy it again or remove it", path)
        return None, "file(s) that are not DICOM"
    try:
        ds = pydicom.dcmread(path, stop_before_pixels=True, force=not marker)
    except Exception as err:  # pydicom raises many kinds on damaged input
        if marker or claims:
            raise AnatomeshError(f"damaged DICOM file, its header cannot be read ({reason(err)}); "
                                 "copy it again or remove it", path) from None
        return None, "file(s) that are not DICOM"
    if not marker and not any(k in ds for k in ("SOPClassUID", "Modality", "Rows")):
        if claims:
            raise AnatomeshError("not a readable DICOM file although named like one; copy it "
                                 "again or remove it", path)
        return None, "file(s) that are not DICOM"
    return ds, ""


def _object_kind(ds, path: Path) -> str:
    """Why ``ds`` is skipped, or the empty string for a single-frame slice with a position."""
    sop = _sop_class(ds)
    name = sop.name if sop else "unknown SOP class"
    if path.name.upper() == "DICOMDIR" or sop == _uid.MediaStorageDirectoryStorage:
        return "DICOMDIR index file(s) (not images)"
    if "Rows" not in ds or "Columns" not in ds:
        if sop is None:
            raise AnatomeshError("damaged DICOM file: its header names no object type (SOP "
                                 "class) and no image size; copy it again or remove it", path)
        if "Image Storage" in name:
            raise AnatomeshError(f"truncated or damaged {name} file: its header has no image "
                                 "size (Rows/Columns); copy it again or remove it", path)
        return f"non-image DICOM object(s) ({name})"
    if int_or(ds.get("NumberOfFrames"), 1) > 1:
        return f"multi-frame object(s) ({name}; only single-frame slices are supported)"
    if "ImagePositionPatient" not in ds or "ImageOrientationPatient" not in ds:
        return f"image(s) without a patient position ({name}), not part of a 3D volume"
    return ""


def _sop_class(ds) -> Optional[_uid.UID]:
    value = str(ds.get("SOPClassUID", "") or "")
    if not value:
        meta = getattr(ds, "file_meta", None)
        value = str(meta.get("MediaStorageSOPClassUID", "") or "") if meta is not None else ""
    return _uid.UID(value) if value else None


def _series_key(ds):
    uid = str(ds.get("SeriesInstanceUID", "") or "")
    if uid:
        return uid
    # anonymised files may lack the UID: fall back on what a person would group by
    return ("", int_or(ds.get("SeriesNumber"), None), text_of(ds, "SeriesDescription"),
            text_of(ds, "Modality"))


def _series_info(members) -> SeriesInfo:
    ds = members[0][1]
    rows, cols = Counter((int_or(d.get("Rows"), 0), int_or(d.get("Columns"), 0))
                         for _, d in members).most_common(1)[0][0]
    return SeriesInfo(uid=text_of(ds, "SeriesInstanceUID"), number=int_or(ds.get("SeriesNumber"), None),
                      description=text_of(ds, "SeriesDescription"), modality=text_of(ds, "Modality"),
                      n_slices=len(members), rows=rows, cols=cols, files=[p for p, _ in members])


def _choose(scan: _Scan, series) -> Tuple[SeriesInfo, list]:
    """The series picked by ``series`` (index, then SeriesNumber, then UID)."""
    found = scan.series
    if not found:
        raise AnatomeshError("no DICOM image series here, only segmentation objects (SEG/RTSTRUCT); "
                             "pick one with --series N (`anatomesh inspect` lists them) or give the image "
                             "series' folder", scan.source)
    if series is None or (isinstance(series, str) and not series.strip()):
        if len(found) == 1:
            return found[0]
        if scan.preferred is not None:
            return found[scan.preferred]
        raise AnatomeshError(f"{len(found)} image series found: {_listing(found)}; choose one "
                             "with --series N (series=N in Python: the 1-based number in this "
                             "list, a SeriesNumber or a SeriesInstanceUID)", scan.source)
    text = str(series).strip()
    if text.lstrip("+-").isdigit():
        n = int(text)
        if 1 <= n <= len(found):
            return found[n - 1]
        matches = [s for s in found if s[0].number == n]
        if len(matches) == 1:
            return matches[0]
    matches = [s for s in found if s[0].uid and s[0].uid == text]
    if len(matches) == 1:
        return matches[0]
    raise AnatomeshError(f"no image series matches --series {text!r}; found {len(found)}: "
                         f"{_listing(found)}; give the 1-based number in this list, a "
                         "SeriesNumber or a SeriesInstanceUID", scan.source)


def _listing(found) -> str:
    return "; ".join(f"[{n}] {info.label()} (uid {info.uid or 'none'})"
                     for n, (info, _) in enumerate(found, 1))


# -- geometry -----------------------------------------------------------------------------------


# -- pass 2: pixels -------------------------------------------------------------------------------


# -- metadata and small helpers --------------------------------------------------------------------
def _meta(info: SeriesInfo, headers: list, source: Path, step: float, slope, intercept) -> dict:
    first = headers[0]
    modality = text_of(first, "Modality")
    units = "HU" if modality == "CT" else text_of(first, "RescaleType") or text_of(first, "Units")
    if np.all(slope == slope[0]) and np.all(intercept == intercept[0]):
        rescale = {"slope": float(slope[0]), "intercept": float(intercept[0])}
    else:
        rescale = {"slope": "per slice", "intercept": "per slice",
                   "slope_range": [float(slope.min()), float(slope.max())],
                   "intercept_range": [float(intercept.min()), float(intercept.max())]}
    ts = transfer_syntax(first)
    return {
        "format": "dicom",
        "modality": modality,
        "series_uid": info.uid,
        "series_number": info.number,
        "series_description": info.description,
        "units": units,
        "rescale": rescale,
        "transfer_syntax": ts.name,
        "transfer_syntax_uid": str(ts),
        "window_center": first_float(first.get("WindowCenter")),
        "window_width": first_float(first.get("WindowWidth")),
        "source": str(source),
        "n_files": len(headers),
        "slice_spacing": step,
        "slice_thickness": float_or(first, "SliceThickness", None),
        "manufacturer": text_of(first, "Manufacturer"),
    }


