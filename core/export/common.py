"""Input checks and colour helpers shared by the scene writers (3MF, GLB)."""
from __future__ import annotations

from typing import List, Sequence, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh


def check_meshes(meshes: Sequence[Mesh], path, fmt: str) -> List[Mesh]:
    """The meshes as a list, or :class:`AnatomeshError` naming ``path`` for an empty list, a
    non-Mesh, surfaces in different (or unknown) spaces, a mesh without faces, non-finite vertices
    or face indices out of range."""
    if isinstance(meshes, Mesh):
        meshes = [meshes]
    meshes = list(meshes or [])
    if not meshes:
        raise AnatomeshError(f"no surfaces to write to {fmt}; extract at least one label or level", path)
    for m in meshes:
        if not isinstance(m, Mesh):
            raise AnatomeshError(f"cannot write {type(m).__name__} to {fmt}: give anatomesh Mesh "
                                 f"objects", path)
        what = f"surface {m.name or '(unnamed)'!r}"
        if m.space not in ("RAS", "LPS") or m.space != meshes[0].space:
            raise AnatomeshError(f"surfaces must all be in one space, RAS or LPS ({what} is in "
                                 f"{m.space!r}, the first in {meshes[0].space!r}); convert them "
                                 f"to one space first", path)
        if m.n_faces == 0:
            raise AnatomeshError(f"{what} has no triangles; leave it out of the {fmt} export", path)
        if not np.isfinite(m.vertices).all():
            raise AnatomeshError(f"{what} has NaN or infinite vertex coordinates; re-run the "
                                 f"smoothing/extraction that produced it", path)
        if m.faces.min() < 0 or m.faces.max() >= m.n_vertices:
            raise AnatomeshError(f"{what} has face indices outside its {m.n_vertices} vertices", path)
    return meshes


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
