"""The edges of an extracted surface, as mesh formats that store them want them (Blender's mesh:
an edge list and each face corner's edge), built in linear time — so a viewer can take a new
isosurface without deriving its edges itself (the live isovalue slider in Blender)."""
from __future__ import annotations

from typing import Tuple

import numpy as np

from ..model.errors import AnatomeshError
from . import _edges_kernels as K


def unique_edges(faces: np.ndarray, n_vertices: int) -> Tuple[np.ndarray, np.ndarray]:
    """``(edges (E, 2) int32, corner_edge (3M,) int32)`` of triangles ``faces`` (M, 3): every
    undirected edge once as (lower vertex, higher vertex), ordered by the lower vertex, and for
    corner ``c`` of face ``f`` (the edge from ``faces[f, c]`` to ``faces[f, (c + 1) % 3]``) its
    index in ``edges`` at ``3 f + c``."""
    f = np.ascontiguousarray(faces, np.int32).reshape(-1, 3)
    if f.size and (int(f.min()) < 0 or int(f.max()) >= n_vertices):
        raise AnatomeshError(f"faces refer to vertices outside 0..{n_vertices - 1}")
    if not f.size:
        return np.zeros((0, 2), np.int32), np.zeros(0, np.int32)
    return K.unique_edges(f, int(n_vertices))
