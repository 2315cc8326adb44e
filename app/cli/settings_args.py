"""Command-line flags made from the recipe's own field definitions (:func:`anatomesh.app.recipe.setting`):
each flag's name, type, choices, metavar and help (with its unit and default) come from the one
place the setting is defined, so the flags, the recipe files and the documentation cannot drift."""
from __future__ import annotations

import argparse
import dataclasses
from typing import Iterable

from ..recipe import Recipe

#: argparse types of the plain kinds
_TYPES = {"int": int, "float": float, "str": str, "path": str, "series": str}


def add_setting_args(parser: argparse.ArgumentParser, names: Iterable[str], recipe_type=Recipe) -> None:
    """Add the flag of each recipe field of ``names`` to ``parser`` (``dest`` the field's name,
    default None: a flag not given leaves the recipe's value). A true/false field is a switch
    (``--no-...`` when its default is true)."""
    fields = {f.name: f for f in dataclasses.fields(recipe_type)}
    for name in names:
        f = fields[name]
        m = f.metadata
        text = help_text(f)
        if m["kind"] == "bool":
            action = "store_false" if f.default is True else "store_true"
            parser.add_argument(m["flag"], dest=name, action=action, default=None, help=text)
        else:
            parser.add_argument(m["flag"], dest=name, type=_TYPES[m["kind"]], choices=m["choices"] or None,
                                metavar=m["metavar"] or None, help=text)


def help_text(f: dataclasses.Field) -> str:
    """A field's help as the command line shows it: what it does, its unit, its default."""
    m = f.metadata
    text = m["help"] + (f" ({m['unit']})" if m["unit"] and m["unit"] not in m["help"] else "")
    default = f.default
    if m["kind"] != "bool" and default not in (None, "", dataclasses.MISSING) and "default" not in m["help"]:
        text += f"; default {default}"
    return text.replace("%", "%%")  # argparse formats help with %


def setting_flags(recipe_type=Recipe) -> tuple:
    """The recipe fields that have a flag of their own."""
    return tuple(f.name for f in dataclasses.fields(recipe_type) if f.metadata["flag"])
