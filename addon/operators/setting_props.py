"""Recipe settings as Blender properties, made from their one definition
(:func:`anatomesh.app.flow.settings.setting`): name, description (help and unit), default, range
(``min``/``max``), length unit and choices all come from the field. Every setting the hand-made
panels do not hold (:data:`anatomesh.addon.operators.recipe.PANEL_FIELDS`) gets one in the
generated property group ``Scene.anatomesh_recipe`` (:func:`settings_group`), shown in the
Settings panel section by section and copied into every recipe the add-on runs or saves
(:func:`group_to_recipe`, :func:`recipe_to_group`), so a new setting reaches Blender without
touching the add-on.

A setting that may be left unset (default None) is unset at the value just outside its range
(``0`` for a distance that must be > 0, ``3`` for a count >= 4) or, without a range, at an empty
text. A list setting is a text holding its recipe-file value (``[2.0, 5.0, 10.0]``).
"""
from __future__ import annotations

import dataclasses
import tomllib
from typing import Dict, Iterable, List

from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import PropertyGroup

from ...app.flow.settings import KINDS, default_of, field_help, option_name, toml_value
from ...core.model.errors import AnatomeshError

#: kinds shown as numbers, and the kinds shown as a text
_NUMBERS = {"int": IntProperty, "float": FloatProperty}


def _unset(f: dataclasses.Field):
    """The property value meaning "not set" of an optional number, or None (a text then)."""
    low, _, low_open = f.metadata["range"]
    if f.default is not None or f.metadata["kind"] not in _NUMBERS or low is None:
        return None
    if f.metadata["kind"] == "int":
        return low if low_open else low - 1
    return float(low) if low_open else None


def setting_property(f: dataclasses.Field):
    """The Blender property of one recipe setting (see the module docstring)."""
    m, kind = f.metadata, f.metadata["kind"]
    name = f.name.replace("_", " ").capitalize()
    default = default_of(f)
    if kind == "bool":
        return BoolProperty(name=name, default=bool(default), description=field_help(f))
    if m["choices"]:
        items = [(c.upper(), c, "") for c in m["choices"]]
        return EnumProperty(name=name, items=items, default=str(default).upper(), description=field_help(f))
    unset = _unset(f)
    if kind in _NUMBERS and (default is not None or unset is not None):
        low, high, _ = m["range"]
        kw = {"min": unset if unset is not None else low, "max": high}
        kw = {k: v for k, v in kw.items() if v is not None}
        if kind == "float" and m["unit"] == "mm":
            kw["unit"] = "LENGTH"
        note = f"{unset:g}: not set" if unset is not None else ""
        return _NUMBERS[kind](name=name, default=default if default is not None else unset,
                              description=field_help(f, note), **kw)
    text = "" if default in (None, "") else (toml_value(default) if isinstance(default, list) else str(default))
    subtype = "FILE_PATH" if kind == "path" else "NONE"
    return StringProperty(name=name, default=text, subtype=subtype,
                          description=field_help(f, "empty: not set" if default is None else ""))


def group_fields(recipe_type, exclude: Iterable[str]) -> List[dataclasses.Field]:
    """The settings of ``recipe_type`` a generated group holds: all but ``exclude``."""
    skip = set(exclude)
    return [f for f in dataclasses.fields(recipe_type) if f.name not in skip]


def settings_group(recipe_type, exclude: Iterable[str], name: str = "ANATOMESH_PG_recipe") -> type:
    """A PropertyGroup class with one property per setting of :func:`group_fields`."""
    fields = group_fields(recipe_type, exclude)
    return type(name, (PropertyGroup,), {
        "__annotations__": {f.name: setting_property(f) for f in fields},
        "__doc__": "Recipe settings made from their definitions (the Settings panel)",
        "fields": tuple(f.name for f in fields)})


def by_section(recipe_type, names: Iterable[str]) -> Dict[str, List[str]]:
    """``names`` grouped by their recipe-file section, in the recipe's section order."""
    fields = {f.name: f for f in dataclasses.fields(recipe_type)}
    out: Dict[str, List[str]] = {}
    for section in recipe_type.NOTES:
        inside = [n for n in names if fields[n].metadata["section"] == section]
        if inside:
            out[section] = inside
    return out


def recipe_value(f: dataclasses.Field, value):
    """A property's value as the recipe's (None where not set); a list text is read as a recipe
    file's value and checked as one (one-line error naming the setting)."""
    kind = f.metadata["kind"]
    if f.metadata["choices"]:
        return str(value).lower()
    if kind in _NUMBERS and not isinstance(value, str):
        unset = _unset(f)
        if unset is not None and value == unset:
            return None
        return int(value) if kind == "int" else float(value)
    if isinstance(value, str) and not value.strip():
        return default_of(f)  # an empty text: the setting's default (None for an optional one)
    if kind in ("bool", "str", "path", "series"):
        return value
    try:
        parsed = tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        parsed = value  # a bare name (a label)
    ok, _, convert = KINDS[kind]
    if not ok(parsed):
        raise AnatomeshError(f"{option_name(f)} must be {f.metadata['allowed']}, got {value!r}")
    return parsed if convert is None else convert(parsed)


def blender_value(f: dataclasses.Field, value):
    """A recipe's value as the property's (the inverse of :func:`recipe_value`)."""
    kind = f.metadata["kind"]
    if f.metadata["choices"]:
        return str(value).upper()
    if kind == "bool":
        return bool(value)
    unset = _unset(f)
    if kind in _NUMBERS and (f.default is not None or unset is not None):
        return unset if value is None else value
    if value is None:
        return ""
    return toml_value(value) if isinstance(value, list) else str(value)


def group_to_recipe(group, recipe) -> None:
    """Copy a generated group's settings into ``recipe`` (in place)."""
    fields = {f.name: f for f in dataclasses.fields(recipe)}
    for name in group.fields:
        setattr(recipe, name, recipe_value(fields[name], getattr(group, name)))


def recipe_to_group(recipe, group) -> None:
    """Put ``recipe``'s settings into a generated group."""
    fields = {f.name: f for f in dataclasses.fields(recipe)}
    for name in group.fields:
        setattr(group, name, blender_value(fields[name], getattr(recipe, name)))
