"""A scan's Blender objects back into one core SurfaceSet: shells that share vertex ids
(``anatomesh_vid``) reassembled with their interfaces stored once and their pinch points as split
rows, for decimating and live smoothing."""
from __future__ import annotations

from typing import List, Tuple

import numpy as np

from . import bridge


def surface_set_from_objects(objects, rest: bool = False) -> Tuple[object, List]:
    """Put shells that share vertex ids (``anatomesh_vid``) back together into a core SurfaceSet.

    Object ``k`` becomes label ``k + 1`` (background 0). A triangle found in two objects (an
    interface, once per orientation) is stored once, oriented as in its first object, with the
    two labels on its sides; a vertex id used by several vertices of one object (a pinch point,
    where a shell touches itself) gives split rows, so the shells come back 2-manifold.
    Positions are the objects' current ones (the shape shown), or with ``rest`` their unsmoothed
    ones (``anatomesh_rest``). No lattice (the live cache adds it). Returns ``(SurfaceSet, objects)``.
    """
    from ...core.geometry.pinches import copy_numbers
    from ...core.model.errors import AnatomeshError
    from ...core.model.surfaceset import SurfaceSet

    parts = []
    for o in objects:
        vid = bridge.point_attribute(o.data, bridge.SHARED_INDEX_ATTRIBUTE, "int")
        pos = bridge.point_attribute(o.data, bridge.REST_ATTRIBUTE, "vector") if rest else None
        pos = bridge.positions(o.data) if pos is None else pos
        parts.append((o, pos, bridge.triangles(o.data), vid.astype(np.int64)))
    n = 1 + max(int(vid.max()) for _, _, _, vid in parts if vid.size)
    verts = np.zeros((n, 3), np.float32)
    occ_faces, occ_owner, occ_copy = [], [], []
    for k, (o, pos, tri, vid) in enumerate(parts):
        first = copy_numbers(vid) == 0  # a pinch point's copies sit beside it, not on it
        verts[vid[first]] = pos[first]
        occ_faces.append(vid[tri])
        occ_owner.append(np.full(len(tri), k + 1, np.int32))
        occ_copy.append(copy_numbers(vid)[tri])
    g = np.concatenate(occ_faces)
    own = np.concatenate(occ_owner)
    copy = np.concatenate(occ_copy)
    _, first, inv = np.unique(np.sort(g, axis=1), axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(first)                 # stored faces in the order the objects list them
    slot = np.empty(len(first), np.int64)
    slot[order] = np.arange(len(first))
    face_of = slot[inv]                       # stored face of every occurrence
    faces = g[first[order]]
    inside = own[first[order]]
    outside = np.zeros(len(faces), np.int32)
    twin = own != inside[face_of]
    uses = np.bincount(face_of, minlength=len(faces))
    if uses.max(initial=0) > 2 or np.any(np.bincount(face_of[twin], minlength=len(faces)) != uses - 1):
        raise AnatomeshError("the scan's objects do not fit together as one surface set (a triangle "
                             "is used by more than two organs or twice by one); re-extract the scan")
    outside[face_of[twin]] = own[twin]
    # split rows: corners that use a vertex copy (copy >= 1) in their own shell
    occ, corner_in_occ = np.nonzero(copy > 0)
    rows = np.zeros((len(occ), 4), np.int32)
    if len(occ):
        fi = face_of[occ]
        vals = g[occ, corner_in_occ]
        rows[:, 0] = fi
        rows[:, 1] = np.where(twin[occ], 1, 0)
        rows[:, 2] = np.argmax(faces[fi] == vals[:, None], axis=1)
        rows[:, 3] = copy[occ, corner_in_occ]
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
    affine = object_affine(objects[0]) if objects else np.eye(4)
    ss = SurfaceSet(verts, faces, np.c_[inside, outside], None, affine,
                    space=str(objects[0].get("anatomesh_space", "RAS")), splits=rows, background=0)
    return ss, [o for o, _, _, _ in parts]


def object_affine(obj) -> np.ndarray:
    """The voxel-to-mm affine (4, 4) an object was extracted with (``anatomesh_affine``), or the
    identity when it has none."""
    aff = obj.get("anatomesh_affine")
    return np.asarray(list(aff), np.float64).reshape(4, 4) if aff is not None and len(aff) == 16 else np.eye(4)
