"""Edit-mode print tools on a user's own meshes, in the spirit of Blender's 3D Print
Toolbox: small checks that return element indices of a ``bmesh`` (each measured by a core
function on the mesh's triangles), and the fixes built on them.

================================  ===============================================================
:func:`nonmanifold_edges`         edges with more than two faces, or none (core
                                  :func:`~anatomesh.core.geometry.topology.edge_face_counts`)
:func:`boundary_edges`            edges with exactly one face (holes)
:func:`intersecting_faces`        faces crossing another face of the mesh (core
                                  :func:`~anatomesh.core.geometry.intersections.self_intersections`,
                                  Möller 1997)
:func:`thin_faces`                faces with a corner thinner than the minimum wall (core
                                  :func:`~anatomesh.core.printing.thickness.wall_thickness`)
:func:`fill_holes`                boundary loops of up to N edges (core
                                  :func:`~anatomesh.core.printing.fixes.boundary_loops`) filled
                                  by ``bmesh.ops.holes_fill`` and triangulated
:func:`remove_tiny_shells`        loose parts enclosing less than a volume (core
                                  :func:`~anatomesh.core.printing.solid.tiny_shells`)
:func:`relax_selected`            the selected vertices smoothed by the core's Laplacian filter,
                                  unselected ones locked (gain 0), none farther than a maximum
                                  deviation (:class:`~anatomesh.core.smooth.constraints.Constraint`)
================================  ===============================================================

Measures are taken in world coordinates when the object's transform is given (``matrix``),
else in the mesh's own (mm in an Anatomesh scene); volumes mm³. Ngons are
measured through their triangulation (``calc_loop_triangles``); the results name bmesh indices.
"""
from __future__ import annotations

from typing import Dict, List, Tuple

import bmesh
import numpy as np

#: the problems the Edit Mode selector selects (identifier, label, description)
PROBLEM_ITEMS = (
    ("NON_MANIFOLD", "Non-manifold edges", "Edges with more than two faces, or with none"),
    ("BOUNDARY", "Boundary edges", "Edges with one face: the rims of holes"),
    ("INTERSECTING", "Self-intersecting faces", "Faces that cross another face of the mesh"),
    ("THIN", "Thin faces", "Faces thinner than the print panel's minimum wall"),
)


def mesh_arrays(bm, matrix=None) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(vertices (N, 3) float64 mm, triangles (T, 3) int64, face of each triangle (T,) int64)``
    of a bmesh, indices as ``bm.verts`` / ``bm.faces`` (index tables refreshed); ``matrix``
    (4, 4): the object's transform, to measure in world coordinates (None: the mesh's own)."""
    bm.verts.index_update()
    bm.faces.index_update()
    bm.edges.index_update()
    v = np.array([x.co for x in bm.verts], np.float64).reshape(-1, 3)
    if matrix is not None:
        m = np.asarray(matrix, np.float64)
        v = v @ m[:3, :3].T + m[:3, 3]
    tris = bm.calc_loop_triangles()
    f = np.array([[lp.vert.index for lp in t] for t in tris], np.int64).reshape(-1, 3)
    owner = np.array([t[0].face.index for t in tris], np.int64)
    return v, f, owner


def _edges_of_pairs(bm, pairs: np.ndarray) -> List[int]:
    """bmesh edge indices of vertex pairs (K, 2); pairs that are no edge (diagonals of ngons)
    are skipped."""
    index = {tuple(sorted((e.verts[0].index, e.verts[1].index))): e.index for e in bm.edges}
    return sorted(index[k] for k in map(tuple, np.sort(pairs, axis=1).tolist()) if k in index)


def nonmanifold_edges(bm) -> List[int]:
    """Indices of the edges used by more than two faces, and of loose edges (no face)."""
    from ...core.geometry.topology import edge_face_counts

    v, f, _ = mesh_arrays(bm)
    edges, count, _ = edge_face_counts(f, len(v))
    out = set(_edges_of_pairs(bm, edges[count > 2]))
    out.update(e.index for e in bm.edges if not e.link_faces)
    return sorted(out)


def boundary_edges(bm) -> List[int]:
    """Indices of the edges with exactly one face."""
    from ...core.geometry.topology import edge_face_counts

    v, f, _ = mesh_arrays(bm)
    edges, count, _ = edge_face_counts(f, len(v))
    return _edges_of_pairs(bm, edges[count == 1])


def intersecting_faces(bm, matrix=None) -> List[int]:
    """Indices of the faces crossing another face (faces sharing a vertex do not count)."""
    from ...core.geometry.intersections import self_intersections

    v, f, owner = mesh_arrays(bm, matrix)
    if not len(f):
        return []
    pairs = self_intersections(v, f)
    return sorted(set(owner[np.unique(pairs.ravel())].tolist()))


def thin_faces(bm, min_wall: float, matrix=None) -> List[int]:
    """Indices of the faces with a corner where the wall is thinner than ``min_wall`` mm."""
    from ...core.printing.thickness import wall_thickness

    v, f, owner = mesh_arrays(bm, matrix)
    if not len(f):
        return []
    t = wall_thickness(v, f, max_thickness=5.0 * min_wall)
    thin = np.nanmin(np.where(np.isnan(t[f]), np.inf, t[f]), axis=1) < min_wall
    return sorted(set(owner[thin].tolist()))


def problem_elements(bm, kind: str, min_wall: float = 0.8, matrix=None) -> Tuple[str, List[int]]:
    """``("EDGE" | "FACE", indices)`` of the problem ``kind`` (see :data:`PROBLEM_ITEMS`)."""
    if kind == "NON_MANIFOLD":
        return "EDGE", nonmanifold_edges(bm)
    if kind == "BOUNDARY":
        return "EDGE", boundary_edges(bm)
    if kind == "INTERSECTING":
        return "FACE", intersecting_faces(bm, matrix)
    if kind == "THIN":
        return "FACE", thin_faces(bm, min_wall, matrix)
    raise ValueError(f"unknown problem kind {kind!r}")


def select_elements(bm, domain: str, indices: List[int]) -> None:
    """Select exactly the given edges or faces (and their vertices); everything else unselected."""
    for seq in (bm.verts, bm.edges, bm.faces):
        for x in seq:
            x.select_set(False)
    seq = bm.edges if domain == "EDGE" else bm.faces
    seq.ensure_lookup_table()
    for i in indices:
        seq[i].select_set(True)
    bm.select_flush_mode()


def fill_holes(bm, max_edges: int) -> Dict:
    """Fill the holes whose boundary loop has at most ``max_edges`` edges; the new faces are
    triangulated. Returns ``{"filled", "left_open", "added_faces"}``."""
    from ...core.printing.fixes import boundary_loops

    v, f, _ = mesh_arrays(bm)
    loops, bad = boundary_loops(f, len(v))
    small = [lp for lp in loops if len(lp) <= max_edges]
    pairs = np.concatenate([np.stack([lp, np.roll(lp, -1)], axis=1) for lp in small]) if small \
        else np.zeros((0, 2), np.int64)
    bm.edges.ensure_lookup_table()
    edges = [bm.edges[i] for i in _edges_of_pairs(bm, pairs)]
    n0 = len(bm.faces)
    made = bmesh.ops.holes_fill(bm, edges=edges, sides=max_edges)["faces"] if edges else []
    if made:
        bmesh.ops.triangulate(bm, faces=made)
    return {"filled": len(made), "left_open": len(loops) - len(small) + (1 if bad else 0),
            "added_faces": len(bm.faces) - n0}


def remove_tiny_shells(bm, min_volume_mm3: float, matrix=None) -> Dict:
    """Delete the loose parts enclosing less than ``min_volume_mm3`` mm³ (absolute volume).
    Returns ``{"removed", "volumes_mm3"}``."""
    from ...core.printing.solid import tiny_shells

    v, f, owner = mesh_arrays(bm, matrix)
    if not len(f):
        return {"removed": 0, "volumes_mm3": []}
    shells = tiny_shells(v, f, min_volume_mm3)
    bm.faces.ensure_lookup_table()
    doomed = {x for s in shells for i in np.unique(owner[s["faces"]]) for x in bm.faces[int(i)].verts}
    if doomed:
        bmesh.ops.delete(bm, geom=list(doomed), context="VERTS")
    return {"removed": len(shells), "volumes_mm3": [round(float(s["volume_mm3"]), 4) for s in shells]}


def relax_selected(bm, max_deviation: float, iterations: int = 10, matrix=None) -> Dict:
    """Smooth the selected vertices with the core's Laplacian filter (Fujiwara 1995, λ 0.5), the
    unselected ones locked (gain 0), none moving farther than ``max_deviation`` mm from where it
    was (the bound is applied after every pass). Laplacian rather than Taubin: under a tight
    bound Taubin's inflating μ step undoes the clamped λ step and roughens (a noisy plate at
    0.1 mm: spread 0.34 → 0.39 mm with Taubin, → 0.29 mm with Laplacian); the bound caps the
    shrinking. Returns ``{"moved", "max_moved_mm"}``."""
    from ...core.smooth.constraints import Constraint
    from ...core.smooth.driver import smooth

    v, f, _ = mesh_arrays(bm, matrix)
    sel = np.array([x.select for x in bm.verts], bool)
    if not sel.any() or not len(f):
        return {"moved": 0, "max_moved_mm": 0.0}
    out = smooth(v, f, "laplacian", iterations=int(iterations), lam=0.5,
                 constraint=Constraint(max_deviation=float(max_deviation)), gain=sel.astype(np.float64),
                 fold_guard=True)
    out[~sel] = v[~sel]
    d = np.linalg.norm(out - v, axis=1)
    if matrix is not None:  # back to the mesh's own coordinates
        inv = np.linalg.inv(np.asarray(matrix, np.float64))
        out = out @ inv[:3, :3].T + inv[:3, 3]
    for x, p in zip(bm.verts, out):
        if x.select:
            x.co = p
    return {"moved": int((d > 0).sum()), "max_moved_mm": round(float(d.max()), 4)}
