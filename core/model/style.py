"""The style table: each structure's base colour, material class and default opacity, as data.

A style table maps structure names to a :class:`Style`. The default table ships as data
(``styles/default.toml``, beside this module; its header cites the colour convention it follows);
a user's TOML file (``--style FILE``) may be partial: it overrides or extends the default entry by
entry and field by field. Every door (GLB, PLY, 3MF, the web page, Blender) takes its colours and
transparency from the label table built with it.

Looking a name up (:meth:`StyleTable.style_of`), first match wins:

1. an exact structure entry (TotalSegmentator names; the comparison ignores case, word order
   and separators, so ``"kidney_left"``, ``"Left Kidney"`` and ``"LeftKidney"`` are one name);
2. a synonym (DICOM SEG / RTSTRUCT names with SNOMED CT meanings, Slicer's generic anatomy
   names, TotalSegmentator's MR names) pointing to a structure entry;
3. keyword rules (``"vertebra"`` anywhere in the name → bone), in file order;
4. the fallback entry.

File format (TOML; colours ``"#rrggbb"`` or ``[r, g, b]`` in 0..1, or 0..255 integers)::

    [fallback]
    color = "#cccccc"
    material = "other"
    opacity = 1.0

    [structures]
    liver = { color = "#b35a2e", material = "parenchyma" }
    lung_upper_lobe_left = { opacity = 0.3 }        # a user file may give one field only

    [synonyms]
    "left kidney" = "kidney_left"

    [[rules]]
    keywords = ["vertebra", "rib"]
    color = "#f0e6c8"
    material = "bone"
"""
from __future__ import annotations

import re
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the same parser, as a package
    import tomli as tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

from .errors import AnatomeshError

#: tissue classes a structure is drawn as (one shader/material preset per class)
MATERIALS = ("parenchyma", "hollow", "artery", "vein", "bone", "cartilage", "muscle", "fat",
             "nerve", "lesion", "airway", "skin", "other")

#: the default style table, shipped as data
DEFAULT_STYLE_FILE = Path(__file__).with_name("styles") / "default.toml"

_STOP_WORDS = {"of", "the", "structure", "entire"}
# words written several ways: TG-263 sides (Lung_L), singular and plural
_WORD_ALIASES = {"l": "left", "r": "right", "lt": "left", "rt": "right", "vertebra": "vertebrae",
                 "lungs": "lung", "kidneys": "kidney"}


@dataclass(frozen=True)
class Style:
    """How one structure is drawn.

    color : (r, g, b) sRGB in [0, 1]; material : one of :data:`MATERIALS`;
    opacity : 0..1 (1 opaque; lungs are see-through by default);
    source : where the entry came from: ``"structure"``, ``"synonym"``, ``"rule"`` or
    ``"fallback"``; ``user`` : True when a user's style file set this entry's colour.
    """

    color: Tuple[float, float, float]
    material: str = "other"
    opacity: float = 1.0
    source: str = "structure"
    user: bool = False


def name_key(name: str) -> str:
    """The lookup key of a name: lower-case words, sorted, without separators and filler words
    ("Left Kidney", "kidney_left" and "LeftKidney" → ``"kidney left"``)."""
    spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", str(name))
    words = [_WORD_ALIASES.get(t, t) for t in re.split(r"[^a-z0-9]+", spaced.lower())
             if t and t not in _STOP_WORDS]
    return " ".join(sorted(words))


class StyleTable:
    """Structure styles (see module docstring). Build with :func:`load_style`."""

    def __init__(self, structures: Mapping[str, Style], synonyms: Mapping[str, str],
                 rules: Sequence[Tuple[Tuple[str, ...], Style]], fallback: Style,
                 sources: Sequence[str] = ()):
        self.structures: Dict[str, Style] = {name_key(k): v for k, v in structures.items()}
        self.names: Dict[str, str] = {name_key(k): k for k in structures}
        self.synonyms: Dict[str, str] = {name_key(k): name_key(v) for k, v in synonyms.items()}
        self.rules = list(rules)
        self.fallback = fallback
        self.sources = list(sources)

    def style_of(self, name: str) -> Style:
        """The :class:`Style` of a structure name (exact, synonym, keyword rule, fallback)."""
        key = name_key(name)
        if key in self.structures:
            return self.structures[key]
        if key in self.synonyms and self.synonyms[key] in self.structures:
            return replace(self.structures[self.synonyms[key]], source="synonym")
        tokens = key.split()
        joined = re.sub(r"[^a-z0-9]+", "", str(name).lower())
        for keywords, style in self.rules:
            if any(_keyword_matches(k, tokens, joined) for k in keywords):
                return style
        return self.fallback

    def __repr__(self) -> str:
        return (f"StyleTable({len(self.structures)} structures, {len(self.synonyms)} synonyms, "
                f"{len(self.rules)} rules; from {', '.join(self.sources) or 'code'})")


def _keyword_matches(keyword: str, tokens: Sequence[str], joined: str) -> bool:
    """A one-word keyword matches a word of the name (or, 5+ letters, inside glued words like
    "leftkidney"); a phrase matches when all its words are in the name."""
    words = keyword.lower().split()
    if len(words) > 1:
        return all(w in tokens for w in words)
    return keyword in tokens or (len(keyword) >= 5 and keyword in joined)


def load_style(path=None) -> StyleTable:
    """The style table: the default (``path=None``), or the default overridden and extended by
    the user's TOML file ``path`` (entries merge field by field; user rules come first).

    Raises
    ------
    AnatomeshError
        One line naming the file when it cannot be read, is not TOML or has a bad entry.
    """
    default = _read_toml(DEFAULT_STYLE_FILE)
    table = _build(default, {}, DEFAULT_STYLE_FILE)
    if path is None:
        return table
    path = Path(path)
    user = _read_toml(path)
    return _build(default, user, path)


def _read_toml(path: Path) -> Dict:
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise AnatomeshError("style file not found; give a TOML style table (see docs/STYLES.md)",
                             path) from None
    except (OSError, UnicodeDecodeError) as err:
        raise AnatomeshError(f"cannot read the style file ({err.__class__.__name__})", path) from None
    except tomllib.TOMLDecodeError as err:
        raise AnatomeshError(f"not a valid TOML style table: {err}", path) from None


def _build(default: Dict, user: Dict, path: Path) -> StyleTable:
    unknown = set(user) - {"fallback", "structures", "synonyms", "rules"}
    if unknown:
        raise AnatomeshError(f"unknown section {sorted(unknown)[0]!r} in the style file; expected "
                             "[fallback], [structures], [synonyms] or [[rules]]", path)
    fallback = _style({**default.get("fallback", {}), **_section(user, "fallback", dict, path)},
                      "fallback", "fallback", path, user=bool(user.get("fallback", {}).get("color")))
    entries = {name_key(k): [k, dict(v), False] for k, v in default.get("structures", {}).items()}
    for name, fields in _section(user, "structures", dict, path).items():
        if not isinstance(fields, dict):
            raise AnatomeshError(f"structure {name!r} must be a table like "
                                 "{ color = \"#rrggbb\", opacity = 0.5 }", path)
        entry = entries.setdefault(name_key(name), [name, {}, False])
        entry[1].update(fields)
        entry[2] = entry[2] or "color" in fields
    structures = {name: _style(fields, f"structure {name!r}", "structure", path, user=mine)
                  for name, fields, mine in entries.values()}
    synonyms = {**default.get("synonyms", {}), **_section(user, "synonyms", dict, path)}
    rules = [_rule(r, path, True) for r in _section(user, "rules", list, path)]
    rules += [_rule(r, DEFAULT_STYLE_FILE, False) for r in default.get("rules", [])]
    sources = [str(DEFAULT_STYLE_FILE.name)] + ([str(path)] if user else [])
    return StyleTable(structures, synonyms, rules, fallback, sources)


def _section(doc: Dict, key: str, kind, path: Path):
    value = doc.get(key, kind())
    if not isinstance(value, kind):
        raise AnatomeshError(f"[{key}] must be a {'table' if kind is dict else 'list of tables'}",
                             path)
    return value


def _rule(fields, path: Path, user: bool) -> Tuple[Tuple[str, ...], Style]:
    if not isinstance(fields, dict) or not isinstance(fields.get("keywords"), list) or \
            not fields["keywords"]:
        raise AnatomeshError("each [[rules]] entry needs keywords = [\"word\", ...] and a color",
                             path)
    words = tuple(str(k).lower() for k in fields["keywords"])
    body = {k: v for k, v in fields.items() if k != "keywords"}
    return words, _style(body, f"rule {words[0]!r}", "rule", path, user=user and "color" in body)


def _style(fields: Dict, what: str, source: str, path: Path, user: bool = False) -> Style:
    extra = set(fields) - {"color", "material", "opacity"}
    if extra:
        raise AnatomeshError(f"{what}: unknown field {sorted(extra)[0]!r}; expected color, "
                             "material, opacity", path)
    if "color" not in fields:
        raise AnatomeshError(f"{what} has no color and is not in the default table", path)
    material = str(fields.get("material", "other"))
    if material not in MATERIALS:
        raise AnatomeshError(f"{what}: material {material!r} is not one of {', '.join(MATERIALS)}",
                             path)
    try:
        opacity = float(fields.get("opacity", 1.0))
    except (TypeError, ValueError):
        opacity = -1.0
    if not 0.0 <= opacity <= 1.0:
        raise AnatomeshError(f"{what}: opacity must be a number from 0 to 1", path)
    return Style(parse_color(fields["color"], what, path), material, opacity, source, user)


def parse_color(value, what: str = "color", path=None) -> Tuple[float, float, float]:
    """``"#rrggbb"``, ``[r, g, b]`` in 0..1, or ``[r, g, b]`` integers 0..255 → (r, g, b) in 0..1."""
    if isinstance(value, str) and re.fullmatch(r"#?[0-9a-fA-F]{6}", value.strip()):
        h = value.strip().lstrip("#")
        return tuple(int(h[i:i + 2], 16) / 255.0 for i in (0, 2, 4))
    if isinstance(value, list) and len(value) == 3 and \
            all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in value):
        scale = 255.0 if any(c > 1 for c in value) or all(isinstance(c, int) and c > 1 for c in value) else 1.0
        rgb = tuple(float(c) / scale for c in value)
        if all(0.0 <= c <= 1.0 for c in rgb):
            return rgb
    raise AnatomeshError(f"{what}: color {value!r} must be \"#rrggbb\" or [r, g, b] (0..1 or "
                         "0..255)", path)


_DEFAULT: Optional[StyleTable] = None


def default_style() -> StyleTable:
    """The default style table, read once."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = load_style(None)
    return _DEFAULT


_GOLDEN = 0.618033988749895


def shade(rgb, value: int) -> Tuple[float, float, float]:
    """Scale brightness by 0.88-1.12, fixed per value: neighbours of one class (vertebrae, ribs) differ a little."""
    f = 0.88 + 0.24 * ((int(value) * _GOLDEN) % 1.0)
    return tuple(float(min(1.0, max(0.0, c * f))) for c in rgb)
