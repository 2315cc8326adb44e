"""What a setting is, once: a dataclass field made by :func:`setting` carries its default, its
place in a recipe file (``[section] key``), its kind, unit, range, choices, help and command-line
flag. From those definitions come the recipe files (read, checked, written: :func:`from_toml`,
:func:`to_toml`), the range checks (:func:`check_values`), the documentation's table
(:func:`settings_table`), the command line's flags (:mod:`anatomesh.app.cli.settings_args`) and
the Blender add-on's properties. The settings of a run are :class:`~anatomesh.app.flow.recipe.Recipe`.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the same parser, as a package
    import tomli as tomllib
from dataclasses import field
from pathlib import Path
from typing import Dict, List, Optional, Tuple

from ...core.model.errors import AnatomeshError

#: what a setting's value may be in a recipe file: (check, words for the error, conversion)
KINDS = {
    "bool": (lambda v: isinstance(v, bool), "true or false", None),
    "int": (lambda v: _is_int(v), "a whole number", None),
    "float": (lambda v: _is_number(v), "a number", float),
    "str": (lambda v: isinstance(v, str), "a text", None),
    "path": (lambda v: isinstance(v, str), "a path", None),
    "paths": (lambda v: isinstance(v, str) or (isinstance(v, list) and v and all(isinstance(x, str) for x in v)),
              "a path or a list of paths", None),
    "floats": (lambda v: isinstance(v, list) and all(_is_number(x) for x in v), "a list of numbers",
               lambda v: [float(x) for x in v]),
    "strs": (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), "a list of names", None),
    "ints": (lambda v: isinstance(v, list) and all(_is_int(x) for x in v), "a list of whole numbers", None),
    "label": (lambda v: isinstance(v, str) or _is_int(v), "a label name or value", None),
    "labels": (lambda v: v == "all" or (isinstance(v, list) and all(isinstance(x, str) or _is_int(x) for x in v)),
               "\"all\" or a list of label values/names", None),
    "label_groups": (lambda v: isinstance(v, list) and all(isinstance(g, list) and all(
        isinstance(x, str) or _is_int(x) for x in g) for g in v), "a list of label groups", None),
    "label_pairs": (lambda v: isinstance(v, list) and all(isinstance(g, list) and len(g) == 2 and all(
        isinstance(x, str) or _is_int(x) for x in g) for g in v), "a list of label pairs", None),
    "series": (lambda v: isinstance(v, (str, int)) and not isinstance(v, bool), "a series UID or number", str),
    "number_or_floats": (lambda v: _is_number(v) or (isinstance(v, list) and all(_is_number(x) for x in v)),
                         "a number or a list of numbers", None),
}




def setting(default, section: str, key: str, kind: str, help: str, *, unit: str = "",
            allowed: str = "", count: tuple = (), choices: tuple = (), flag: str = "",
            metavar: str = "", low=None, high=None, low_open: bool = False, factory=None):
    """A setting, defined once: its default, where it sits in a recipe file (``[section] key``),
    its kind (:data:`KINDS`; a list kind with ``count``: one of these lengths; a text with
    ``choices``: one of them), what it does (``help``: the command line's, the documentation's
    and the Blender panel's), its ``unit``, its range (``low``..``high``, either may be None;
    ``low_open``: above ``low``, not at it; numbers and each number of a list), its
    command-line ``flag`` (with ``metavar``) and, for the one-line error of a wrong value, what
    is ``allowed`` (default: the choices, or the kind's words with the range)."""
    if choices and not allowed:
        allowed = " or ".join(f'"{c}"' for c in choices)
    meta = {"section": section, "key": key, "kind": kind, "help": help, "unit": unit,
            "allowed": allowed or _range_words(KINDS[kind][1], low, high, low_open), "count": count,
            "choices": tuple(choices), "flag": flag, "metavar": metavar, "range": (low, high, low_open)}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


def _range_words(words: str, low, high, low_open: bool) -> str:
    """``a number in (0, 1]``, ``a whole number in 0..16``, ``a number > 0`` ..."""
    if low is None and high is None:
        return words
    if high is None:
        return f"{words} {'>' if low_open else '>='} {low:g}"
    if low is None:
        return f"{words} <= {high:g}"
    if words.startswith("a whole number") and not low_open:
        return f"{words} in {low}..{high}"
    return f"{words} in {'(' if low_open else '['}{low:g}, {high:g}]"


def check_values(settings) -> None:
    """Raise :class:`AnatomeshError` for the first setting of ``settings`` (a dataclass of
    :func:`setting` fields) outside its range or choices, naming its flag (or ``[section] key``)
    and what is allowed. Settings left at None are not checked."""
    for f in dataclasses.fields(settings):
        low, high, low_open = f.metadata["range"]
        value = getattr(settings, f.name)
        if value is None:
            continue
        if f.metadata["choices"] and value not in f.metadata["choices"]:
            raise AnatomeshError(f"{option_name(f)} must be {f.metadata['allowed']}, got {value!r}")
        if low is None and high is None:
            continue
        whole = f.metadata["kind"] in ("int", "ints")
        for x in value if isinstance(value, (list, tuple)) else [value]:
            if not (_is_int(x) if whole else _is_number(x)) or math.isnan(x) or \
                    (low is not None and (x <= low if low_open else x < low)) or (high is not None and x > high):
                raise AnatomeshError(f"{option_name(f)} must be {f.metadata['allowed']}, got {value!r}")


def read_numbers(text, flag: str, count: Optional[Tuple[int, ...]] = None) -> List[float]:
    """``"1,2,3"`` (or a number, or a list of numbers) → floats; one-line error naming ``flag``."""
    items = text if isinstance(text, (list, tuple)) else str(text).replace(" ", ",").split(",")
    try:
        values = [float(x) for x in items if str(x).strip() != ""]
    except (TypeError, ValueError):
        raise AnatomeshError(f"{flag} takes numbers, got {text!r}") from None
    if any(isinstance(x, bool) for x in items) or not all(math.isfinite(v) for v in values):
        raise AnatomeshError(f"{flag} takes finite numbers, got {text!r}")
    if count is not None and len(values) not in count:
        want = " or ".join(str(c) for c in count)
        raise AnatomeshError(f"{flag} takes {want} numbers, got {len(values)} ({text!r})")
    return values


def read_number_lists(settings) -> None:
    """Number-list settings given as text (a flag's ``1,2,3`` or ``1 2 3``) or a single number,
    as lists of floats, in place (one-line error naming the flag; the count checked)."""
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        if value is not None and f.metadata["kind"] in ("floats", "number_or_floats"):
            setattr(settings, f.name, read_numbers(value, option_name(f), f.metadata["count"] or None))


def option_name(f: dataclasses.Field) -> str:
    """How a user names a setting: its flag, else ``[section] key``."""
    m = f.metadata
    return m["flag"] or f"[{m['section']}] {m['key']}"


def sections(settings_type) -> Dict[str, Dict[str, str]]:
    """Recipe-file section → {key: field name} of a settings type, from its fields' own
    definitions, in the order of the type's ``NOTES`` (section → the comment written above it)."""
    out: Dict[str, Dict[str, str]] = {section: {} for section in settings_type.NOTES}
    for f in dataclasses.fields(settings_type):
        out[f.metadata["section"]][f.metadata["key"]] = f.name
    return out


def default_of(f: dataclasses.Field):
    """A setting's default value (made anew for a list setting)."""
    return f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default


def fields_of(settings_type) -> Dict[str, dataclasses.Field]:
    """The fields of a settings type by name."""
    return {f.name: f for f in dataclasses.fields(settings_type)}


def _path_fields(settings_type) -> tuple:
    """The fields holding paths (resolved against the recipe file's folder)."""
    return tuple(f.name for f in dataclasses.fields(settings_type) if f.metadata["kind"] in ("path", "paths"))


def field_help(f: dataclasses.Field, unset: str = "") -> str:
    """A setting's help as a panel shows it (a Blender property's description): what it does,
    its unit, and what the panel's ``unset`` value means (e.g. "0: the preset's own")."""
    m = f.metadata
    text = m["help"][:1].upper() + m["help"][1:]
    if m["unit"] and m["unit"] not in text:
        text += f", {m['unit']}"
    return text + (f" ({unset})" if unset else "")


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def settings_table(settings_type) -> str:
    """Every setting of a settings type as a Markdown table (section, key, value, default, unit, what it does,
    command-line flag), from the fields' own definitions."""
    rows = ["| section | key | value | default | unit | what it does | flag |", "|---|---|---|---|---|---|---|"]
    fields = fields_of(settings_type)
    for f in (fields[name] for keys in sections(settings_type).values() for name in keys.values()):
        m = f.metadata
        default = default_of(f)
        rows.append(f"| `[{m['section']}]` | `{m['key']}` | {m['allowed']} | "
                    f"{'' if default in (None, '') else '`' + toml_value(default) + '`'} | {m['unit']} | {m['help']} | "
                    f"{'`' + m['flag'] + '`' if m['flag'] else ''} |")
    return "\n".join(rows) + "\n"


# ---------------------------------------------------------------------------------------------
def from_toml(text: str, settings_type, base=None, source=None):
    """TOML text → a ``settings_type``: unknown sections/keys and values of the wrong kind are
    one-line errors naming the key and what is allowed; keys not given keep their defaults;
    relative paths resolve against ``base`` (if given)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise AnatomeshError(f"not valid TOML ({exc}); fix the recipe file", source) from None
    values = {}
    known, fields = sections(settings_type), fields_of(settings_type)
    for section, body in doc.items():
        keys = known.get(section)
        if keys is None:
            raise AnatomeshError(f"unknown recipe section [{section}]; allowed sections: "
                                 f"{', '.join(known)}", source)
        if not isinstance(body, dict):
            raise AnatomeshError(f"{section} must be a [{section}] section with keys "
                                 f"{', '.join(keys)}", source)
        for key, value in body.items():
            name = keys.get(key)
            if name is None:
                raise AnatomeshError(f"unknown key {key!r} in [{section}]; allowed keys: "
                                     f"{', '.join(keys)}", source)
            meta = fields[name].metadata
            ok, _, convert = KINDS[meta["kind"]]
            if not ok(value) or (meta["count"] and isinstance(value, list) and len(value) not in meta["count"]):
                raise AnatomeshError(f"[{section}] {key} must be {meta['allowed']}, got {value!r}", source)
            values[name] = value if convert is None else convert(value)
    if base is not None:
        for name in _path_fields(settings_type):
            if values.get(name):
                values[name] = _resolve(values[name], Path(base))
    return settings_type(**values)


def _resolve(value, base: Path):
    if isinstance(value, list):
        return [_resolve(v, base) for v in value]
    p = Path(os.path.expanduser(value))
    return str(p if p.is_absolute() else Path(os.path.abspath(base / p)))


# ---------------------------------------------------------------------------------------------
def to_toml(settings, base=None, header=()) -> str:
    """The settings as TOML text, ``header`` lines first (sections as in :func:`sections`, each
    with its note; settings that are None left out). With ``base`` (the folder the file will be
    written to), paths are written relative to it, so a folder holding the file and its scan
    can be moved as a whole; :func:`from_toml` with that ``base`` gives back equal settings."""
    values = dataclasses.asdict(settings)
    if base is not None:
        for name in _path_fields(type(settings)):
            if values.get(name):
                values[name] = _relative(values[name], Path(base))
    lines = list(header)
    for section, keys in sections(type(settings)).items():
        body = [f"{key} = {toml_value(values[name])}" for key, name in keys.items()
                if values[name] is not None]
        if body:
            lines += ["", f"# {type(settings).NOTES[section]}", f"[{section}]"] + body
    return "\n".join(lines) + "\n"


def _relative(value, base: Path):
    if isinstance(value, list):
        return [_relative(v, base) for v in value]
    p = os.path.abspath(os.path.expanduser(str(value)))
    b = os.path.abspath(base)
    try:
        common = os.path.commonpath([p, b])
    except ValueError:  # another drive (Windows)
        return p
    if os.path.dirname(common) == common:  # only the filesystem root in common: keep it absolute
        return p
    return Path(os.path.relpath(p, b)).as_posix()


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # JSON's string escapes are TOML basic strings'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise AnatomeshError(f"cannot write {type(v).__name__} value {v!r} into a recipe")


