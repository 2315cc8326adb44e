"""Saved views of the web page: named states the page lists and shows with a click.

A views file (``--web-views FILE``) is TOML or JSON mapping a view's name to its state, either
the page's URL fragment as text or a table of the same keys::

    "liver cut" = "hide=skin&clip=axial:0.45&view=anterior"

    [lungs]
    opacity = { lung_upper_lobe_left = 0.3, lung_upper_lobe_right = 0.3 }
    hide = ["skin"]
    clip = "coronal:0.6:flip"
    view = "left"

Keys (as the page reads them from its URL, web/src/url-state.js): ``hide`` (structure names),
``opacity`` (name -> 0..1), ``clip`` (``axial|coronal|sagittal:F[:flip]``, F in 0..1 of the
model's extent), ``view`` (anterior, posterior, left, right, superior, inferior), ``camera``
(``TX,TY,TZ;DX,DY,DZ;UX,UY,UZ;ZOOM``), ``measure`` (``X,Y,Z[;X,Y,Z]`` mm, display frame).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Dict, List
from urllib.parse import quote, unquote

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from ...core.model.errors import AnatomeshError

PLANES = ("axial", "coronal", "sagittal")
VIEWS = ("anterior", "posterior", "left", "right", "superior", "inferior")
KEYS = ("hide", "opacity", "clip", "view", "camera", "measure")


def read_views(path) -> List[Dict[str, str]]:
    """The views of a TOML or JSON file: ``[{"name": ..., "fragment": ...}]`` in file order.
    Raises :class:`AnatomeshError` (one line naming the file) for a file that cannot be read or
    a view that is not valid."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        raise AnatomeshError("cannot read the views file; check the path", path) from None
    try:
        doc = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as exc:
        raise AnatomeshError(f"not valid {'JSON' if path.suffix.lower() == '.json' else 'TOML'} "
                             f"({exc}); a views file maps names to URL fragments or tables", path) from None
    if not isinstance(doc, dict) or not doc:
        raise AnatomeshError("a views file maps view names to states, e.g. \"liver cut\" = \"clip=axial:0.5\"", path)
    views = []
    for name, value in doc.items():
        try:
            fragment = value.lstrip("#") if isinstance(value, str) else fragment_of(value)
            check_fragment(fragment)
        except (ValueError, TypeError, AttributeError) as exc:
            raise AnatomeshError(f"view {name!r}: {exc}", path) from None
        views.append({"name": str(name), "fragment": fragment})
    return views


def fragment_of(state: Dict) -> str:
    """A table of view keys as the page's URL fragment (names URL-encoded)."""
    if not isinstance(state, dict):
        raise ValueError("give a URL fragment (text) or a table of " + ", ".join(KEYS))
    unknown = [k for k in state if k not in KEYS]
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r}; keys: {', '.join(KEYS)}")
    parts = []
    for key in KEYS:
        if key not in state:
            continue
        v = state[key]
        if key == "hide":
            v = ",".join(quote(str(n), safe="") for n in ([v] if isinstance(v, str) else v))
        elif key == "opacity":
            v = ",".join(f"{quote(str(n), safe='')}:{a}" for n, a in v.items())
        elif key == "measure" and isinstance(v, list):
            v = ";".join(",".join(str(x) for x in p) for p in v)
        parts.append(f"{key}={v}")
    return "&".join(parts)


def check_fragment(fragment: str) -> None:
    """Raise ValueError naming the first key of ``fragment`` the page would refuse."""
    for part in filter(None, fragment.split("&")):
        key, _, value = part.partition("=")
        if key not in KEYS:
            raise ValueError(f"unknown key {key!r}; keys: {', '.join(KEYS)}")
        if key == "opacity":
            for item in filter(None, value.split(",")):
                name, _, a = item.rpartition(":")
                if not name or not _number(a, 0, 1):
                    raise ValueError(f"opacity is NAME:A with A in 0..1, got {unquote(item)!r}")
        elif key == "clip":
            p = value.split(":")
            if not (2 <= len(p) <= 3 and p[0] in PLANES and _number(p[1], 0, 1) and p[2:] in ([], ["flip"])):
                raise ValueError(f"clip is axial|coronal|sagittal:F with F in 0..1, optional :flip; got {value!r}")
        elif key == "view" and value not in VIEWS:
            raise ValueError(f"view is one of {', '.join(VIEWS)}; got {value!r}")
        elif key == "camera":
            p = value.split(";")
            if len(p) != 4 or not all(_numbers(x, 3) for x in p[:3]) or not _number(p[3], 0, math.inf, open_low=True):
                raise ValueError(f"camera is TX,TY,TZ;DX,DY,DZ;UX,UY,UZ;ZOOM; got {value!r}")
        elif key == "measure":
            p = [x for x in value.split(";") if x]
            if not 1 <= len(p) <= 2 or not all(_numbers(x, 3) for x in p):
                raise ValueError(f"measure is X,Y,Z[;X,Y,Z] in mm; got {value!r}")


def _number(text: str, low: float, high: float, open_low: bool = False) -> bool:
    try:
        x = float(text)
    except ValueError:
        return False
    return math.isfinite(x) and (x > low if open_low else x >= low) and x <= high


def _numbers(text: str, count: int) -> bool:
    p = text.split(",")
    return len(p) == count and all(_number(x, -math.inf, math.inf) for x in p)
