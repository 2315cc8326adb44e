"""Label maps: reading label tables, and deciding what is a label map.

A *label map* is a volume of non-negative integers where each value names a structure and
``0`` is background (never listed in a table). This module

* reads label tables: TotalSegmentator JSON (``{"5": "liver"}``, also files holding several
  tables such as ``{"total": {...}, "total_mr": {...}}``), nnU-Net ``dataset.json`` label
  blocks, 3D Slicer colour tables (``.ctbl``/``.txt``: ``value name r g b a``, 0-255, and the
  ``.csv`` form) and ITK-SNAP label description files (``IDX R G B A VIS MSH "LABEL"``);
* finds a table stored next to an image (:func:`find_sidecar`);
* names the structures and colours them with :func:`anatomesh.core.model.labels.label_table_for`;
* decides whether an image is a label map (:func:`looks_like_label_map`) and attaches its table
  (:func:`resolve_label_map`, used by the NIfTI and NRRD readers).

Name precedence in the readers: an explicit table (``labels=``) > a sidecar table > (NRRD) the
segment names of a 3D Slicer ``.seg.nrrd`` > the file name for a map with a single structure
(``aorta.nii.gz`` → ``aorta``) > generic ``label_<value>``. No table is guessed from the values
alone: TotalSegmentator names are used only when such a table is given or found as a sidecar.
"""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path
from typing import Dict, Iterable, List, Mapping, Optional, Tuple, Union

import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import LabelInfo, label_table_for, name_tokens
from .values import value_counts

#: images with more distinct values than this are not taken for label maps unless forced
MAX_AUTO_LABELS = 512
#: a forced label map (``label_map=True`` or a table given) may hold at most this many values
MAX_LABELS = 65535

_TABLE_HELP = ("expected a TotalSegmentator JSON ({\"5\": \"liver\", ...}), a 3D Slicer colour table "
               "(lines 'value name r g b a', 0-255) or an ITK-SNAP label description file")


# ------------------------------------------------------------------------------------------
# reading label tables
# ------------------------------------------------------------------------------------------
def read_label_table(path, key: Optional[str] = None, values: Optional[Iterable[int]] = None,
                     hint: Optional[str] = None) -> Dict[int, LabelInfo]:
    """Read a label table: value → :class:`LabelInfo` (name, colour in [0, 1]); 0 (background) is left out.

    Formats are recognised by content: JSON (TotalSegmentator ``{"5": "liver"}``, nnU-Net
    ``{"labels": {"liver": 1}}``, or a file of several named tables), 3D Slicer colour tables
    (``value name r g b [a]`` with 0-255 colours, or Slicer's ``.csv``), ITK-SNAP label
    descriptions (``IDX R G B A VIS MSH "LABEL"``). Tables without colours get palette colours.

    Parameters
    ----------
    path : path
        The table file. ``"file.json#total_mr"`` selects the table ``total_mr`` of a multi-table
        JSON (same as ``key="total_mr"``).
    key : str, optional
        Which table of a multi-table JSON to use.
    values : iterable of int, optional
        The label values of the map to be named. Used to pick a table from a multi-table JSON
        when ``key`` is not given: the tables holding every value, then among those the one
        whose name shares a word with ``hint`` (``example_seg_mr`` → ``total_mr``), else the
        first in file order; if no table holds every value, the one holding most.
    hint : str, optional
        The image file name, for the choice above.

    Raises
    ------
    AnatomeshError
        The file is missing, not a label table, or ``key`` is not one of its tables.
    """
    table, _ = load_label_table(path, key=key, values=values, hint=hint)
    return table


def load_label_table(path, key: Optional[str] = None, values: Optional[Iterable[int]] = None,
                     hint: Optional[str] = None) -> Tuple[Dict[int, LabelInfo], str]:
    """:func:`read_label_table`, also returning a description of what was read (``file#key``)."""
    p, key = _split_key(path, key)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise AnatomeshError("label table not found; check the path", p) from None
    except (OSError, UnicodeDecodeError) as err:
        raise AnatomeshError(f"cannot read the label table ({err}); {_TABLE_HELP}", p) from None
    stripped = text.lstrip()
    if not stripped:
        raise AnatomeshError(f"the label table is empty; {_TABLE_HELP}", p)
    if stripped[0] in "{[":
        names, chosen = _parse_json(stripped, p, key, values, hint)
        src = f"{p}#{chosen}" if chosen else str(p)
        return label_table_for(names, names), src
    if key is not None:
        raise AnatomeshError(f"a table key ({key!r}) only applies to JSON files with several tables; "
                             "drop the key", p)
    table = _parse_itksnap(text) or _parse_slicer_csv(text) or _parse_columns(text)
    table = {v: info for v, info in table.items() if v != 0}  # 0 is background
    if not table:
        raise AnatomeshError(f"no label entries found; {_TABLE_HELP}", p)
    return table, str(p)


def _split_key(path, key):
    p = Path(path)
    if key is None and not p.exists() and "#" in p.name:
        name, _, key = p.name.rpartition("#")
        p = p.with_name(name)
    return p, key


def _parse_json(text: str, p: Path, key, values, hint) -> Tuple[Dict[int, str], Optional[str]]:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise AnatomeshError(f"invalid JSON ({err.msg}, line {err.lineno}); {_TABLE_HELP}", p) from None
    if isinstance(doc, dict) and isinstance(doc.get("labels"), dict):  # nnU-Net dataset.json
        doc = doc["labels"]
    flat = _flat_names(doc)
    if flat is not None:
        if key is not None:
            raise AnatomeshError(f"this JSON holds a single table; drop the key {key!r}", p)
        return flat, None
    if not isinstance(doc, dict):
        raise AnatomeshError(f"unrecognised JSON layout; {_TABLE_HELP}", p)
    tables = {k: t for k, t in ((k, _flat_names(v)) for k, v in doc.items()) if t is not None}
    if not tables:
        raise AnatomeshError(f"no label table in this JSON; {_TABLE_HELP}", p)
    if key is not None:
        if key not in tables:
            raise AnatomeshError(f"no table {key!r} in this file; choose one of {', '.join(tables)}", p)
        return tables[key], key
    return _pick_table(tables, values, hint, p)


def _flat_names(obj) -> Optional[Dict[int, str]]:
    """``{"5": "liver"}`` or ``{"liver": 5}`` → {5: "liver"}; None when ``obj`` is not such a table."""
    if not isinstance(obj, dict) or not obj:
        return None
    out: Dict[int, str] = {}
    if all(_is_int_text(k) and isinstance(v, str) for k, v in obj.items()):
        for k, v in obj.items():
            out[int(k)] = v
        return out
    if all(isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool)
           for k, v in obj.items()):
        for k, v in obj.items():
            out[int(v)] = k
        return out
    return None


def _is_int_text(s) -> bool:
    return isinstance(s, str) and re.fullmatch(r"\s*-?\d+\s*", s) is not None


def _pick_table(tables: Dict[str, Dict[int, str]], values, hint, p: Path):
    keys = list(tables)
    if values is None:
        if len(keys) == 1:
            return tables[keys[0]], keys[0]
        raise AnatomeshError(f"this JSON holds several tables ({', '.join(keys)}); choose one with "
                             f"'{p.name}#{keys[0]}'", p)
    vals = {int(v) for v in values if int(v) != 0}
    covered = {k: len(vals & set(tables[k])) for k in keys}
    best = max(covered.values())
    candidates = [k for k in keys if covered[k] == best]
    if len(candidates) > 1 and hint:
        # prefer the table sharing most words with the file name and having fewest words that
        # are not in it: 'example_seg_mr' → 'total_mr', 'example_seg' → 'total'
        words = set(name_tokens(image_stem(hint)))

        def score(k):
            kw = set(name_tokens(k))
            return len(kw & words) - len(kw - words)

        chosen = max(candidates, key=score)  # ties: file order
        return tables[chosen], chosen
    return tables[candidates[0]], candidates[0]


_ITK_LINE = re.compile(r'^\s*(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+([0-9.eE+-]+)\s+(\d+)\s+(\d+)\s+"(.*)"\s*$')


def _parse_itksnap(text: str) -> Dict[int, LabelInfo]:
    out: Dict[int, LabelInfo] = {}
    for line in text.splitlines():
        m = _ITK_LINE.match(line)
        if m:
            v = int(m.group(1))
            rgb = tuple(min(255, int(m.group(i))) / 255.0 for i in (2, 3, 4))
            out[v] = LabelInfo(v, m.group(8).strip() or f"label_{v}", rgb, color_given=True)
    return out


def _parse_slicer_csv(text: str) -> Dict[int, LabelInfo]:
    """Slicer's CSV colour table: a header row with LabelValue, Name, Color_R, Color_G, Color_B."""
    first = text.lstrip().splitlines()[0] if text.strip() else ""
    if "LabelValue" not in first or "," not in first:
        return {}
    out: Dict[int, LabelInfo] = {}
    try:
        for row in csv.DictReader(text.lstrip().splitlines()):
            v = int(row["LabelValue"])
            rgb = tuple(float(row[c]) / 255.0 for c in ("Color_R", "Color_G", "Color_B"))
            out[v] = LabelInfo(v, (row.get("Name") or f"label_{v}").strip(), rgb, color_given=True)
    except (KeyError, ValueError, TypeError):
        return {}
    return out


def _parse_columns(text: str) -> Dict[int, LabelInfo]:
    """3D Slicer/FreeSurfer colour table lines ``value name r g b [a]``; plain ``value name`` lines too.

    Names may contain spaces (all tokens between the value and the colour). Lines starting with
    ``#`` are comments. Returns {} when any non-comment line does not fit (not such a table).
    """
    named: Dict[int, str] = {}
    out: Dict[int, LabelInfo] = {}
    for line in text.splitlines():
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split()
        if len(parts) < 2 or not _is_int_text(parts[0]):
            return {}
        v = int(parts[0])
        nums = 0
        while nums < 4 and len(parts) - 1 - nums > 1 and _is_int_text(parts[-1 - nums]):
            nums += 1
        if nums >= 3:
            rgb_tokens = parts[len(parts) - nums:len(parts) - nums + 3]
            name = " ".join(parts[1:len(parts) - nums])
            rgb = tuple(min(255, max(0, int(t))) / 255.0 for t in rgb_tokens)
            out[v] = LabelInfo(v, name, rgb, color_given=True)
        else:
            named[v] = " ".join(parts[1:])
    if named:
        out.update(label_table_for(named, named))
    return out


def find_sidecar(image_path, folder_tables: bool = True) -> Optional[Path]:
    """A label table stored next to an image, or None.

    Rule, in this order (the first readable label table wins; a candidate that is not a label
    table, e.g. a BIDS ``.json`` of acquisition parameters, is skipped):

    1. same stem as the image plus ``.ctbl``, ``.txt``, ``.csv``, ``.json`` (``seg.nii.gz`` →
       ``seg.ctbl``, ``seg.txt``, ...), and ``<stem>_labels.*`` / ``<stem>.labels.*``;
    2. unless ``folder_tables`` is False: ``label_names*.json`` files in the same folder
       (TotalSegmentator's name files), sorted. The readers skip these for a single-structure
       mask, which is named after its file instead (``liver.nii.gz`` is not "spleen").
    """
    p = Path(image_path)
    folder = p.parent
    stem = image_stem(p)
    candidates: List[Path] = []
    for base in (stem, f"{stem}_labels", f"{stem}.labels"):
        for ext in (".ctbl", ".txt", ".csv", ".json"):
            candidates.append(folder / f"{base}{ext}")
    if folder_tables:
        try:
            candidates += sorted(folder.glob("label_names*.json"))
        except OSError:
            pass
    for c in candidates:
        if c.is_file() and c != p:
            try:
                load_label_table(c, values=[])
            except AnatomeshError:
                continue
            return c
    return None


def image_stem(path) -> str:
    """The file name without its image extensions: ``aorta.nii.gz`` → ``aorta``, ``a.seg.nrrd`` → ``a``."""
    name = Path(path).name
    for ext in (".seg.nrrd", ".seg.nhdr", ".nii.gz", ".nii", ".nrrd", ".nhdr", ".gz"):
        if name.lower().endswith(ext) and len(name) > len(ext):
            return name[: -len(ext)]
    return Path(name).stem


# ------------------------------------------------------------------------------------------
# is it a label map?
# ------------------------------------------------------------------------------------------
def _slabs(data: np.ndarray):
    """Views of ``data`` along its slowest axis in memory (contiguous chunks, bounded memory)."""
    if data.ndim == 0:
        yield data.reshape(1)
        return
    if data.flags.f_contiguous and not data.flags.c_contiguous:
        for i in range(data.shape[-1]):
            yield data[..., i]
    else:
        for i in range(data.shape[0]):
            yield data[i]


def is_integer_valued(data: np.ndarray) -> bool:
    """True when every voxel is a finite whole number (integer and bool dtypes always are)."""
    if data.dtype.kind in "biu":
        return True
    if data.dtype.kind != "f":
        return False
    for s in _slabs(data):
        if not (np.isfinite(s).all() and np.array_equal(s, np.floor(s))):
            return False
    return True


def distinct_values(data: np.ndarray, limit: Optional[int] = None) -> Optional[np.ndarray]:
    """Sorted distinct values of an integer-valued array; None when there are more than ``limit``.

    One counting pass over the voxels without copying them (:func:`.values.value_counts`).
    """
    values = value_counts(data)[0]
    if limit is not None and values.size > limit:
        return None
    return values


def looks_like_label_map(data: np.ndarray, max_labels: int = MAX_AUTO_LABELS) -> bool:
    """Guess whether ``data`` is a label map rather than a scan.

    Rule: every value is a finite whole number, the minimum is >= 0, and there are at most
    ``max_labels`` (512) distinct values, background included. So a CT (negative HU) never is
    one, a binary 0/1 mask always is, and an MR or CT with thousands of grey values is not. A
    low-bit scan with few grey values (e.g. 8-bit, <= 512 levels) *is* taken for a label map:
    pass ``label_map=False`` to the reader for those.
    """
    data = np.asarray(data)
    if data.size == 0 or data.dtype.kind not in "biuf":
        return False
    if data.dtype.kind == "b":
        return True
    if not is_integer_valued(data) or data.min() < 0:
        return False
    return distinct_values(data, limit=max_labels) is not None


def label_dtype(max_value: int) -> np.dtype:
    """Smallest of uint8 / uint16 / int32 holding ``max_value``."""
    for dt in (np.uint8, np.uint16, np.int32):
        if max_value <= np.iinfo(dt).max:
            return np.dtype(dt)
    raise ValueError(f"label value {max_value} does not fit in int32")


def as_label_array(data: np.ndarray, max_value: int) -> np.ndarray:
    """``data`` (integer-valued, >= 0) as uint8/uint16/int32, copied only when the dtype changes."""
    dt = label_dtype(int(max_value))
    return data if data.dtype == dt else data.astype(dt)


# ------------------------------------------------------------------------------------------
# what the readers call
# ------------------------------------------------------------------------------------------
def resolve_label_map(data: np.ndarray, path, *, labels=None, label_map: Optional[bool] = None,
                      hint_label: bool = False, names: Optional[Mapping[int, LabelInfo]] = None,
                      names_source: str = "") -> Tuple[np.ndarray, Optional[Dict[int, LabelInfo]], List[str], Dict]:
    """Decide whether a freshly read image is a label map and build its table.

    Parameters
    ----------
    data : np.ndarray, shape (I, J, K)
        The voxels, scaling applied.
    path : path
        The image file (for the sidecar search, the single-structure name and messages).
    labels : path, optional
        An explicit label table; it makes the image a label map (unless ``label_map=False``).
    label_map : bool, optional
        True forces a label map, False forbids one, None decides by :func:`looks_like_label_map`.
    hint_label : bool
        The file says it is a label map (NIfTI intent ``label``); decided like ``label_map=None``
        but without the 512-value limit.
    names, names_source : optional
        Names the file itself carries (a ``.seg.nrrd``'s segments) and where they come from.

    Returns
    -------
    data : np.ndarray
        Unchanged for a scan; for a label map, uint8/uint16/int32.
    table : dict int → LabelInfo or None
        None for a scan.
    warnings : list of str
    meta : dict
        ``label_table`` (where the names come from) for a label map.

    Raises
    ------
    AnatomeshError
        A label map was asked for (``label_map=True`` or ``labels=``) but the values are not
        non-negative whole numbers (NaN, fractions, negative values), or there are too many.
    """
    p = Path(path)
    warnings: List[str] = []
    if label_map is False:
        if labels is not None:
            warnings.append("a label table was given but label_map=False: the image is read as a scan")
        return data, None, warnings, {}
    forced = label_map is True or labels is not None or names is not None
    if forced:
        why = ("a label table was given" if labels is not None else
               "label_map=True was given" if names is None else "the file is a segmentation")
        values = _check_label_values(data, p, why)
    else:
        if data.size == 0 or not is_integer_valued(data) or data.min() < 0:
            return data, None, warnings, {}
        values = distinct_values(data, limit=MAX_LABELS if hint_label else MAX_AUTO_LABELS)
        if values is None:
            return data, None, warnings, {}
    data = as_label_array(data, int(values.max()) if values.size else 0)
    nonzero = [int(v) for v in values if v != 0]
    if not nonzero:
        warnings.append("the label map is empty (all voxels are 0, background)")

    table_names: Optional[Mapping[int, Union[str, LabelInfo]]] = None
    source = ""
    if labels is not None:
        table_names, source = load_label_table(labels, values=nonzero, hint=p.name)
    elif names is not None:
        table_names, source = names, names_source
    else:
        side = find_sidecar(p, folder_tables=len(nonzero) != 1)
        if side is not None:
            table_names, source = load_label_table(side, values=nonzero, hint=p.name)
    if table_names is None and len(nonzero) == 1:
        table_names, source = {nonzero[0]: image_stem(p)}, "file name"
    if table_names is not None:
        missing = [v for v in nonzero if v not in table_names]
        if missing:
            shown = ", ".join(str(v) for v in missing[:10]) + (" ..." if len(missing) > 10 else "")
            warnings.append(f"{len(missing)} label value(s) not in the label table {source} "
                            f"({shown}): named label_<value>")
    table = label_table_for(nonzero, table_names)
    return data, table, warnings, {"label_table": source or "generic names"}


def _check_label_values(data: np.ndarray, p: Path, why: str) -> np.ndarray:
    if data.dtype.kind not in "biuf":
        raise AnatomeshError(f"{why} but the voxels are of type {data.dtype}, not numbers; give "
                             "a label map of whole numbers", p)
    if data.dtype.kind == "f":
        bad = int(data.size - np.count_nonzero(np.isfinite(data)))
        if bad:
            raise AnatomeshError(f"{why} but {bad} voxels are NaN or infinite; a label map holds "
                                 "whole numbers only: fix the file", p)
        if not is_integer_valued(data):
            raise AnatomeshError(f"{why} but the voxels have fractional values; this looks like a "
                                 "scan: read it without a label table", p)
    if data.size and data.min() < 0:
        raise AnatomeshError(f"{why} but the image has negative values (min {data.min():g}); a "
                             "label map holds values >= 0: is this a scan? Then read it without a label "
                             "table", p)
    values = distinct_values(data, limit=MAX_LABELS)
    if values is None:
        raise AnatomeshError(f"{why} but the image has more than {MAX_LABELS} distinct values; "
                             "that is a scan, not a label map: read it without a label table", p)
    if values.size and values.max() > np.iinfo(np.int32).max:
        raise AnatomeshError(f"label value {int(values.max())} is too large (limit 2^31-1); "
                             "renumber the labels", p)
    return values
