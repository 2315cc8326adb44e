"""Label tables: what each label value is called and its colour, and colours in general.

* :class:`LabelInfo` — one entry (value, name, colour r, g, b in [0, 1], sRGB);
* the anatomical palette: structures coloured by keywords in their names
  (:func:`anatomical_color`), others by distinct hues spaced by the golden ratio
  (:func:`distinct_color`); :func:`label_table_for` builds a table for the values of a map;
* :func:`select_labels` resolves a user's choice ("all", values, names) against a volume's table;
* sRGB ↔ linear conversions (IEC 61966-2-1) for writers and renderers that want linear colour.

Reading table files is :mod:`anatomesh.core.io.label_tables`' job.
"""
from __future__ import annotations

import colorsys
import difflib
import re
from dataclasses import dataclass
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import AnatomeshError


#: the anatomical palette (see :func:`anatomical_color`)


@dataclass
class LabelInfo:
    """One entry of a label table: integer value, display name, colour (r, g, b) in [0, 1]."""

    value: int
    name: str
    color: Tuple[float, float, float] = (0.8, 0.8, 0.8)


_GOLDEN = 0.618033988749895
_IVORY = (0.93, 0.89, 0.78)
# (keywords, rgb in [0, 1]); the first rule with a keyword matching the name wins, so specific
# rules (pulmonary vessels, cysts, tumours, discs) come before broad ones (vein, kidney, bone).
# Pulmonary arteries are blue and pulmonary veins red, as in anatomical illustration
# (oxygen-poor / oxygen-rich blood); every other artery is red and every other vein blue.
_PALETTE: Tuple[Tuple[Tuple[str, ...], Tuple[float, float, float]], ...] = (
    (("tumour", "tumor", "lesion", "cancer", "carcinoma", "metastasis", "metastases",
      "neoplasm", "nodule"), (0.15, 0.9, 0.2)),
    (("cyst",), (0.85, 0.88, 0.55)),
    (("intervertebral", "disc", "discs", "cartilage", "cartilages", "meniscus"), (0.72, 0.84, 0.9)),
    (("pulmonary artery", "pulmonary trunk"), (0.3, 0.4, 0.85)),
    (("pulmonary vein",), (0.85, 0.15, 0.15)),
    (("vein", "veins", "vena", "venous", "portal"), (0.2, 0.3, 0.8)),
    (("artery", "arteries", "arterial", "aorta", "aortic", "carotid", "trunk", "lumen"),
     (0.85, 0.1, 0.1)),
    (("heart", "myocardium", "cardiac", "atrium", "atrial", "ventricle", "appendage"),
     (0.65, 0.22, 0.18)),
    (("spinal cord", "nerve", "nerves", "plexus"), (0.95, 0.85, 0.4)),
    (("bone", "bones", "vertebra", "vertebrae", "rib", "ribs", "skull", "cranium", "mandible",
      "maxilla", "femur", "hip", "pelvis", "sacrum", "coccyx", "sternum", "clavicula",
      "clavicle", "scapula", "humerus", "radius", "ulna", "tibia", "fibula", "patella",
      "skeleton", "spine"), _IVORY),
    (("liver", "hepatic"), (0.55, 0.27, 0.17)),
    (("spleen", "splenic"), (0.5, 0.13, 0.3)),
    (("kidney", "kidneys", "renal"), (0.72, 0.33, 0.27)),
    (("lung", "lungs", "pulmonary"), (0.96, 0.66, 0.7)),
    (("brain", "cerebrum", "cerebellum", "cortex", "brainstem", "thalamus"), (0.86, 0.74, 0.74)),
    (("muscle", "muscles", "gluteus", "iliopsoas", "psoas", "autochthon", "erector",
      "diaphragm", "quadriceps", "sartorius"), (0.75, 0.22, 0.22)),
    (("stomach", "colon", "bowel", "duodenum", "esophagus", "oesophagus", "intestine",
      "rectum", "ileum", "jejunum", "cecum", "caecum", "appendix", "gut"), (0.92, 0.72, 0.6)),
    (("pancreas", "pancreatic"), (0.95, 0.8, 0.42)),
    (("gallbladder", "gall", "bile", "biliary"), (0.3, 0.6, 0.22)),
    (("urinary bladder", "bladder", "urinary", "ureter"), (0.95, 0.88, 0.3)),
    (("adrenal",), (0.95, 0.55, 0.12)),
    (("thyroid", "parathyroid"), (0.78, 0.3, 0.38)),
    (("trachea", "bronchus", "bronchi", "airway", "airways", "larynx"), (0.7, 0.8, 0.86)),
    (("fat", "adipose"), (1.0, 0.88, 0.45)),
    (("skin", "body"), (0.94, 0.76, 0.64)),
    (("prostate", "uterus", "ovary", "testis"), (0.86, 0.58, 0.55)),
    (("eye", "eyeball", "lens"), (0.9, 0.92, 0.95)),
)


def name_tokens(name: str) -> List[str]:
    """Lower-case words of a name: 'kidney_cyst_left' → ['kidney', 'cyst', 'left']."""
    spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", str(name))  # LeftKidney → Left Kidney
    return [t for t in re.split(r"[^a-z0-9]+", spaced.lower()) if t]


def _matches(keyword: str, tokens: Sequence[str], joined: str) -> bool:
    words = keyword.split()
    if len(words) > 1:  # a phrase: consecutive tokens
        n = len(words)
        return any(list(tokens[i:i + n]) == words for i in range(len(tokens) - n + 1))
    if keyword in tokens:
        return True
    if len(keyword) >= 5:  # long keywords also match inside glued words ("leftkidney")
        return keyword in joined
    return False


def anatomical_color(name: str) -> Optional[Tuple[float, float, float]]:
    """The conventional colour (r, g, b in [0, 1]) of a structure, chosen from keywords in its name.

    Bones ivory, arteries red, veins blue (pulmonary vessels the other way round, as in
    anatomical illustration), liver brown, spleen dark purple-red, kidneys reddish brown, lungs
    pink, heart red-brown, brain pinkish grey, muscles red, gut beige, pancreas yellowish,
    gallbladder green, urinary bladder yellow, adrenals orange, trachea light blue-grey, fat
    yellow, skin/body skin tone, tumours/lesions bright green, cysts pale yellow-green.

    Returns None when no keyword matches (the caller picks a distinct colour).

    >>> anatomical_color("vertebrae_L3") == anatomical_color("rib_left_1")
    True
    """
    tokens = name_tokens(name)
    joined = "".join(tokens)
    for keywords, rgb in _PALETTE:
        if any(_matches(k, tokens, joined) for k in keywords):
            return rgb
    return None


# --- body systems (web page tree): the system of each palette rule, by its first keyword
#: the systems in the order a structure tree lists them
SYSTEMS = ("organs", "vessels", "heart", "bones", "muscles", "nerves", "airways", "lesions", "other")
_SYSTEM_OF_RULE = {
    "tumour": "lesions", "cyst": "lesions", "intervertebral": "bones", "pulmonary artery": "vessels",
    "pulmonary vein": "vessels", "vein": "vessels", "artery": "vessels", "heart": "heart",
    "spinal cord": "nerves", "bone": "bones", "liver": "organs", "spleen": "organs",
    "kidney": "organs", "lung": "organs", "brain": "nerves", "muscle": "muscles", "stomach": "organs",
    "pancreas": "organs", "gallbladder": "organs", "urinary bladder": "organs", "adrenal": "organs",
    "thyroid": "organs", "trachea": "airways", "fat": "other", "skin": "other", "prostate": "organs",
    "eye": "organs",
}


def structure_system(name: str) -> str:
    """The body system of a structure, one of :data:`SYSTEMS`, from the same keyword rules as
    :func:`anatomical_color` (the first matching rule decides): ``"kidney_cyst_left"`` →
    ``"lesions"``, ``"vertebrae_L3"`` → ``"bones"``, ``"portal_vein_and_splenic_vein"`` →
    ``"vessels"``; names no rule knows → ``"other"``."""
    tokens = name_tokens(name)
    joined = "".join(tokens)
    for keywords, _ in _PALETTE:
        if any(_matches(k, tokens, joined) for k in keywords):
            return _SYSTEM_OF_RULE.get(keywords[0], "other")
    return "other"


def distinct_color(value: int) -> Tuple[float, float, float]:
    """A saturated colour for ``value``: hues spaced by the golden ratio, so consecutive values differ."""
    hue = (int(value) * _GOLDEN) % 1.0
    return tuple(float(c) for c in colorsys.hsv_to_rgb(hue, 0.6, 0.9))


def _shade(rgb, value: int) -> Tuple[float, float, float]:
    """Scale brightness by 0.88-1.12, fixed per value: neighbours of one class (vertebrae, ribs) differ a little."""
    f = 0.88 + 0.24 * ((int(value) * _GOLDEN) % 1.0)
    return tuple(float(min(1.0, max(0.0, c * f))) for c in rgb)


def label_table_for(values: Iterable[int],
                    names: Optional[Mapping[int, Union[str, LabelInfo]]] = None) -> Dict[int, LabelInfo]:
    """A label table for the non-zero ``values``: names from ``names``, colours from the palette.

    Parameters
    ----------
    values : iterable of int
        Label values present in a map; 0 (background) is skipped.
    names : mapping int → str or LabelInfo, optional
        Known names. A :class:`LabelInfo` keeps its own colour (e.g. from a colour table);
        a plain name gets :func:`anatomical_color` (shaded a little per value) or, when no
        keyword matches, :func:`distinct_color`. Values without a name are ``label_<value>``.

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
        if isinstance(entry, LabelInfo):
            out[v] = LabelInfo(v, entry.name, tuple(float(c) for c in entry.color))
            continue
        name = str(entry) if entry is not None and str(entry).strip() else f"label_{v}"
        base = anatomical_color(name) if entry is not None else None
        out[v] = LabelInfo(v, name, _shade(base, v) if base is not None else distinct_color(v))
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
