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

* files that are not DICOM (skipped), DICOM objects that are not volume slices (DICOMDIR,
  structured reports, RT structure sets, presentation states, multi-frame objects, images
  without a patient position: skipped with a note);
* slice steps that vary by more than 1 % without a gap; a gantry tilt (shear angle given);
  orientation vectors that are not orthogonal.

``series=`` is a 1-based index into :func:`list_series` order first, then a SeriesNumber, then a
SeriesInstanceUID.
"""
from __future__ import annotations

import math
import os
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import pydicom
from pydicom import uid as _uid
from pydicom.multival import MultiValue
from pydicom.pixels import get_decoder, pixel_array

from ..model.errors import AnatomeshError
from ..model.progress import Progress, report, sub
from ..model.volume import Volume, check_fits_in_memory

PathLike = Union[str, os.PathLike]

#: file names that claim to be DICOM: when such a file cannot be read it is an error, not a skip
DICOM_SUFFIXES = (".dcm", ".dicom", ".ima")
GAP_FACTOR = 1.5            # a step above this times the median step is a gap (missing slices)
UNIFORM_TOLERANCE = 0.01    # relative spread of the slice steps tolerated without a warning
DUPLICATE_MM = 0.01         # two slices closer than this along the normal share a position
ORIENTATION_TOLERANCE = 1e-4  # direction-cosine difference tolerated between slices
TILT_TOLERANCE_DEG = 0.01   # shear below this is rounding; the affine is then orthogonal
LINE_TOLERANCE_PX = 0.1     # in-plane scatter of slice origins tolerated, in pixels

# transfer syntax → the pip package(s) whose pydicom plug-in decodes it
_CODEC_PACKAGES = {
    _uid.JPEGBaseline8Bit: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGExtended12Bit: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLossless: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLosslessSV1: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLSLossless: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLSNearLossless: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEG2000Lossless: "pylibjpeg pylibjpeg-openjpeg",
    _uid.JPEG2000: "pylibjpeg pylibjpeg-openjpeg",
    _uid.HTJ2KLossless: "pylibjpeg pylibjpeg-openjpeg",
    _uid.HTJ2KLosslessRPCL: "pylibjpeg pylibjpeg-openjpeg",
    _uid.HTJ2K: "pylibjpeg pylibjpeg-openjpeg",
    _uid.RLELossless: "pylibjpeg pylibjpeg-rle",
}


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


def read_dicom(path_or_paths: Union[PathLike, Sequence[PathLike]], series=None,
               progress: Optional[Progress] = None) -> Volume:
    """Read one DICOM image series into an LPS :class:`Volume` (see the module docstring).

    Parameters
    ----------
    path_or_paths : path or list of paths
        A folder (searched recursively), one file (its folder is read and its series chosen) or
        a list of files and folders.
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
    scan = _scan(path_or_paths, sub(progress, 0.0, 0.3))
    info, headers = _choose(scan, series)
    order, affine, step, geo_warnings = _geometry(info.files, headers, scan.source)
    files = [info.files[i] for i in order]
    headers = [headers[i] for i in order]
    stack = _read_pixels(files, headers, scan.source, sub(progress, 0.3, 0.95))
    slope = np.array([_float(h, "RescaleSlope", 1.0) for h in headers])
    intercept = np.array([_float(h, "RescaleIntercept", 0.0) for h in headers])
    data = _to_volume_layout(stack, slope, intercept)
    del stack
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


def _scan(path_or_paths, progress) -> _Scan:
    files, source, single = _collect_files(path_or_paths)
    if not files:
        raise AnatomeshError("the folder is empty; give the folder that holds the DICOM slices",
                             source)
    groups: Dict[object, list] = defaultdict(list)
    skipped: Dict[str, List[Path]] = defaultdict(list)
    for n, path in enumerate(files):
        ds, kind = _read_header(path)
        if ds is not None:
            kind = _object_kind(ds, path)
        if kind:
            skipped[kind].append(path)
        else:
            groups[_series_key(ds)].append((path, ds))
        report(progress, (n + 1) / len(files), f"reading DICOM headers {n + 1}/{len(files)}")
    notes = [f"skipped {len(ps)} {kind}: {_names(ps, source)}" for kind, ps in skipped.items()]
    if not groups:
        found = "; ".join(f"{len(ps)} {kind}" for kind, ps in skipped.items())
        raise AnatomeshError(f"no DICOM image series found among {len(files)} file(s) ({found}); "
                             "give the folder that holds the image slices", source)
    series = [(_series_info(members), [ds for _, ds in members]) for members in groups.values()]
    series.sort(key=lambda s: (s[0].number is None, s[0].number or 0, s[0].description, s[0].uid))
    preferred = None
    if single is not None:
        preferred = next((n for n, (info, _) in enumerate(series) if single in info.files), None)
    return _Scan(source, series, notes, preferred)


def _collect_files(path_or_paths) -> Tuple[List[Path], Path, Optional[Path]]:
    """(files, folder named in messages, the single file given or None)."""
    if isinstance(path_or_paths, (str, os.PathLike)):
        p = Path(path_or_paths)
        if not p.exists():
            raise AnatomeshError("no such file or folder; check the path", p)
        if p.is_file():
            return _walk(p.parent), p.parent, p
        return _walk(p), p, None
    paths = [Path(q) for q in path_or_paths]
    if not paths:
        raise AnatomeshError("no DICOM files given (empty list)")
    files: List[Path] = []
    for q in paths:
        if not q.exists():
            raise AnatomeshError("no such file or folder; check the path", q)
        files.extend(_walk(q) if q.is_dir() else [q])
    try:
        source = Path(os.path.commonpath([str(q if q.is_dir() else q.parent) for q in paths]))
    except ValueError:  # different drives
        source = paths[0].parent
    return files, source, None


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
            raise AnatomeshError("empty file (0 bytes) among the DICOM slices: an incomplete copy; "
                                 "copy the series again or delete the file", path)
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
            raise AnatomeshError(f"damaged DICOM file, its header cannot be read ({_short(err)}); "
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
    if _int(ds.get("NumberOfFrames"), 1) > 1:
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
    return ("", _int(ds.get("SeriesNumber"), None), _str(ds, "SeriesDescription"),
            _str(ds, "Modality"))


def _series_info(members) -> SeriesInfo:
    ds = members[0][1]
    rows, cols = Counter((_int(d.get("Rows"), 0), _int(d.get("Columns"), 0))
                         for _, d in members).most_common(1)[0][0]
    return SeriesInfo(uid=_str(ds, "SeriesInstanceUID"), number=_int(ds.get("SeriesNumber"), None),
                      description=_str(ds, "SeriesDescription"), modality=_str(ds, "Modality"),
                      n_slices=len(members), rows=rows, cols=cols, files=[p for p, _ in members])


def _choose(scan: _Scan, series) -> Tuple[SeriesInfo, list]:
    """The series picked by ``series`` (index, then SeriesNumber, then UID)."""
    found = scan.series
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
def _geometry(files: List[Path], headers: list, source: Path):
    """Sort the slices and build the affine. Returns (order, affine, median step mm, warnings)."""
    _check_alike(files, headers, source)
    row, col, dx, dy, warnings = _in_plane_axes(files, headers, source)
    normal = np.cross(row, col)
    normal /= np.linalg.norm(normal)
    if len(files) < 2:
        raise AnatomeshError("the series has a single slice; a volume needs at least 2", files[0])
    pos = np.array([_floats(d, "ImagePositionPatient", 3, p) for p, d in zip(files, headers)])
    t = pos @ normal  # position along the normal
    order = np.argsort(t, kind="stable")
    t, pos = t[order], pos[order]
    step, more = _slice_step(t, order, files, headers, source)
    vector, tilt = _slice_vector(pos, t, step, normal, min(dx, dy), order, files, headers, source)
    affine = np.eye(4)
    affine[:3, 0] = row * dx
    affine[:3, 1] = col * dy
    affine[:3, 2] = vector
    affine[:3, 3] = pos[0]
    return order, affine, step, warnings + more + tilt


def _check_alike(files, headers, source):
    """Raise unless all slices have one image size and are greyscale."""
    sizes = [(_int(d.get("Rows"), 0), _int(d.get("Columns"), 0)) for d in headers]
    _same(files, sizes, "image sizes", lambda v: f"{v[1]}x{v[0]}", source)
    samples = [_int(d.get("SamplesPerPixel"), 1) for d in headers]
    _same(files, samples, "samples per pixel", str, source)
    if samples[0] != 1:
        raise AnatomeshError("colour (RGB) images cannot form a scalar volume; export the "
                             "series as greyscale", files[0])


def _in_plane_axes(files, headers, source):
    """Unit row and column directions, column and row spacing (mm), warnings."""
    iop = np.array([_floats(d, "ImageOrientationPatient", 6, p) for p, d in zip(files, headers)])
    _same_numbers(files, iop, ORIENTATION_TOLERANCE, "orientations", source)
    spacing = np.array([_floats(d, "PixelSpacing", 2, p) for p, d in zip(files, headers)])
    _same_numbers(files, spacing, 1e-4 * spacing.max(), "pixel spacings", source)
    dy, dx = spacing[0]  # PixelSpacing = (between rows, between columns)
    if dx <= 0 or dy <= 0:
        raise AnatomeshError(f"PixelSpacing {spacing[0].tolist()} is not positive", files[0])
    row, col = iop[0, :3], iop[0, 3:]
    if min(np.linalg.norm(row), np.linalg.norm(col)) < 1e-6:
        raise AnatomeshError("ImageOrientationPatient has a zero vector", files[0])
    row, col = row / np.linalg.norm(row), col / np.linalg.norm(col)
    angle = math.degrees(math.acos(max(-1.0, min(1.0, float(row @ col)))))
    warnings = []
    if abs(angle - 90.0) > 0.06:
        warnings.append(f"the image row and column directions are {angle:.2f}° apart, not 90°; "
                        "the affine keeps them as given")
    return row, col, float(dx), float(dy), warnings


def _slice_step(t, order, files, headers, source):
    """Median step along the normal (mm) after the duplicate and gap checks; warnings."""
    steps = np.diff(t)
    _check_duplicates(steps, t, order, files, headers, source)
    step = float(np.median(steps))
    _check_gaps(steps, step, t, order, files, source)
    if steps.max() - steps.min() <= UNIFORM_TOLERANCE * step:
        return step, []
    drift = np.abs(t - (t[0] + step * np.arange(len(t)))).max()
    return step, [f"slice spacing is not uniform: steps from {steps.min():.4g} to "
                  f"{steps.max():.4g} mm; the volume uses the median {step:.4g} mm, so slices "
                  f"may be placed up to {drift:.3g} mm off"]


def _slice_vector(pos, t, step, normal, pixel, order, files, headers, source):
    """The affine's third column: ``normal * step``, or sheared along the slice origins (tilt)."""
    travel = (pos[-1] - pos[0]) / (t[-1] - t[0])  # origin displacement per mm along the normal
    off = np.linalg.norm(pos - pos[0] - np.outer(t - t[0], travel), axis=1)
    if off.max() > LINE_TOLERANCE_PX * pixel:
        bad = int(np.argmax(off))
        raise AnatomeshError(f"the slice origins do not lie on one line: "
                             f"{_rel(files[order[bad]], source)} is {off[bad]:.3g} mm off; the "
                             "files may belong to different acquisitions; pass the files of one",
                             source)
    tilt = math.degrees(math.atan(float(np.linalg.norm(travel - normal * (travel @ normal)))))
    if tilt <= TILT_TOLERANCE_DEG:
        return normal * step, []
    gantry = _float(headers[order[0]], "GantryDetectorTilt", 0.0)
    named = f", GantryDetectorTilt {gantry:g}°" if gantry else ""
    return travel * step, [f"the slices are sheared by {tilt:.2f}° (gantry tilt{named}); the "
                           "affine reproduces the sheared grid exactly, but tools that assume "
                           "square voxels may need a resampled copy"]


def _same_numbers(files, values: np.ndarray, tol: float, what: str, source):
    """Raise when rows of ``values`` differ from the first by more than ``tol``."""
    if np.all(np.abs(values - values[0]) <= tol):
        return
    keys = [tuple(np.round(v, 4).tolist()) for v in values]
    _same(files, keys, what, lambda v: "[" + ", ".join(f"{x:g}" for x in v) + "]", source)


def _same(files, keys: list, what: str, fmt, source):
    """Raise when ``keys`` (one per slice) differ, listing each group with an example file."""
    if len(set(keys)) == 1:
        return
    groups: Dict[object, List[Path]] = defaultdict(list)
    for k, p in zip(keys, files):
        groups[k].append(p)
    parts = ", ".join(f"{len(ps)} with {fmt(k)} (e.g. {_rel(ps[0], source)})"
                      for k, ps in sorted(groups.items(), key=lambda kv: -len(kv[1])))
    raise AnatomeshError(f"mixed {what} within one series: {parts}; a volume needs one; pass "
                         "only the files that belong together", source)


def _check_duplicates(steps, t, order, files, headers, source):
    dup = np.flatnonzero(steps < DUPLICATE_MM)
    if not len(dup):
        return
    a, b = order[dup[0]], order[dup[0] + 1]
    more = f" ({len(dup) - 1} more such pair(s))" if len(dup) > 1 else ""
    same = _str(headers[a], "SOPInstanceUID") and \
        _str(headers[a], "SOPInstanceUID") == _str(headers[b], "SOPInstanceUID")
    why = "the same image twice (same SOPInstanceUID)" if same else \
        "a duplicated file, or several acquisitions or time points in one series"
    raise AnatomeshError(f"duplicate slice positions: {_rel(files[a], source)} and "
                         f"{_rel(files[b], source)} are both at {t[dup[0]]:.4g} mm along the "
                         f"slice normal{more}: {why}; remove the duplicates "
                         "or pass the files of one acquisition", source)


def _check_gaps(steps, step, t, order, files, source):
    gaps = np.flatnonzero(steps > GAP_FACTOR * step)
    if not len(gaps):
        return
    g = gaps[0]
    missing = max(1, int(round(steps[g] / step)) - 1)
    more = f"; {len(gaps) - 1} more gap(s)" if len(gaps) > 1 else ""
    raise AnatomeshError(f"missing slice(s): the position jumps by {steps[g]:.4g} mm between "
                         f"{_rel(files[order[g]], source)} ({t[g]:.4g} mm) and "
                         f"{_rel(files[order[g + 1]], source)} ({t[g + 1]:.4g} mm) where the usual "
                         f"step is {step:.4g} mm, about {missing} slice(s) missing{more}; copy "
                         "the complete series again", source)


# -- pass 2: pixels -------------------------------------------------------------------------------
def _read_pixels(files: List[Path], headers: list, source: Path, progress) -> np.ndarray:
    """Decode the sorted slices into a (K, rows, cols) stack of stored values."""
    _check_decoders(files, headers, source)
    n_k = len(files)
    rows, cols = _int(headers[0].get("Rows"), 0), _int(headers[0].get("Columns"), 0)
    itemsize = max(1, _int(headers[0].get("BitsAllocated"), 16) // 8)
    # the stack of stored values plus the (at most float32) output
    check_fits_in_memory((cols, rows, n_k), np.float32, "the DICOM series", source,
                         factor=(itemsize + 4) / 4)
    stack = None
    for k, (path, ds) in enumerate(zip(files, headers)):
        arr = _decode(path, ds)
        if arr.shape != (rows, cols):
            raise AnatomeshError(f"the pixel array has shape {arr.shape}, expected "
                                 f"({rows}, {cols}): not a greyscale slice like the others", path)
        if stack is None:
            stack = np.empty((n_k, rows, cols), arr.dtype)
        elif arr.dtype != stack.dtype:
            stack = stack.astype(np.result_type(stack.dtype, arr.dtype))
        stack[k] = arr
        report(progress, (k + 1) / n_k, f"reading slice {k + 1}/{n_k}")
    return stack


def _check_decoders(files, headers, source):
    seen = set()
    for path, ds in zip(files, headers):
        ts = _transfer_syntax(ds)
        if ts in seen:
            continue
        seen.add(ts)
        try:
            decoder = get_decoder(ts)
        except NotImplementedError:
            raise AnatomeshError(f"the pixel data is stored as {ts.name} ({ts}), which pydicom "
                                 "cannot decode; convert the series to uncompressed DICOM first "
                                 "(e.g. dcmtk's dcmdjpeg or gdcmconv --raw)", path) from None
        if not decoder.is_available:
            package = _CODEC_PACKAGES.get(ts, "pylibjpeg pylibjpeg-openjpeg pylibjpeg-libjpeg")
            raise AnatomeshError(f"the pixel data is compressed as {ts.name} ({ts}) and no "
                                 f"decoder for it is installed; install one with 'pip install "
                                 f"{package}' in the Python that runs Anatomesh", source)


def _decode(path: Path, ds) -> np.ndarray:
    try:
        if ds.file_meta.get("TransferSyntaxUID"):
            return pixel_array(path)
        full = pydicom.dcmread(path, force=True)  # bare data set without file meta
        full.file_meta.TransferSyntaxUID = _transfer_syntax(full)
        return full.pixel_array
    except Exception as err:  # decoders raise many kinds on damaged data
        raise AnatomeshError(f"cannot decode the pixel data ({_short(err)}): the file is "
                             "truncated or damaged; copy it again", path) from None


def _transfer_syntax(ds) -> _uid.UID:
    value = ds.file_meta.get("TransferSyntaxUID") if getattr(ds, "file_meta", None) else None
    if value:
        return _uid.UID(str(value))
    implicit, little = getattr(ds, "original_encoding", (True, True))
    if implicit:
        return _uid.ImplicitVRLittleEndian
    return _uid.ExplicitVRLittleEndian if little else _uid.ExplicitVRBigEndian


def _to_volume_layout(stack: np.ndarray, slope: np.ndarray, intercept: np.ndarray) -> np.ndarray:
    """(K, R, C) stored values → C-contiguous (C, R, K) rescaled, int16 when exact, else float32."""
    from ._dicom_kernels import transpose_rescale

    n_k, rows, cols = stack.shape
    integer = stack.dtype.kind in "iu" and all(float(v).is_integer()
                                               for v in np.r_[slope, intercept])
    if integer:
        lo = stack.min(axis=(1, 2)).astype(np.float64)
        hi = stack.max(axis=(1, 2)).astype(np.float64)
        ends = np.r_[lo * slope + intercept, hi * slope + intercept]
        integer = ends.min() >= -32768 and ends.max() <= 32767
    out = np.empty((cols, rows, n_k), np.int16 if integer else np.float32)
    if not stack.dtype.isnative:  # numba reads native byte order only
        stack = stack.astype(stack.dtype.newbyteorder("="))
    kind = np.int64 if integer else np.float64
    transpose_rescale(np.ascontiguousarray(stack), slope.astype(kind), intercept.astype(kind), out)
    return out


# -- metadata and small helpers --------------------------------------------------------------------
def _meta(info: SeriesInfo, headers: list, source: Path, step: float, slope, intercept) -> dict:
    first = headers[0]
    modality = _str(first, "Modality")
    units = "HU" if modality == "CT" else _str(first, "RescaleType") or _str(first, "Units")
    if np.all(slope == slope[0]) and np.all(intercept == intercept[0]):
        rescale = {"slope": float(slope[0]), "intercept": float(intercept[0])}
    else:
        rescale = {"slope": "per slice", "intercept": "per slice",
                   "slope_range": [float(slope.min()), float(slope.max())],
                   "intercept_range": [float(intercept.min()), float(intercept.max())]}
    ts = _transfer_syntax(first)
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
        "window_center": _first_float(first.get("WindowCenter")),
        "window_width": _first_float(first.get("WindowWidth")),
        "source": str(source),
        "n_files": len(headers),
        "slice_spacing": step,
        "slice_thickness": _float(first, "SliceThickness", None),
        "manufacturer": _str(first, "Manufacturer"),
    }


def _floats(ds, keyword: str, n: int, path: Path) -> List[float]:
    value = ds.get(keyword)
    try:
        values = [float(v) for v in _as_list(value)]
    except (TypeError, ValueError):
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise AnatomeshError(f"missing or malformed {keyword} ({value!r}); the slice cannot be "
                             "placed in 3D", path)
    return values


def _as_list(value) -> list:
    if value is None or value == "":
        return []
    return list(value) if isinstance(value, (list, tuple, MultiValue)) else [value]


def _float(ds, keyword: str, default):
    try:
        value = ds.get(keyword)
        return default if value is None or value == "" else float(value)
    except (TypeError, ValueError):
        return default


def _first_float(value) -> Optional[float]:
    try:
        return float(_as_list(value)[0])
    except (TypeError, ValueError, IndexError):
        return None


def _int(value, default):
    try:
        return default if value is None or value == "" else int(value)
    except (TypeError, ValueError):
        return default


def _str(ds, keyword: str) -> str:
    value = ds.get(keyword)
    return "" if value is None else str(value).strip()


def _short(err: Exception) -> str:
    text = str(err).strip().splitlines()
    return (text[0] if text else type(err).__name__)[:160]


def _rel(path: Path, source: Path) -> str:
    try:
        return str(Path(path).relative_to(source))
    except ValueError:
        return str(path)


def _names(paths: List[Path], source: Path, limit: int = 3) -> str:
    shown = ", ".join(_rel(p, source) for p in paths[:limit])
    return shown + (f" and {len(paths) - limit} more" if len(paths) > limit else "")
