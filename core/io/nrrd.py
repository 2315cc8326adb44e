"""NRRD (``.nrrd``, ``.nhdr`` + detached data, 3D Slicer ``.seg.nrrd``) → Volume, with pynrrd.

Geometry (NRRD spec, http://teem.sourceforge.net/nrrd/format.html):
``affine[:3, :3]`` columns are the ``space directions`` of the three spatial axes, in axis
order (pynrrd reads with ``index_order='F'``, so ``data[i, j, k]`` is the sample at axis
positions i, j, k); ``affine[:3, 3]`` is ``space origin``, the centre of the first sample.
``space`` decides the Volume's space: ``left-posterior-superior`` → LPS,
``right-anterior-superior`` → RAS, ``left-anterior-superior`` → converted to LPS (y negated).
``scanner-xyz`` / ``3D-right-handed`` / ``3D-left-handed`` do not name patient directions: they
are taken as LPS (as ITK does) with a warning. A file with no space at all (only
``spacings``/``axis mins``, or ``space directions`` without ``space``) is read with its axes
taken as LPS, spacing from ``spacings`` (1 mm if absent), origin from ``axis mins`` (0 if
absent), and a warning saying the orientation is unknown. Time-varying spaces are rejected.
``space units`` in m or µm are converted to mm.

Axes: exactly three spatial axes (kind ``domain``/``space``, or a ``space directions`` entry that
is not ``none``). One extra non-spatial axis of length 1 is dropped; a longer one is accepted
only for a 3D Slicer segmentation (its layers), anything else (vectors, RGB, DWI lists) is
rejected.

3D Slicer segmentations (``Segment<N>_*`` header fields, see Slicer's developer guide
"Segmentation labelmap file format (.seg.nrrd)"): each segment has a ``Layer`` (which 3D volume
of the list axis holds it; default: its index) and a ``LabelValue`` in that layer (default 1),
a ``Name`` and a ``Color`` (r g b in [0, 1]). They become one label map with one label per
segment. Several layers are merged when no voxel belongs to two segments; the segments keep
their label values when these are unique across layers, else they are numbered 1..N in header
order (with a warning). Overlapping segments are an error (not supported yet): the message
names two overlapping segments and says how to avoid it.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.volume import Volume, check_fits_in_memory
from ..model.labels import LabelInfo
from ._reader_common import finish_volume
from .library_messages import notes_of_library, reason
from .label_tables import distinct_values, label_dtype

_SPACES = {
    "left-posterior-superior": "LPS", "lps": "LPS",
    "right-anterior-superior": "RAS", "ras": "RAS",
    "left-anterior-superior": "LAS", "las": "LAS",
}
_NON_PATIENT_SPACES = ("scanner-xyz", "3d-right-handed", "3d-left-handed")
_SPATIAL_KINDS = ("domain", "space")
_UNITS_TO_MM = {"mm": 1.0, "millimeter": 1.0, "millimeters": 1.0, "cm": 10.0, "m": 1000.0,
                "meter": 1000.0, "meters": 1000.0, "um": 1e-3, "µm": 1e-3, "micron": 1e-3,
                "microns": 1e-3, "micrometer": 1e-3, "micrometers": 1e-3}
_TYPES = {
    np.dtype(np.int8): ("signed char", "int8", "int8_t"),
    np.dtype(np.uint8): ("uchar", "unsigned char", "uint8", "uint8_t"),
    np.dtype(np.int16): ("short", "short int", "signed short", "signed short int", "int16", "int16_t"),
    np.dtype(np.uint16): ("ushort", "unsigned short", "unsigned short int", "uint16", "uint16_t"),
    np.dtype(np.int32): ("int", "signed int", "int32", "int32_t"),
    np.dtype(np.uint32): ("uint", "unsigned int", "uint32", "uint32_t"),
    np.dtype(np.int64): ("longlong", "long long", "long long int", "signed long long",
                         "signed long long int", "int64", "int64_t"),
    np.dtype(np.uint64): ("ulonglong", "unsigned long long", "unsigned long long int", "uint64",
                          "uint64_t"),
    np.dtype(np.float32): ("float",),
    np.dtype(np.float64): ("double",),
}
_TYPE_OF = {name: dt for dt, names in _TYPES.items() for name in names}
_SEGMENT_FIELD = re.compile(r"^Segment(\d+)_(\w+)$")


@notes_of_library
def read_nrrd(path, labels=None, label_map: Optional[bool] = None) -> Volume:
    """Read a ``.nrrd``/``.nhdr`` file (``.seg.nrrd`` segmentations included).

    Parameters
    ----------
    path : path
        The NRRD file, or the ``.nhdr`` header of a detached one.
    labels : path, optional
        A label table; makes the image a label map and overrides segment names.
    label_map : bool, optional
        Force (True) or forbid (False) a label map; by default a segmentation always is one, and
        other images are decided by :func:`~anatomesh.core.io.label_tables.looks_like_label_map`.

    Returns
    -------
    Volume
        ``data`` shape (I, J, K) (float64 scans become float32; label maps uint8/uint16/int32);
        ``affine`` voxel → mm in ``space`` (LPS or RAS as the file says); ``meta`` with
        ``format``, ``source``, ``nrrd_space``, ``encoding``, ``segments`` (segmentations).

    Raises
    ------
    AnatomeshError
        Not NRRD, corrupt or missing data, unsupported axes or space, overlapping segments, or
        too large for the available memory.
    """
    import nrrd

    p = Path(path)
    header = _read_header(p, nrrd)
    sizes = [int(s) for s in np.atleast_1d(header.get("sizes", []))]
    spatial, extra = _axes(header, sizes, p)
    segments = _segments(header)
    if extra is not None and sizes[extra] > 1 and not segments:
        kind = (header.get("kinds") or ["?"] * len(sizes))[extra]
        raise AnatomeshError(
            f"the image has {sizes[extra]} values per voxel (axis {extra}, kind '{kind}', sizes "
            f"{tuple(sizes)}); only scalar volumes and 3D Slicer segmentations are supported: "
            "extract one component first", p)
    warnings: List[str] = []
    affine, space = _affine(header, spatial, p, warnings)

    dtype = _TYPE_OF.get(str(header.get("type", "")).strip().lower())
    if dtype is None:
        raise AnatomeshError(f"unsupported NRRD sample type {header.get('type')!r}; convert it to an "
                             "integer or float type", p)
    shape3 = tuple(sizes[a] for a in spatial)
    n_extra = sizes[extra] if extra is not None else 1
    out = np.dtype(np.float32) if dtype.kind == "f" else dtype
    check_fits_in_memory(shape3, dtype, "NRRD volume", p,
                         factor=n_extra + (out.itemsize / dtype.itemsize if out != dtype or segments else 0))

    data = _read_data(p, header, nrrd)
    if data.shape != tuple(sizes):
        raise AnatomeshError(f"the data has shape {data.shape} but the header says sizes {tuple(sizes)}: "
                             "the file is damaged; export it again", p)
    if extra is not None:
        data = np.moveaxis(data, extra, 0)
    else:
        data = data[None]  # one layer
    meta: Dict = {
        "format": "NRRD",
        "source": str(p),
        "nrrd_space": header.get("space", header.get("space dimension", "")),
        "encoding": header.get("encoding", ""),
        "dtype_on_disk": dtype.name,
        "shape_on_disk": tuple(sizes),
        "description": str(header.get("content", "")),
    }
    if segments:
        data, names, seg_warnings = _merge_segments(data, segments, p)
        warnings += seg_warnings
        meta["segments"] = [s["name"] for s in segments]
        return finish_volume(data, affine, space, meta, p, warnings, labels=labels,
                             label_map=label_map, names=names,
                             names_source="3D Slicer segment names")
    return finish_volume(data[0], affine, space, meta, p, warnings, labels=labels,
                         label_map=label_map)


def _read_header(p: Path, nrrd) -> Dict:
    try:
        with open(p, "rb") as fh:
            return dict(nrrd.read_header(fh))
    except FileNotFoundError:
        raise AnatomeshError("no such file; check the path", p) from None
    except Exception as err:  # NRRDError, UnicodeDecodeError, ValueError from malformed fields
        raise AnatomeshError(f"not a readable NRRD header ({reason(err)}); check that it is a "
                             "complete .nrrd/.nhdr file", p) from None


def _read_data(p: Path, header: Dict, nrrd) -> np.ndarray:
    try:
        with open(p, "rb") as fh:
            nrrd.read_header(fh)  # leaves fh at the start of attached data
            data = nrrd.read_data(header, fh, str(p), index_order="F")
    except MemoryError:
        raise AnatomeshError("not enough memory to read the voxel data; close other programs or use a "
                             "machine with more memory", p) from None
    except Exception as err:  # truncated gzip, missing detached file, size mismatch...
        raise AnatomeshError(f"could not read the voxel data ({reason(err)}): the file or its "
                             "detached data file is truncated, missing or corrupt", p) from None
    return np.asarray(data)


def _axes(header: Dict, sizes: List[int], p: Path) -> Tuple[List[int], Optional[int]]:
    """Indices of the three spatial axes and of the (at most one) other axis."""
    n = len(sizes)
    kinds = [str(k).lower() for k in header.get("kinds", [])] if header.get("kinds") else []
    dirs = header.get("space directions")
    if dirs is not None:
        rows = np.asarray(dirs, dtype=np.float64)
        spatial = [a for a in range(min(n, rows.shape[0])) if np.all(np.isfinite(rows[a]))]
    elif len(kinds) == n and any(k in _SPATIAL_KINDS for k in kinds):
        spatial = [a for a in range(n) if kinds[a] in _SPATIAL_KINDS]
    else:
        spatial = list(range(n)) if n == 3 else [a for a in range(n) if a >= n - 3]
    others = [a for a in range(n) if a not in spatial]
    if len(spatial) != 3 or len(others) > 1:
        raise AnatomeshError(f"the image has {len(spatial)} spatial axes (sizes {tuple(sizes)}, "
                             f"kinds {kinds or 'not given'}); only 3D volumes are supported: give a 3D "
                             "volume", p)
    return spatial, (others[0] if others else None)


def _affine(header: Dict, spatial: List[int], p: Path, warnings: List[str]):
    space_raw = str(header.get("space", "")).strip()
    space_key = space_raw.lower()
    dirs = header.get("space directions")
    if space_key.endswith("-time") or space_key in ("rast", "last", "lpst") or (
            not space_raw and int(header.get("space dimension", 3)) != 3):
        raise AnatomeshError(f"time-varying or non-3D space {space_raw or header.get('space dimension')!r} "
                             "is not supported; export a single 3D volume", p)
    affine = np.eye(4)
    if dirs is not None:
        rows = np.asarray(dirs, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != 3:
            raise AnatomeshError(f"'space directions' must be 3-vectors, got {rows.shape}: the header is "
                                 "damaged; fix it or export the file again", p)
        affine[:3, :3] = rows[spatial].T
        origin = header.get("space origin")
        if origin is not None:
            affine[:3, 3] = np.asarray(origin, dtype=np.float64)
        elif space_raw:
            warnings.append("no 'space origin' in the header: origin set to (0, 0, 0)")
    else:
        spacings = _per_axis(header, "spacings", spatial, 1.0)
        mins = _per_axis(header, "axis mins", spatial, 0.0)
        affine[:3, :3] = np.diag(spacings)
        affine[:3, 3] = mins
    if space_key in _SPACES:
        space = _SPACES[space_key]
        if dirs is None:
            raise AnatomeshError(f"space {space_raw!r} given without 'space directions'; the "
                                 "header is incomplete; export the file again", p)
    elif space_key in _NON_PATIENT_SPACES:
        space = "LPS"
        warnings.append(f"NRRD space {space_raw!r} does not name patient directions; its axes are "
                        "taken as LPS (as ITK does): check left/right")
    elif space_raw:
        raise AnatomeshError(f"unknown NRRD space {space_raw!r}; use left-posterior-superior or "
                             "right-anterior-superior", p)
    else:
        space = "LPS"
        what = ("'space directions' without a 'space' field" if dirs is not None else
                "no space information (space, space directions)")
        sp = tuple(round(float(s), 6) for s in np.linalg.norm(affine[:3, :3], axis=0))
        warnings.append(f"the header has {what}: orientation unknown, the axes are taken as LPS "
                        f"with spacing {sp} mm; check the orientation before measuring")
    if space == "LAS":  # convert to LPS: y (anterior → posterior) changes sign
        affine[1, :] *= -1.0
        space = "LPS"
    units = header.get("space units")
    if units is not None:
        factors = {_UNITS_TO_MM.get(str(u).strip().lower()) for u in units}
        if None in factors or len(factors) != 1:
            warnings.append(f"space units {list(units)} not understood: taken as mm")
        elif factors != {1.0}:
            affine[:3, :] *= factors.pop()
            warnings.append(f"space units {list(units)} converted to mm")
    if not np.all(np.isfinite(affine)):
        raise AnatomeshError("the geometry (space directions/origin) holds NaN or infinite numbers; "
                             "fix the header", p)
    if abs(np.linalg.det(affine[:3, :3])) < 1e-12:
        raise AnatomeshError("the space directions are degenerate (zero or parallel axes); fix the header", p)
    return affine, space


def _per_axis(header: Dict, field: str, spatial: List[int], default: float) -> np.ndarray:
    vals = header.get(field)
    out = np.full(3, default)
    if vals is not None:
        arr = np.asarray(vals, dtype=np.float64)
        for i, a in enumerate(spatial):
            if a < arr.size and np.isfinite(arr[a]):
                out[i] = arr[a]
    return out


# ------------------------------------------------------------------------------------------
# 3D Slicer segmentations
# ------------------------------------------------------------------------------------------
def _segments(header: Dict) -> List[Dict]:
    """Segment descriptions from ``Segment<N>_<Field>`` header entries, in index order."""
    fields: Dict[int, Dict[str, str]] = {}
    for key, value in header.items():
        m = _SEGMENT_FIELD.match(str(key))
        if m:
            fields.setdefault(int(m.group(1)), {})[m.group(2)] = str(value).strip()
    segs = []
    for idx in sorted(fields):
        f = fields[idx]
        seg = {"index": idx, "name": f.get("Name") or f.get("ID") or f"Segment_{idx}",
               "layer": _int(f.get("Layer"), idx if "LabelValue" not in f else 0),
               "label_value": _int(f.get("LabelValue"), 1), "color": None}
        try:
            rgb = [float(c) for c in f.get("Color", "").split()]
            if len(rgb) == 3 and all(0.0 <= c <= 1.0 for c in rgb):
                seg["color"] = tuple(rgb)
        except ValueError:
            pass
        segs.append(seg)
    return segs


def _int(text: Optional[str], default: int) -> int:
    try:
        return int(float(text)) if text not in (None, "") else default
    except ValueError:
        return default


def _merge_segments(layers: np.ndarray, segments: List[Dict], p: Path):
    """(L, I, J, K) layers + segment list → one (I, J, K) label map and its names."""
    n_layers = layers.shape[0]
    warnings: List[str] = []
    if layers[0].size == 1:
        raise AnatomeshError("the segmentation holds no voxels (Slicer saves empty segmentations "
                             "as a single voxel); paint the segments and save again", p)
    for s in segments:
        if not 0 <= s["layer"] < n_layers:
            raise AnatomeshError(f"segment {s['name']!r} is in layer {s['layer']} but the file has "
                                 f"{n_layers} layer(s): the file is damaged; save it again from 3D Slicer", p)
    values = [s["label_value"] for s in segments]
    unique = len(set(values)) == len(values)
    if n_layers == 1 and unique:
        out = layers[0]
        new_values = values
    else:
        _check_overlap(layers, segments, p)
        new_values = values if unique else list(range(1, len(segments) + 1))
        if not unique:
            warnings.append("segment label values repeat across layers; segments are numbered "
                            f"1..{len(segments)} in header order")
        out = np.zeros(layers.shape[1:], dtype=label_dtype(max(new_values, default=0)))
        for s, v in zip(segments, new_values):
            out[layers[s["layer"]] == s["label_value"]] = v
    names = {}
    for s, v in zip(segments, new_values):
        color = s["color"]
        names[v] = LabelInfo(v, s["name"], color, color_given=True) if color is not None else s["name"]
    present = set(distinct_values(out).tolist())
    empty = [s["name"] for s, v in zip(segments, new_values) if v not in present]
    if empty:
        warnings.append(f"empty segment(s), no voxels: {', '.join(empty)}")
    return out, names, warnings


def _check_overlap(layers: np.ndarray, segments: List[Dict], p: Path) -> None:
    """Raise when a voxel belongs to segments of two different layers."""
    if layers.shape[0] < 2:
        return
    count = np.zeros(layers.shape[1:], dtype=np.uint8)
    for layer in layers:
        count += layer != 0
    hit = np.argwhere(count > 1)
    if hit.size == 0:
        return
    ijk = tuple(int(c) for c in hit[0])
    found = [s["name"] for s in segments if layers[s["layer"]][ijk] == s["label_value"]]
    pair = " and ".join(repr(n) for n in found[:2]) or "two segments"
    raise AnatomeshError(
        f"segments {pair} overlap ({len(hit)} voxels, e.g. voxel {ijk}); overlapping segments are "
        "not supported yet: in 3D Slicer export each segment to its own file (Segmentations "
        "module, Export to files) or remove the overlap (Segment Editor, Masking: 'Overwrite other "
        "segments') and save again", p)


