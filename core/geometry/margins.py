"""Distance colouring: every vertex coloured by its distance to one structure's surface.

For planning (liver surgery: vessels within a safety margin of a tumour, Preim & Botha 2013,
*Visual Computing for Medicine*, ch. "surgery planning"): each vertex of every other surface gets
the exact Euclidean distance to the nearest point of the target's triangles (Ericson 2004,
"Real-Time Collision Detection", §5.1.5, through the :class:`~anatomesh.core.geometry.spatial.TriangleGrid`),
and a colour per safety margin — within 2 mm red, within 5 mm yellow, within 10 mm green by
default; farther vertices keep the structure's own colour. Colours are sRGB, stored as
``Mesh.vertex_colors`` (the GLB writer writes them as ``COLOR_0``, the PLY writer as uchar, the
Blender scene as a colour attribute, the web page shows them).

A vertex inside the (closed, outward) target — a vessel running through a tumour — is at 0 mm,
as one touching it: inside is told by the side of the closest point's angle-weighted pseudonormal
(Bærentzen & Aanæs 2005, "Signed distance computation using the angle weighted pseudonormal"),
exact for a closed oriented surface, also where the closest point is on an edge or a vertex.
Vertices deeper inside than the largest margin are first proposed by ray parity
(:meth:`~anatomesh.core.geometry.spatial.TriangleGrid.contains`), then decided the same way.
Distances beyond the largest margin are not needed for the colours and are searched no farther
(they are ``inf``).
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import rgba
from ..model.mesh import Mesh
from .spatial import TriangleGrid

#: default safety margins (mm) and their colours (sRGB): red, yellow, green
MARGINS_MM = (2.0, 5.0, 10.0)
MARGIN_COLORS = ((0.9, 0.1, 0.08), (0.98, 0.85, 0.1), (0.2, 0.78, 0.25))


def check_margins(margins: Sequence[float]) -> Tuple[float, ...]:
    """Margins as increasing positive mm; raises :class:`AnatomeshError` otherwise."""
    try:
        m = tuple(float(x) for x in margins)
    except (TypeError, ValueError):
        raise AnatomeshError(f"--margins must be distances in mm, e.g. 2,5,10; got {margins!r}") from None
    if not m or len(m) > len(MARGIN_COLORS) or not all(np.isfinite(m)) or min(m) <= 0 \
            or any(b <= a for a, b in zip(m, m[1:])):
        raise AnatomeshError(f"--margins must be 1 to {len(MARGIN_COLORS)} increasing distances in mm "
                             f"> 0, e.g. 2,5,10; got {','.join(str(x) for x in margins)}")
    return m


def surface_distances(points: np.ndarray, target: TriangleGrid, max_distance: float) -> np.ndarray:
    """Exact distance (mm) from each point (P, 3) to the closed target surface, (P,) float64:
    0 inside it, ``inf`` where nothing is within ``max_distance`` mm."""
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    d, face, q, feat = target.closest(p, max_distance=float(max_distance), return_feature=True)
    lo, hi = target.origin, target.origin + target.dims * target.cell_size  # the grid's box
    deep = np.flatnonzero(np.all((p >= lo) & (p <= hi), axis=1) & ~np.isfinite(d))
    if deep.size:  # beyond the margins: ray parity proposes, the pseudonormal below decides
        deep = deep[target.contains(p[deep])]
    if deep.size:  # an inside point is within half the box's smallest side of the surface
        dd, ff, qq, fe = target.closest(p[deep], max_distance=0.5 * float(np.min(hi - lo)) + 1e-9,
                                        return_feature=True)
        face[deep], q[deep], feat[deep] = ff, qq, fe
    near = np.flatnonzero((face >= 0) & (d > 0))  # a closest point found, not on the surface
    if near.size:
        n = _pseudonormals(target.vertices, target.faces)[face[near], feat[near]]
        inside = np.einsum("ij,ij->i", p[near] - q[near], n) < 0
        d[near[inside]] = 0.0
    return d


def _pseudonormals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(M, 7, 3) the pseudonormal of each feature of each face (feature codes of
    :meth:`TriangleGrid.closest`: corners 0-2 the angle-weighted vertex normals, edges 3-5 the sum
    of the two faces' normals, 6 the face normal), Bærentzen & Aanæs 2005."""
    f = np.asarray(f, np.int64)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    fn = np.cross(b - a, c - a)
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    out = np.empty((len(f), 7, 3))
    vn = np.zeros((len(v), 3))
    for k, (p0, p1, p2) in enumerate(((a, b, c), (b, c, a), (c, a, b))):  # corner k's angle
        u, w = p1 - p0, p2 - p0
        ang = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ij,ij->i", u, w))
        np.add.at(vn, f[:, k], ang[:, None] * fn)
    out[:, :3] = vn[f]
    edges = np.sort(np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1), axis=2).reshape(-1, 2)
    _, key = np.unique(edges, axis=0, return_inverse=True)
    en = np.zeros((key.max() + 1, 3))
    np.add.at(en, key.ravel(), np.repeat(fn, 3, axis=0))
    out[:, 3:6] = en[key.reshape(-1, 3)]
    out[:, 6] = fn
    return out


def margin_colors(distances: np.ndarray, margins: Sequence[float], base_color,
                  colors: Sequence = MARGIN_COLORS) -> np.ndarray:
    """(P, 3) float32 sRGB: ``colors[k]`` for the first margin ``k`` with distance <= margin,
    ``base_color`` (the structure's own, RGB or RGBA 0..1) beyond the last."""
    d = np.asarray(distances, np.float64)
    out = np.tile(np.asarray(rgba(base_color)[:3], np.float32), (d.shape[0], 1))
    for m, c in reversed(list(zip(margins, colors))):
        out[d <= m] = np.asarray(c[:3], np.float32)
    return out


def find_target(meshes: Sequence[Mesh], target) -> int:
    """Index of the mesh named ``target`` (case-insensitive) or with label value ``target``."""
    key = str(target).strip().lower()
    for i, m in enumerate(meshes):
        if m.name.lower() == key or (m.value is not None and key == _value_text(m.value)):
            return i
    names = ", ".join(m.name for m in meshes[:8]) + (", ..." if len(meshes) > 8 else "")
    raise AnatomeshError(f"--distance-to {target!r}: no such structure; choose one of {names}")


def _value_text(v) -> str:
    f = float(v)
    return str(int(f)) if f.is_integer() else str(f)


def color_by_distance(meshes: Sequence[Mesh], target, margins: Sequence[float] = MARGINS_MM,
                      target_surface: Optional[Mesh] = None) -> Tuple[List[Mesh], Dict]:
    """Colour every mesh except the target by its vertices' distance to the target's surface.

    Parameters
    ----------
    meshes : sequence of Mesh
        Surfaces in one space, vertices (N, 3) mm.
    target : str or int
        Name (case-insensitive) or label value of the structure distances are measured to.
    margins : increasing mm
        Safety margins, coloured :data:`MARGIN_COLORS` (red, yellow, green).
    target_surface : Mesh, optional
        The surface to measure to (e.g. the full-detail target while colouring a coarse level of
        detail); default the target mesh itself.

    Returns
    -------
    meshes : list of Mesh
        The same meshes (not copied) with ``vertex_colors`` (N, 3) sRGB set; the target's are
        cleared (it shows its own colour).
    summary : dict
        ``target``, ``margins_mm``, ``colors`` and per other mesh name ``min_distance_mm``
        (``None`` beyond the last margin) and ``within_mm``: the share of vertices within each
        margin.
    """
    margins = check_margins(margins)
    meshes = list(meshes)
    k = find_target(meshes, target)
    surf = target_surface if target_surface is not None else meshes[k]
    if surf.n_faces == 0:
        raise AnatomeshError(f"--distance-to {target!r}: that structure has no triangles")
    if any(m.space != surf.space for m in meshes):
        raise AnatomeshError("distance colouring needs every surface in one space (RAS or LPS)")
    grid = TriangleGrid(surf.vertices, surf.faces)
    shells: Dict[str, Dict] = {}
    meshes[k].vertex_colors = None  # the target keeps its own colour
    others = [i for i in range(len(meshes)) if i != k]
    stacked = surface_distances(np.concatenate([meshes[i].vertices for i in others] or [np.zeros((0, 3))]),
                                grid, margins[-1])
    ends = np.cumsum([0] + [meshes[i].n_vertices for i in others])
    for j, i in enumerate(others):
        m, d = meshes[i], stacked[ends[j]:ends[j + 1]]
        m.vertex_colors = margin_colors(d, margins, m.color)
        near = float(d.min()) if d.size and np.isfinite(d.min()) else None
        shells[m.name] = {"min_distance_mm": None if near is None else round(near, 3),
                          "within_mm": {f"{x:g}": round(float(np.mean(d <= x)), 4) if d.size else 0.0
                                        for x in margins}}
    return meshes, {"target": meshes[k].name, "margins_mm": list(margins),
                    "colors": [list(c) for c in MARGIN_COLORS[:len(margins)]], "shells": shells}
