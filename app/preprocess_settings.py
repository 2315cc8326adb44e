"""The preprocessing settings of a recipe, parsed and checked (one-line errors naming the flag).

``anatomesh mesh`` flags, the ``[preprocess]`` TOML keys and the Blender panel fill the same
:class:`~anatomesh.app.recipe.Recipe` fields:

====================  ======================  =================================================
flag                  recipe key              value
====================  ======================  =================================================
--resample            resample                mm: one number (isotropic) or X,Y,Z
--resample-method     resample_method         linear, cubic, lanczos
--roi                 roi                     x0,y0,z0,x1,y1,z1 mm in the output space
--smooth-volume       smooth_volume           gaussian:SIGMA_MM, median:SIZE_MM, diffusion:ITERATIONS
--interpolate         interpolate             label maps: shape-based, isotropic at the finest spacing
--fuzzy-boundary      fuzzy_boundary          label maps: morphological fuzzy boundary
--fill-cavities       fill_cavities           label maps: fill enclosed background pockets
--close-handles       close_handles           label maps: plug tunnels up to MM across
--fuzzy               fuzzy                   I1 I2 [N]: N nested isosurfaces over [I1, I2]
--precise             precise                 refine isosurfaces onto the trilinear interpolant
--difference-colors   difference_colors       colour surfaces by their distance to the surface
                                              without preprocessing
====================  ======================  =================================================

This module imports nothing from ``app`` (the recipe imports it).
"""
from __future__ import annotations

import math
from typing import List, Optional, Tuple

from ..core.model.errors import AnatomeshError

RESAMPLE_METHODS = ("linear", "cubic", "lanczos")
SMOOTH_FILTERS = ("gaussian", "median", "diffusion")


def parse_numbers(text, flag: str, count: Optional[Tuple[int, ...]] = None) -> List[float]:
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
    values = parse_numbers(arg, f"--smooth-volume {name}", (1, 3))
    if any(v <= 0 for v in values):
        raise AnatomeshError(f"--smooth-volume {name} needs sizes in mm > 0, got {arg!r}")
    return name, values


def check_preprocess(recipe) -> None:
    """Normalise and check the preprocessing fields of ``recipe`` in place (numbers to float
    lists, method names lower case); raise :class:`AnatomeshError` naming the flag."""
    if recipe.resample is not None:
        recipe.resample = parse_numbers(recipe.resample, "--resample", (1, 3))
        if any(v <= 0 for v in recipe.resample):
            raise AnatomeshError(f"--resample is a voxel size in mm > 0, got {recipe.resample}")
    recipe.resample_method = str(recipe.resample_method).lower()
    if recipe.resample_method not in RESAMPLE_METHODS:
        raise AnatomeshError(f"--resample-method must be one of {', '.join(RESAMPLE_METHODS)}, "
                             f"got {recipe.resample_method!r}")
    if recipe.roi is not None:
        recipe.roi = parse_numbers(recipe.roi, "--roi", (6,))
        if any(a == b for a, b in zip(recipe.roi[:3], recipe.roi[3:])):
            raise AnatomeshError(f"--roi is a box x0,y0,z0,x1,y1,z1 in mm with x0 != x1 etc., got {recipe.roi}")
    if recipe.smooth_volume is not None:
        parse_smooth_volume(recipe.smooth_volume)
    if recipe.close_handles is not None and not (not isinstance(recipe.close_handles, bool)
                                                 and recipe.close_handles > 0):
        raise AnatomeshError(f"--close-handles is the largest tunnel to plug, in mm > 0, got {recipe.close_handles!r}")
    if recipe.fuzzy is not None:
        recipe.fuzzy = parse_numbers(recipe.fuzzy, "--fuzzy I1 I2 [N]", (2, 3))
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
