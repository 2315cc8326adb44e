"""Fuzzy isosurfaces: an interval of isovalues shown as nested, partly transparent surfaces.

A tissue boundary in a scan is not one value but a band (partial volume, noise); a single
isovalue picks one surface out of it. :func:`fuzzy_isosurfaces` shows the band: ``n`` surfaces at
evenly spaced levels from ``i1`` to ``i2``, the middle one opaque and the others increasingly
transparent toward the ends (alpha falls linearly with the distance from the middle, to
``1 / (half + 1)`` at the ends), after the fuzzy isosurfaces of volume visualisation (Levoy 1988,
"Display of surfaces from volume data": opacity falling off around an isovalue). Higher levels
lie inside lower ones where the values rise inward (a bright object), so the shells nest.
Each surface's RGBA ``Mesh.color`` carries its alpha: the GLB writer makes it a blended
material, the Blender scene its object opacity.
"""
from __future__ import annotations

from typing import List, Optional, Sequence

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.progress import Progress
from .isosurface import isosurfaces

DEFAULT_SURFACES = 5
MAX_SURFACES = 32


def fuzzy_levels(i1: float, i2: float, n: int = DEFAULT_SURFACES):
    """``(levels, alphas)``: ``n`` evenly spaced levels from ``i1`` to ``i2`` (float64) and their
    opacities in (0, 1], 1 in the middle (two middles for an even ``n``)."""
    if isinstance(n, bool) or int(n) != n or not 2 <= n <= MAX_SURFACES:
        raise AnatomeshError(f"--fuzzy needs 2..{MAX_SURFACES} surfaces, got {n!r}")
    i1, i2 = float(i1), float(i2)
    if not (np.isfinite(i1) and np.isfinite(i2)) or i1 == i2:
        raise AnatomeshError(f"--fuzzy needs an interval I1 I2 of two different finite values, got {i1:g} {i2:g}")
    levels = np.linspace(i1, i2, int(n))
    half = (n - 1) / 2.0
    rank = np.floor(np.abs(np.arange(n) - half))  # 0 for the middle one (or two)
    alphas = 1.0 - rank / (np.floor(half) + 1.0)
    return levels, alphas


def fuzzy_isosurfaces(volume, i1: float, i2: float, n: int = DEFAULT_SURFACES,
                      color: Sequence[float] = (0.9, 0.85, 0.75), cap: bool = False,
                      name: str = "fuzzy", progress: Optional[Progress] = None) -> List[Mesh]:
    """``n`` nested isosurfaces over ``[i1, i2]`` (one read of the data, see :func:`isosurfaces`),
    in level order; each Mesh has ``color`` = (r, g, b, alpha), ``meta["alpha"]`` and
    ``meta["fuzzy"]`` = (index, n, i1, i2), and is named ``"<name> <level>"``."""
    levels, alphas = fuzzy_levels(i1, i2, n)
    meshes = isosurfaces(volume, [float(lv) for lv in levels], cap=cap, progress=progress)
    rgb = tuple(float(c) for c in tuple(color)[:3])
    for k, (m, a) in enumerate(zip(meshes, alphas)):
        m.color = rgb + (round(float(a), 4),)
        m.name = f"{name} {m.value:g}"
        m.meta.update(alpha=float(a), fuzzy=[k, int(n), float(i1), float(i2)])
    return meshes
