"""The preprocessing settings of a recipe, checked beyond their definitions (the ``[preprocess]``
fields of :class:`~anatomesh.app.flow.recipe.Recipe`, listed in docs/SETTINGS.md): the volume
filter's spec, the box of ``roi``, the fuzzy shells; one-line errors naming the flag.
This module imports only :mod:`.settings` from ``app`` (the recipe imports it)."""
from __future__ import annotations

from typing import List, Tuple

from ...core.model.errors import AnatomeshError
from .settings import read_numbers

RESAMPLE_METHODS = ("linear", "cubic", "lanczos")
SMOOTH_FILTERS = ("gaussian", "median", "diffusion")


def parse_smooth_volume(spec) -> Tuple[str, List[float]]:
    """``"gaussian:1.5"`` → ``("gaussian", [1.5])``; ``gaussian:1,1,3`` gives one value per axis
    (mm); ``median:SIZE_MM`` likewise; ``diffusion:ITERATIONS`` a whole number."""
    text = str(spec).strip().lower()
    name, _, arg = text.partition(":")
    if name not in SMOOTH_FILTERS or not arg:
        raise AnatomeshError(f"--smooth-volume must be gaussian:SIGMA_MM, median:SIZE_MM or "
                             f"diffusion:ITERATIONS, got {spec!r}")
    if name == "diffusion":
        try:
            n = int(arg)
        except ValueError:
            n = -1
        if not 1 <= n <= 10000:
            raise AnatomeshError(f"--smooth-volume diffusion:ITERATIONS needs a whole number in "
                                 f"1..10000, got {arg!r}")
        return name, [float(n)]
    values = read_numbers(arg, f"--smooth-volume {name}", (1, 3))
    if any(v <= 0 for v in values):
        raise AnatomeshError(f"--smooth-volume {name} needs sizes in mm > 0, got {arg!r}")
    return name, values


def check_preprocess(recipe) -> None:
    """Normalise and check the preprocessing fields of ``recipe`` in place (method names lower
    case) beyond what their definitions check (:func:`~anatomesh.app.flow.settings.check_values`:
    ranges, choices); raise :class:`AnatomeshError` naming the flag."""
    recipe.resample_method = str(recipe.resample_method).lower()
    if recipe.roi is not None:
        if any(a == b for a, b in zip(recipe.roi[:3], recipe.roi[3:])):
            raise AnatomeshError(f"--roi is a box x0,y0,z0,x1,y1,z1 in mm with x0 != x1 etc., got {recipe.roi}")
    if recipe.smooth_volume is not None:
        parse_smooth_volume(recipe.smooth_volume)
    if recipe.fuzzy is not None:
        lo, hi = recipe.fuzzy[:2]
        n = recipe.fuzzy[2] if len(recipe.fuzzy) == 3 else 5
        if lo == hi or n != int(n) or not 2 <= n <= 32:
            raise AnatomeshError(f"--fuzzy needs I1 != I2 and N a whole number in 2..32, got {recipe.fuzzy}")
    if recipe.fuzzy is not None and recipe.levels:
        raise AnatomeshError("give --fuzzy I1 I2 [N] or --level, not both (--fuzzy makes its own levels)")


def active(recipe) -> bool:
    """Whether the recipe asks for any preprocessing."""
    return any(v not in (None, False) for v in (
        recipe.resample, recipe.roi, recipe.smooth_volume, recipe.interpolate, recipe.fuzzy_boundary,
        recipe.fill_cavities, recipe.close_handles, recipe.fuzzy, recipe.precise))
