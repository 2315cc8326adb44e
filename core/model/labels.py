"""Label tables: what each label value is called and its colour, and colours in general.

* :class:`LabelInfo` — one entry (value, name, colour r, g, b in [0, 1], sRGB, material class,
  opacity);
* structures are coloured by the style table (:mod:`anatomesh.core.model.style`;
  :func:`anatomical_color`), others by distinct hues spaced by the golden ratio
  (:func:`distinct_color`); :func:`label_table_for` builds a table for the values of a map;
* :func:`select_labels` resolves a user's choice ("all", values, names) against a volume's table;
* sRGB ↔ linear conversions (IEC 61966-2-1) for writers and renderers that want linear colour.

Reading table files is :mod:`anatomesh.core.io.label_tables`' job.
"""
from __future__ import annotations

import colorsys
import dataclasses
import difflib
import re
from dataclasses import dataclass
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import AnatomeshError
from .style import StyleTable, default_style, shade


@dataclass
class LabelInfo:
    """One entry of a label table: integer value, display name, colour (r, g, b) sRGB in [0, 1],
    material class (one of :data:`anatomesh.core.model.style.MATERIALS`) and opacity 0..1
    (1 opaque), as the style table gives them (:mod:`anatomesh.core.model.style`)."""

    value: int
    name: str
    color: Tuple[float, float, float] = (0.8, 0.8, 0.8)
    material: str = "other"
    opacity: float = 1.0
    #: True when the colour came from the user (a colour table, DICOM SEG/RTSTRUCT display
    #: colours, a Slicer segment): styling and contrast keep it as is
    color_given: bool = False

    def mesh_color(self) -> Tuple[float, ...]:
        """The ``Mesh.color`` of this label: (r, g, b), or (r, g, b, opacity) when see-through."""
        rgb = tuple(float(c) for c in tuple(self.color)[:3])
        return rgb + (float(self.opacity),) if self.opacity < 1.0 else rgb


_GOLDEN = 0.618033988749895


def name_tokens(name: str) -> List[str]:
    """Lower-case words of a name: 'kidney_cyst_left' → ['kidney', 'cyst', 'left']."""
    spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", str(name))  # LeftKidney → Left Kidney
    return [t for t in re.split(r"[^a-z0-9]+", spaced.lower()) if t]


def anatomical_color(name: str) -> Optional[Tuple[float, float, float]]:
    """The conventional colour (r, g, b in [0, 1]) of a structure in the default style table
    (:mod:`anatomesh.core.model.style`: 3D Slicer's GenericAnatomyColors, adjusted): by its
    name, a synonym or keywords in it. None when only the fallback knows the name (the caller
    picks a distinct colour).

    >>> anatomical_color("vertebrae_L3") == anatomical_color("rib_left_1")
    True
    """
    st = default_style().style_of(name)
    return None if st.source == "fallback" else st.color


# --- body systems (web page tree), from the style table's material classes
#: the systems in the order a structure tree lists them
SYSTEMS = ("organs", "vessels", "heart", "bones", "muscles", "nerves", "airways", "lesions", "other")
_SYSTEM_OF_MATERIAL = {
    "parenchyma": "organs", "hollow": "organs", "artery": "vessels", "vein": "vessels",
    "bone": "bones", "cartilage": "bones", "muscle": "muscles", "nerve": "nerves",
    "airway": "airways", "lesion": "lesions", "fat": "other", "skin": "other", "other": "other",
}
_HEART_WORDS = ("heart", "myocardium", "cardiac", "atrium", "atrial", "ventricle", "appendage")


def structure_system(name: str) -> str:
    """The body system of a structure, one of :data:`SYSTEMS`, from its material class in the
    default style table (heart muscle is ``"heart"``): ``"kidney_cyst_left"`` → ``"lesions"``,
    ``"vertebrae_L3"`` → ``"bones"``, ``"portal_vein_and_splenic_vein"`` → ``"vessels"``; names
    only the fallback knows → ``"other"``."""
    st = default_style().style_of(name)
    if st.source == "fallback":
        return "other"
    if st.material == "muscle" and any(w in name_tokens(name) for w in _HEART_WORDS):
        return "heart"
    return _SYSTEM_OF_MATERIAL.get(st.material, "other")


def distinct_color(value: int) -> Tuple[float, float, float]:
    """A saturated colour for ``value``: hues spaced by the golden ratio, so consecutive values differ."""
    hue = (int(value) * _GOLDEN) % 1.0
    return tuple(float(c) for c in colorsys.hsv_to_rgb(hue, 0.6, 0.9))


def label_table_for(values: Iterable[int],
                    names: Optional[Mapping[int, Union[str, LabelInfo]]] = None) -> Dict[int, LabelInfo]:
    """A label table for the non-zero ``values``: names from ``names``, colours from the palette.

    Parameters
    ----------
    values : iterable of int
        Label values present in a map; 0 (background) is skipped.
    names : mapping int → str or LabelInfo, optional
        Known names. A :class:`LabelInfo` keeps its own colour (e.g. from a colour table);
        a plain name gets the default style table's colour (:mod:`.style`; bones shaded a
        little per value) or, when the table does not know it, :func:`distinct_color`. Material
        class and opacity come from the style table by name. Values without a name are
        ``label_<value>``.

    Returns
    -------
    dict int → LabelInfo, sorted by value. Deterministic: the same value and name always get
    the same colour.
    """
    names = names or {}
    out: Dict[int, LabelInfo] = {}
    for v in sorted({int(v) for v in values}):
        if v == 0:
            continue
        entry = names.get(v)
        if isinstance(entry, LabelInfo):  # its colour stays; material and opacity by name
            styled = style_label(dataclasses.replace(entry, value=v, color_given=True))
            out[v] = dataclasses.replace(styled, color_given=entry.color_given)
            continue
        name = str(entry) if entry is not None and str(entry).strip() else f"label_{v}"
        out[v] = style_label(LabelInfo(v, name, distinct_color(v)))
    return out


def rgba(color) -> Tuple[float, float, float, float]:
    """``Mesh.color`` (RGB or RGBA, 0..1) as four floats clipped to 0..1 (alpha 1 if missing)."""
    c = [float(x) for x in tuple(color)[:4]]
    if len(c) < 3 or not all(np.isfinite(c)):
        c = [0.8, 0.8, 0.8]
    if len(c) == 3:
        c.append(1.0)
    return tuple(min(1.0, max(0.0, x)) for x in c)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded 0..1 values to linear light (IEC 61966-2-1)."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear light 0..1 to sRGB encoding (inverse of :func:`srgb_to_linear`)."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.maximum(c, 0) ** (1 / 2.4) - 0.055)


def select_labels(volume, wanted: Union[str, Sequence[Union[int, str]]]) -> Optional[List[int]]:
    """Label values for ``wanted`` ("all", values, or names matched case-insensitively) in a
    volume's label table (``volume.labels``; a :class:`~anatomesh.core.model.volume.Volume`)."""
    if wanted in (None, "all", ["all"]):
        return None
    table = volume.labels or {}
    by_name = {info.name.lower(): v for v, info in table.items()}
    values = []
    for w in wanted:
        if isinstance(w, (int, np.integer)) or str(w).strip().isdigit():
            values.append(int(w))
            continue
        key = str(w).strip().lower()
        if key not in by_name:
            close = difflib.get_close_matches(key, list(by_name), n=5, cutoff=0.6)
            close += [n for n in by_name if key in n and n not in close][:5]
            hint = f"; did you mean {', '.join(close)}?" if close else \
                "; run `anatomesh inspect` to list the labels"
            raise AnatomeshError(f"no label named {w!r}{hint}", volume.meta.get("source"))
        values.append(by_name[key])
    return values


def style_label(info: LabelInfo, style: Optional[StyleTable] = None) -> LabelInfo:
    """``info`` styled by name: material and opacity from ``style`` (default table when None);
    the colour too, unless the user gave it (``info.color_given``). Names only the fallback
    knows keep their colour (unless the user's file sets a fallback colour); bones are shaded a
    little per value, so neighbouring vertebrae differ."""
    style = style or default_style()
    st = style.style_of(info.name)
    if info.color_given:
        color = tuple(float(c) for c in tuple(info.color)[:3])
    elif st.source == "fallback" and not st.user:
        color = tuple(float(c) for c in tuple(info.color)[:3])
    elif st.material == "bone" and not st.user:
        color = shade(st.color, info.value)
    else:
        color = st.color
    return dataclasses.replace(info, color=tuple(color), material=st.material, opacity=st.opacity)


def style_table(table: Mapping[int, LabelInfo], style: Optional[StyleTable] = None) -> Dict[int, LabelInfo]:
    """Every entry of a label table styled (:func:`style_label`)."""
    return {v: style_label(info, style) for v, info in table.items()}


def fixed_colors(table: Mapping[int, LabelInfo], style: Optional[StyleTable] = None) -> List[int]:
    """Values whose colour the user chose (a colour table, or a colour in the user's style file):
    contrast leaves them alone."""
    style = style or default_style()
    return [v for v, info in table.items() if info.color_given or style.style_of(info.name).user]
