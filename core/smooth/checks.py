"""Input checks shared by the smoothing filters and guards: one-line AnatomeshErrors naming the
setting, the problem and what to do."""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..geometry.neighbors import MeshStructure, structure as _structure
from ..model.errors import AnatomeshError

PRECISIONS = {"float64": np.float64, "float32": np.float32}


def check_vertices(vertices) -> np.ndarray:
    v = np.asarray(vertices)
    if v.ndim != 2 or v.shape[1] != 3:
        raise AnatomeshError(f"vertices must be an (N, 3) array of positions in mm, got shape {v.shape}")
    if not np.issubdtype(v.dtype, np.number):
        raise AnatomeshError(f"vertices must be numeric, got dtype {v.dtype}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise AnatomeshError("vertices contain NaN or infinite coordinates; fix the mesh first")
    return v


def out_dtype(vertices) -> np.dtype:
    """Results keep the input's float dtype (float64 for integer input)."""
    dt = np.asarray(vertices).dtype
    return dt if np.issubdtype(dt, np.floating) else np.dtype(np.float64)


def check_iterations(iterations) -> None:
    if int(iterations) != iterations or iterations < 0:
        raise AnatomeshError(f"iterations must be a whole number >= 0, got {iterations}")


def check_rings(rings) -> int:
    if rings not in (1, 2):
        raise AnatomeshError(f"rings must be 1 or 2, got {rings}")
    return rings


def mesh_structure(faces, n_vertices: int, structure: Optional[MeshStructure]) -> MeshStructure:
    if structure is None:
        return _structure(faces, n_vertices)
    if structure.n_vertices != n_vertices or structure.n_faces != np.asarray(faces).shape[0]:
        raise AnatomeshError("the given mesh structure was built for another mesh "
                             f"({structure.n_vertices} vertices, {structure.n_faces} faces)")
    return structure


def check_gain(gain, n: int) -> np.ndarray:
    if gain is None:
        return np.zeros(0)
    g = np.ascontiguousarray(gain, dtype=np.float64).ravel()
    if g.shape[0] != n or not np.all((g >= 0) & (g <= 1)):
        raise AnatomeshError(f"gain must hold one value in [0, 1] per vertex ({n})")
    return g


def precision_dtype(precision: str) -> np.dtype:
    """``"float64"`` (default: results match the slow references to ~1e-13 mm) or ``"float32"``
    (live sliders: faster, ~1e-4 mm, the precision Blender stores positions in)."""
    if precision not in PRECISIONS:
        raise AnatomeshError(f"precision must be 'float64' or 'float32', got {precision!r}")
    return np.dtype(PRECISIONS[precision])


def check_factor(name, value, lo, hi):
    if not (lo < value <= hi):
        raise AnatomeshError(f"{name} must be in ({lo}, {hi}], got {value}")


def check_taubin(lam, mu) -> None:
    """λ in (0, 1] and −1 <= μ < −λ (Taubin 1995: the inflating step outweighs the shrinking one)."""
    check_factor("lam", lam, 0.0, 1.0)
    if not (mu < -lam) or mu < -1.0:
        raise AnatomeshError(f"mu must satisfy -1 <= mu < -lam (Taubin 1995), got lam={lam}, mu={mu}")

