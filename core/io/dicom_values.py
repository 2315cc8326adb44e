"""Reading DICOM attribute values safely: numbers, lists and text with defaults, and short
path/error texts for the one-line messages of the series reader."""
from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional

from pydicom.multival import MultiValue

from ..model.errors import AnatomeshError


def floats(ds, keyword: str, n: int, path: Path) -> List[float]:
    value = ds.get(keyword)
    try:
        values = [float(v) for v in as_list(value)]
    except (TypeError, ValueError):
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise AnatomeshError(f"missing or malformed {keyword} ({value!r}), so the image cannot be "
                             "placed in space; export the file again with its geometry", path)
    return values


def as_list(value) -> list:
    if value is None or value == "":
        return []
    return list(value) if isinstance(value, (list, tuple, MultiValue)) else [value]


def float_or(ds, keyword: str, default):
    try:
        value = ds.get(keyword)
        return default if value is None or value == "" else float(value)
    except (TypeError, ValueError):
        return default


def first_float(value) -> Optional[float]:
    try:
        return float(as_list(value)[0])
    except (TypeError, ValueError, IndexError):
        return None


def int_or(value, default):
    try:
        return default if value is None or value == "" else int(value)
    except (TypeError, ValueError):
        return default


def text_of(ds, keyword: str) -> str:
    value = ds.get(keyword)
    return "" if value is None else str(value).strip()


def rel_path(path: Path, source: Path) -> str:
    try:
        return str(Path(path).relative_to(source))
    except ValueError:
        return str(path)


def file_names(paths: List[Path], source: Path, limit: int = 3) -> str:
    shown = ", ".join(rel_path(p, source) for p in paths[:limit])
    return shown + (f" and {len(paths) - limit} more" if len(paths) > limit else "")
