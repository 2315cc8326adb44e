"""Command-line flags made from the recipe's own field definitions (:func:`anatomesh.app.flow.recipe.setting`):
each flag's name, type, choices, metavar and help (with its unit and default) come from the one
place the setting is defined, so the flags, the recipe files and the documentation cannot drift."""
from __future__ import annotations

import argparse
import dataclasses
from typing import Iterable

from ..flow.recipe import Recipe

#: argparse types of the plain kinds
_TYPES = {"int": int, "float": float, "str": str, "path": str, "series": str, "label": str}


def add_setting_args(parser: argparse.ArgumentParser, names: Iterable[str], recipe_type=Recipe) -> None:
    """Add the flag of each recipe field of ``names`` to ``parser`` (``dest`` the field's name,
    default None: a flag not given leaves the recipe's value). A true/false field is a switch
    (``--no-...`` when its default is true); a list field takes one or more values (``--roi 1 2
    3 4 5 6`` or ``--roi=1,2,3,4,5,6``), kept as their comma text until the recipe's check reads
    them (:func:`flag_values`)."""
    fields = {f.name: f for f in dataclasses.fields(recipe_type)}
    for name in names:
        f = fields[name]
        m = f.metadata
        text = help_text(f)
        if m["kind"] == "bool":
            action = "store_false" if f.default is True else "store_true"
            parser.add_argument(m["flag"], dest=name, action=action, default=None, help=text)
        elif m["kind"] in _TYPES:
            parser.add_argument(m["flag"], dest=name, type=_TYPES[m["kind"]], choices=m["choices"] or None,
                                metavar=m["metavar"] or None, help=text)
        else:
            parser.add_argument(m["flag"], dest=name, nargs="+", metavar=m["metavar"] or None, help=text)


def flag_values(args, names: Iterable[str]) -> dict:
    """The values of the flags of ``names`` given on the command line, by field name (a list
    field's values as one comma text)."""
    out = {}
    for name in names:
        value = getattr(args, name, None)
        if value is not None:
            out[name] = ",".join(value) if isinstance(value, list) else value
    return out


def help_text(f: dataclasses.Field) -> str:
    """A field's help as the command line shows it: what it does, its unit, its default."""
    m = f.metadata
    text = m["help"] + (f" ({m['unit']})" if m["unit"] and m["unit"] not in m["help"] else "")
    default = f.default
    if m["kind"] != "bool" and default not in (None, "", dataclasses.MISSING) and "default" not in m["help"]:
        text += f"; default {default}"
    return text.replace("%", "%%")  # argparse formats help with %
