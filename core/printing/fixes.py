"""Fixes for 3D printing, each optional and each reporting what it did (the checks are in
:mod:`.checks`).

* :func:`remove_tiny` — drop shells enclosing less than a volume (mm³);
* :func:`close_holes` — fill boundary loops of up to ``max_edges`` edges with a fan around the
  loop's centroid (Liepa 2003, "Filling holes in meshes", without the refinement step: small
  holes in segmentation surfaces are nearly planar);
* :func:`separate_parts` / :func:`separate_meshes` — pull touching parts (of a
  :class:`SurfaceSet`, or meshes sharing vertex positions) apart by a clearance: every interface
  vertex is duplicated per side and moved back along that side's normal by half the clearance
  (a mitred offset, solved by Kaczmarz 1937 projections, "Angenäherte Auflösung von Systemen
  linearer Gleichungen"), so printed parts fit together after printing;
* :func:`fuse_labels` / :func:`fuse_parts` — print chosen labels as one solid: merge the labels
  in the label map before extraction, or drop the interface faces between them in a SurfaceSet;
* :func:`thicken_labels` — dilate a label where it is thinner than the minimum wall, in the
  volume before extraction: thin voxels are those a morphological opening by a ball of the wall's
  diameter removes (Serra 1982, "Image Analysis and Mathematical Morphology"), i.e. where no
  inscribed ball that large fits (Hildebrand & Rüegsegger 1997, "A new method for the
  model-independent assessment of thickness in three-dimensional images").

Each returns ``(result, info)``; ``info`` is a JSON-ready dict of what was changed.
"""
from __future__ import annotations

from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh, check_arrays, compact, row_keys, vertex_normals, weld_ids
from .solid import tiny_shells


# ---------------------------------------------------------------------------------------------
# tiny shells and holes (on one Mesh)
# ---------------------------------------------------------------------------------------------
def remove_tiny(mesh: Mesh, min_volume_mm3: float) -> Tuple[Mesh, Dict]:
    """``mesh`` without the components enclosing less than ``min_volume_mm3`` mm³.

    Returns (mesh, ``{"removed": count, "volumes_mm3": [...]}``)."""
    if not np.isfinite(min_volume_mm3) or min_volume_mm3 < 0:
        raise AnatomeshError(f"the tiny-shell volume must be a non-negative number of mm³, got {min_volume_mm3}")
    out = remove_tiny_shells(mesh, float(min_volume_mm3))
    vols = out.meta.pop("removed_shells", [])
    return out, {"removed": len(vols), "volumes_mm3": vols}


def boundary_loops(faces: np.ndarray, n_vertices: int) -> Tuple[List[np.ndarray], int]:
    """Closed loops of boundary edges (edges with one face), each (L,) int64 vertex indices in
    the direction of the face's half-edge. Returns (loops, number of boundary edges that do not
    form simple loops — at vertices where several loops meet)."""
    f = np.asarray(faces, np.int64)
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = he[:, 0] * n_vertices + he[:, 1]
    rev = he[:, 1] * n_vertices + he[:, 0]
    bnd = he[~np.isin(key, rev)]
    if bnd.shape[0] == 0:
        return [], 0
    # vertices with several outgoing boundary half-edges make loops ambiguous: leave them
    out_count = np.bincount(bnd[:, 0], minlength=n_vertices)
    in_count = np.bincount(bnd[:, 1], minlength=n_vertices)
    simple = (out_count[bnd[:, 0]] == 1) & (in_count[bnd[:, 1]] == 1) & \
        (out_count[bnd[:, 1]] == 1) & (in_count[bnd[:, 0]] == 1)
    nxt = {int(a): int(b) for a, b in bnd[simple]}
    loops, seen = [], set()
    bad = int((~simple).sum())
    for s in list(nxt):
        if s in seen:
            continue
        loop = [s]
        seen.add(s)
        cur = nxt[s]
        while cur != s and cur in nxt and cur not in seen:
            loop.append(cur)
            seen.add(cur)
            cur = nxt[cur]
        if cur == s:
            loops.append(np.array(loop, np.int64))
        else:
            bad += len(loop)
    return loops, bad


def close_holes(mesh: Mesh, max_edges: int = 30) -> Tuple[Mesh, Dict]:
    """Fill every boundary loop of at most ``max_edges`` edges with a fan of triangles around a
    new vertex at the loop's centroid, wound like the faces around it.

    Returns (mesh, ``{"closed": count, "left_open": count, "added_faces": count,
    "locations": [centroids mm]}``)."""
    if int(max_edges) < 3:
        raise AnatomeshError(f"holes have at least 3 edges; got --close-holes {max_edges}")
    v, f = check_arrays(mesh.vertices, mesh.faces)
    loops, bad = boundary_loops(f, len(v))
    new_v, new_f, locs = [], [], []
    left = 1 if bad else 0
    for loop in loops:
        if loop.size > max_edges:
            left += 1
            continue
        c = v[loop].mean(axis=0)
        ci = len(v) + len(new_v)
        new_v.append(c)
        # boundary half-edge a→b belongs to a face; the filling face runs b→a
        a, b = loop, np.roll(loop, -1)
        new_f.append(np.stack([b, a, np.full_like(a, ci)], axis=1))
        locs.append([round(float(x), 3) for x in c])
    if not new_v:
        return mesh, {"closed": 0, "left_open": left, "added_faces": 0, "locations": []}
    vv = np.concatenate([v, np.array(new_v)])
    ff = np.concatenate([f] + new_f).astype(np.int32)
    out = Mesh(vv, ff, None, name=mesh.name, value=mesh.value, color=mesh.color, space=mesh.space,
               meta=dict(mesh.meta))
    return out, {"closed": len(new_v), "left_open": left, "added_faces": int(ff.shape[0] - f.shape[0]),
                 "locations": locs}


# ---------------------------------------------------------------------------------------------
# separating and fusing parts of a SurfaceSet
# ---------------------------------------------------------------------------------------------
def _set_arrays(surfaces):
    v = np.asarray(surfaces.vertices, np.float64)
    f = np.asarray(surfaces.faces, np.int64)
    lab = np.asarray(surfaces.face_labels, np.int64)
    return v, f, lab


def separate_parts(surfaces, clearance: float, labels: Optional[Iterable[int]] = None):
    """Pull the parts of a :class:`~anatomesh.core.model.surfaceset.SurfaceSet` apart along their
    shared interfaces by ``clearance`` mm: :func:`separate_meshes` on its shells.

    ``labels`` limits the separation to interfaces between the listed labels; a vertex also
    used by a label not listed stays put (chosen parts still meet along such junctions).

    Returns (one closed :class:`Mesh` per label, same faces as :meth:`SurfaceSet.shells`;
    ``{"clearance_mm", "moved_vertices", "pairs": [[label a, label b], ...]}``)."""
    shells = surfaces.shells()
    chosen = None
    if labels is not None:
        want = {int(x) for x in labels}
        chosen = [k for k, m in enumerate(shells) if int(m.value) in want]
    out, info = separate_meshes(shells, clearance, chosen)
    info["pairs"] = sorted([sorted((int(shells[a].value), int(shells[b].value)))
                            for a, b in info["pairs"]])
    return out, info


def separate_meshes(meshes: Sequence[Mesh], clearance: float, chosen: Optional[Iterable[int]] = None):
    """Pull touching parts apart by ``clearance`` mm, where they share vertex positions (the
    shells of a label map, or their files read back).

    Each part has its own copy of every interface vertex (a position other parts use too); each
    copy moves into its own part by at least ``clearance / 2`` along the normal of every
    interface face around it (faces whose three corners another part has as a face too; a
    mitred offset), or along its vertex normal where parts touch only along an edge or at a
    point. Flat and gently curved interfaces end up ``clearance`` apart; at the rim of an
    interface, where the other part's surface runs on past it, the bevel would narrow the gap
    (to ``clearance * sqrt(2/3)`` at a right angle, less at shallow ones): :func:`open_rims`
    then pushes the rim vertices apart until they are ``clearance`` from the other part. Parts
    stay closed and share no vertex afterwards. A part
    thinner than ``clearance / 2`` behind its interface would fold: thicken it first.
    ``chosen`` (indices) limits the separation to interfaces between those parts.

    Returns (meshes, ``{"clearance_mm", "moved_vertices", "rim_vertices", "pairs": [[i, j],
    ...]}``)."""
    if not np.isfinite(clearance) or clearance <= 0:
        raise AnatomeshError(f"the clearance must be a positive number of mm, got {clearance}")
    shells = list(meshes)
    ok_label = np.ones(len(shells), bool)
    if chosen is not None:
        ok_label[:] = False
        ok_label[list(chosen)] = True
    pos = [np.asarray(m.vertices, np.float64) for m in shells]
    wid = weld_ids(np.concatenate(pos)) if shells else np.zeros(0, np.int64)
    offs = np.cumsum([0] + [len(p) for p in pos])
    owner = np.repeat(np.arange(len(shells)), np.diff(offs))
    nw = int(wid.max()) + 1 if wid.size else 0
    # a position moves when it is shared, and only by chosen parts (if every user is chosen)
    users = np.zeros(nw, np.int64)
    np.add.at(users, np.unique(np.stack([wid, owner], 1), axis=0)[:, 0], 1)
    blocked = np.zeros(nw, bool)
    blocked[wid[~ok_label[owner]]] = True
    movable = (users > 1) & ~blocked
    # interface faces: the same three positions in two parts
    fkeys = [row_keys(np.sort(wid[offs[k]:offs[k + 1]][m.faces], axis=1)) for k, m in enumerate(shells)]
    allk = np.concatenate(fkeys) if fkeys else np.zeros(0)
    _, inv, cnt = np.unique(allk, return_inverse=True, return_counts=True)
    seam_all = cnt[inv.ravel()] > 1
    foffs = np.cumsum([0] + [m.n_faces for m in shells])
    pairs = set()
    out, moved = [], 0
    for k, m in enumerate(shells):
        w = wid[offs[k]:offs[k + 1]]
        move = movable[w] & ok_label[k]
        seam = seam_all[foffs[k]:foffs[k + 1]]
        n_all = vertex_normals(pos[k], m.faces)  # outward (shells are oriented outward)
        n_seam = vertex_normals(pos[k], m.faces[seam]) if np.any(seam) else np.zeros_like(n_all)
        has = np.linalg.norm(n_seam, axis=1) > 0.5
        n = np.where(has[:, None], n_seam, n_all)
        n = _offset_directions(pos[k], m.faces[seam] if np.any(seam) else m.faces, n)
        nv = pos[k] - 0.5 * clearance * n * move[:, None]
        moved += int(move.sum())
        out.append(Mesh(nv, m.faces, None, name=m.name, value=m.value, color=m.color,
                        space=m.space, meta=dict(m.meta)))
        if np.any(move):
            for o in np.unique(owner[np.isin(wid, w[move])]):
                if o != k:
                    pairs.add(tuple(sorted((k, int(o)))))
    fixed = [blocked[wid[offs[k]:offs[k + 1]]] for k in range(len(shells))]
    rims = open_rims(out, sorted(pairs), clearance, fixed)
    return out, {"clearance_mm": float(clearance), "moved_vertices": moved, "rim_vertices": rims,
                 "pairs": [list(p) for p in sorted(pairs)]}


def open_rims(meshes: List[Mesh], pairs, clearance: float, fixed=None, rounds: int = 6) -> int:
    """Push apart the vertices of separated parts that are still nearer than ``clearance`` mm to
    their neighbour — at the rim of an interface, where the other part's surface runs on past
    it at a shallow angle, the mitred offset leaves the gap narrower (0.13 mm of 0.4 mm between
    the sample's liver and gallbladder). Each round, every such vertex of either part moves half
    its deficit away from the nearest point of the other (exact point-to-triangle search,
    :class:`~anatomesh.core.geometry.spatial.TriangleGrid`); ``fixed`` (per part, (N_k,) bool)
    vertices stay (junctions with parts not separated). Changes ``meshes`` in place; returns the
    number of vertices moved."""
    from ..geometry.spatial import TriangleGrid

    moved = set()
    for _ in range(rounds):
        pushed = 0
        for a, b in pairs:
            for k, o in ((a, b), (b, a)):
                pushed += _push_from(meshes, k, TriangleGrid(meshes[o].vertices, meshes[o].faces),
                                     clearance, None if fixed is None else fixed[k], moved)
        if not pushed:
            break
    return len(moved)


def _push_from(meshes, k, other, clearance, fixed, moved) -> int:
    """One round of :func:`open_rims` for part ``k`` against the grid of its neighbour."""
    v = np.asarray(meshes[k].vertices, np.float64)
    d, _, q = other.closest(v, max_distance=clearance)
    near = np.flatnonzero(d < 0.995 * clearance)
    if fixed is not None:
        near = near[~fixed[near]]
    if not near.size:
        return 0
    away = v[near] - q[near]
    ln = np.linalg.norm(away, axis=1, keepdims=True)
    inward = -vertex_normals(v, meshes[k].faces)[near]  # touching: into the own part
    away = np.where(ln > 1e-9, away / np.maximum(ln, 1e-300), inward)
    v = v.copy()
    v[near] += 0.5 * (clearance - d[near])[:, None] * away
    meshes[k] = Mesh(v, meshes[k].faces, None, name=meshes[k].name, value=meshes[k].value,
                     color=meshes[k].color, space=meshes[k].space, meta=dict(meshes[k].meta))
    moved.update((k, int(i)) for i in near)
    return int(near.size)


def _offset_directions(v, faces, n0, iters: int = 8, cap: float = 3.0) -> np.ndarray:
    """Per vertex a displacement d (N, 3) with d·n_f ≥ 1 for the normal n_f of every face
    around it (a mitred offset by 1: where two perpendicular interfaces meet, d = n1 + n2).

    Starts from the unit vertex normals ``n0`` and, per vertex, repeatedly adds the deficit of
    its most violated face (projections onto the half-spaces, Kaczmarz 1937, "Angenäherte
    Auflösung von Systemen linearer Gleichungen"); |d| is capped at ``cap``."""
    f = np.asarray(faces, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    d = np.array(n0, np.float64)
    corner_v = f.ravel()
    corner_n = np.repeat(fn, 3, axis=0)
    for _ in range(iters):
        deficit = 1.0 - np.einsum("ij,ij->i", d[corner_v], corner_n)
        bad = deficit > 1e-3
        if not np.any(bad):
            break
        cv, cd, cn = corner_v[bad], deficit[bad], corner_n[bad]
        order = np.lexsort((cd, cv))  # per vertex, its most violated face last
        last = order[np.r_[cv[order][1:] != cv[order][:-1], True]]
        d[cv[last]] += cd[last, None] * cn[last]
    ln = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(ln > cap, d * cap / np.maximum(ln, 1e-300), d)


def fuse_parts(surfaces, labels: Iterable[int], name: Optional[str] = None) -> Tuple[Mesh, Dict]:
    """One closed solid from the chosen labels of a SurfaceSet: their faces except the
    interfaces between two chosen labels (which would lie inside the fused solid).

    Returns (mesh, ``{"labels": [...], "dropped_faces": count}``)."""
    v, f, lab = _set_arrays(surfaces)
    chosen = np.array(sorted({int(x) for x in labels}), np.int64)
    present = set(np.unique(lab[lab > 0]).tolist())
    missing = [int(x) for x in chosen if int(x) not in present]
    if chosen.size < 1 or missing:
        raise AnatomeshError(f"cannot fuse labels {missing or list(chosen)}: the surfaces have labels "
                             f"{sorted(present)[:20]}")
    a_in = np.isin(lab[:, 0], chosen)
    b_in = np.isin(lab[:, 1], chosen)
    keep = a_in ^ b_in  # exactly one side is in the fused set: its outer surface
    ff = f[keep].copy()
    # orient outward from the fused solid: face normals point from label[:,0] to label[:,1]
    # (SurfaceSet convention); flip where the chosen label is on the other side
    flip = b_in[keep]
    ff[flip] = ff[flip][:, ::-1]
    nv, nf, _, _ = compact(v, ff)
    first = surfaces.shell(int(chosen[0]))
    mesh = Mesh(nv, nf, None, name=name or "+".join(surfaces.shell(int(c)).name for c in chosen),
                value=int(chosen[0]), color=first.color, space=first.space)
    return mesh, {"labels": [int(x) for x in chosen], "dropped_faces": int(np.sum(a_in & b_in))}


# ---------------------------------------------------------------------------------------------
# label-map fixes (before extraction)
# ---------------------------------------------------------------------------------------------
def fuse_labels(volume, labels: Iterable[int], into: Optional[int] = None):
    """A copy of the label-map ``volume`` with the chosen labels merged into one (``into``,
    default the first): extraction then gives one closed solid for them.

    Returns (volume, ``{"labels": [...], "into": value, "voxels": count}``)."""
    from dataclasses import replace

    chosen = [int(x) for x in labels]
    if not chosen:
        raise AnatomeshError("give at least one label to fuse")
    into = chosen[0] if into is None else int(into)
    data = np.array(volume.data, copy=True)
    mask = np.isin(data, chosen)
    data[mask] = into
    vol = replace(volume, data=data, warnings=list(volume.warnings))
    return vol, {"labels": chosen, "into": into, "voxels": int(mask.sum())}


def _ball(radius_vox: np.ndarray) -> np.ndarray:
    r = np.maximum(radius_vox, 0.5)
    n = np.ceil(r).astype(int)
    g = np.meshgrid(*[np.arange(-k, k + 1) for k in n], indexing="ij")
    return sum((gi / ri) ** 2 for gi, ri in zip(g, r)) <= 1.0 + 1e-9


def thicken_labels(volume, min_wall: float, labels: Optional[Iterable[int]] = None):
    """Grow each label where it is thinner than ``min_wall`` mm, in the label map before
    extraction.

    A label's thin voxels are those its morphological opening (Serra 1982, "Image Analysis and
    Mathematical Morphology") by a ball of diameter ``min_wall`` (in mm, anisotropic spacing
    respected) removes — where no inscribed ball of that diameter fits (the thickness of
    Hildebrand & Rüegsegger 1997, "A new method for the model-independent assessment of
    thickness in three-dimensional images") — except pieces lying wholly within one voxel of
    what the opening keeps (the convex corners and edges no ball reaches). They are dilated by a
    ball of radius ``min_wall / 2`` plus half a voxel (so the digital ball has no one-voxel
    spikes) into background voxels (label 0) only, so other labels keep their voxels.

    Returns (volume, ``{"labels": {value: added voxels}, "min_wall_mm"}``)."""
    from dataclasses import replace

    from scipy import ndimage

    if not np.isfinite(min_wall) or min_wall <= 0:
        raise AnatomeshError(f"min_wall must be a positive number of mm, got {min_wall}")
    data = np.asarray(volume.data)
    if not np.issubdtype(data.dtype, np.integer):
        raise AnatomeshError("thickening works on label maps (integer voxels); this volume is a scan")
    spacing = np.linalg.norm(volume.affine[:3, :3], axis=0)
    ball = _ball(0.5 * min_wall / spacing)
    # growing uses half a voxel more, so the digital ball has no one-voxel spikes (lips)
    grow_ball = _ball(0.5 * min_wall / spacing + 0.5)
    values = sorted(set(np.unique(data).tolist()) - {0}) if labels is None else [int(x) for x in labels]
    out = data.copy()
    added = {}
    for val in values:
        m = data == val
        if not m.any():
            continue
        # what the opening removes; a piece of it lying wholly within one voxel of what the
        # opening keeps is a convex corner or edge no ball reaches, not a thin wall
        opened = ndimage.binary_opening(m, ball)
        residue = m & ~opened
        rim = ndimage.binary_dilation(opened, np.ones((3, 3, 3), bool))
        pieces, _ = ndimage.label(residue, np.ones((3, 3, 3), bool))
        thin = np.isin(pieces, np.unique(pieces[residue & ~rim]))
        if not thin.any():
            continue
        grow = ndimage.binary_dilation(thin, grow_ball) & (out == 0)
        out[grow] = val
        added[int(val)] = int(grow.sum())
    vol = replace(volume, data=out, warnings=list(volume.warnings))
    return vol, {"labels": added, "min_wall_mm": float(min_wall)}


def remove_tiny_shells(mesh: Mesh, min_volume_mm3: float) -> Mesh:
    """A copy of ``mesh`` without the components enclosing less than ``min_volume_mm3``
    (see :func:`anatomesh.core.printing.solid.tiny_shells`); unused vertices are dropped. ``meta["removed_shells"]`` lists the
    removed volumes (mm³)."""
    v, f = check_arrays(mesh.vertices, mesh.faces)
    shells = tiny_shells(v, f, min_volume_mm3)
    keep = np.ones(f.shape[0], bool)
    for s in shells:
        keep[s["faces"]] = False
    nv, nf, nn, _ = compact(mesh.vertices, f[keep], mesh.normals)
    meta = dict(mesh.meta)
    meta["removed_shells"] = [round(s["volume_mm3"], 6) for s in shells]
    return Mesh(nv, nf, nn, name=mesh.name, value=mesh.value, color=mesh.color, space=mesh.space,
                meta=meta)
