"""Numba kernels for :mod:`anatomesh.core.geometry.pinches` (private): moving the fans of a
surface set's pinch points apart without making faces cross.

Vocabulary (see the public module): a *slot* is one side of one corner of a *pinch face* (a face
with a corner at a pinch vertex), ``slot = 6 p + 2 k + s`` for pinch face ``p``, corner ``k``,
side ``s``; ``cur`` (P, 3, 2, 3) holds every slot's current position, so each pinch face can be
drawn as each of its two sides' shells show it. An *instance* is one fan of one label at one
pinch vertex (label, vertex, copy); a *group* is a set of instances tied by the faces they
share. ``fans`` is the tuple ``(inst_slots, s_off, g_members, g_off)``: each instance's slots
and each group's instances (CSR). ``near`` is the tuple ``(pos, cand, cand_pinch, cell_keys,
cell_off, grid, real, cand_box)``: the set positions; the candidate faces ``cand`` (Q, 3) int64
(a face once for every cell near a pinch vertex that its bounding box meets), sorted by cell,
and their pinch face number or -1; the cells that hold candidates, by key, ascending
(:func:`cell_key`), with their candidates' offsets (C + 1,); ``grid`` (5,) float64 the cells' origin (3), size
and the key's base; which sides (P, 2) of the pinch faces are a shell's (not the
background's); and the candidate faces' bounding boxes (Q, 6) (:func:`face_boxes`), read in
order, so a candidate's corners are fetched only when its box meets a fan's. A cell is at least
the longest edge of a pinch face plus twice the gap, so a fan, moved or not, lies in the 27
cells around its vertex's.
"""
import numpy as np
from numba import njit

from ._face_pair_kernels import tri_tri

#: directions tried per move: two computed ones, then the 26 from a cube cell to its neighbours
_TRIES = 2 + 26


@njit(cache=True)
def move_fans(corners, fans, inst_copy, separable, v_off, v_groups, near, gap, rel_eps):
    """Move every fan that must move ``gap`` mm; returns ``(disp (I, 3) float64, crossing)``.

    ``corners`` (P, 3) int64 the pinch faces' vertices, their normal pointing from side 0 to
    side 1; ``inst_copy`` (I,) each instance's copy number; ``separable`` (G,) bool;
    ``v_off``/``v_groups`` the groups at each pinch vertex (CSR); ``fans``, ``near``: see the
    module docstring.

    At each vertex one separable group (at most one fan per label) stays: the one with most
    shared vertices (copy 0), unless a group there is not separable. Every other separable group
    moves as one, so the faces its fans share keep one position for both sides: along its unit
    umbrella vector minus the
    other groups' at its vertex (Taubin 1995, "A signal processing approach to fair surface
    design": the umbrella points into a fan's cone), then its own, then the 26 directions, the
    first after which none of its faces crosses a face nearby. In a group that is not separable
    (fans of one label tied through another label, as in a checkerboard of two labels around an
    edge), each copy moves alone into its own label's material (minus the angle-weighted normal
    of its faces, Thürmer & Wüthrich 1998), leaving gaps, not overlaps, between labels.
    ``crossing`` counts moves for which every direction crossed a face (the first is kept).
    """
    pos = near[0]
    cur = np.empty((corners.shape[0], 3, 2, 3))
    for p in range(corners.shape[0]):
        for k in range(3):
            for s in range(2):
                cur[p, k, s] = pos[corners[p, k]]
    umb, inward = _fan_vectors(cur, fans)
    disp = np.zeros((inst_copy.shape[0], 3))
    crossing = 0
    for v in range(v_off.shape[0] - 1):
        here = _ordered(v_groups[v_off[v]:v_off[v + 1]], fans, inst_copy, umb)
        anchor = _anchor(here, separable)
        for g in here:
            if not separable[g]:
                crossing += _move_copies(cur, g, fans, inst_copy, inward, umb, here, near, disp,
                                         gap, rel_eps)
            elif g != anchor:
                crossing += _move_group(cur, g, fans, umb, here, near, disp, gap, rel_eps)
    return disp, crossing


@njit(cache=True)
def _anchor(here, separable):
    """The group that stays at a pinch vertex: none when a group there is not separable (its
    shared fans stay), else the first of ``here`` (:func:`_ordered`)."""
    for g in here:
        if not separable[g]:
            return -1
    return here[0]


@njit(cache=True)
def _ordered(groups, fans, inst_copy, umb):
    """The groups at a vertex in an order that does not depend on how labels are numbered:
    most fans that are no copy first, then most fans, then by their umbrella vectors' sum."""
    g_members, g_off = fans[2], fans[3]
    n = groups.shape[0]
    key = np.empty((n, 5))
    for a in range(n):
        g = groups[a]
        key[a, 2:] = 0.0
        key[a, 0] = key[a, 1] = 0.0
        for b in range(g_off[g], g_off[g + 1]):
            i = g_members[b]
            key[a, 0] -= inst_copy[i] == 0
            key[a, 1] -= 1.0
            key[a, 2:] += umb[i]
    out = groups.copy()
    for a in range(1, n):  # insertion sort: a few groups per vertex
        b = a
        while b > 0 and _before(key[b], key[b - 1]):
            key[b], key[b - 1] = key[b - 1].copy(), key[b].copy()
            out[b], out[b - 1] = out[b - 1], out[b]
            b -= 1
    return out


@njit(cache=True)
def _before(a, b):
    for j in range(a.shape[0]):
        if a[j] != b[j]:
            return a[j] < b[j]
    return False


@njit(cache=True)
def _fan_vectors(cur, fans):
    """Per instance (I, 3): the unit umbrella vector and the unit inward angle-weighted normal."""
    inst_slots, s_off = fans[0], fans[1]
    n = s_off.shape[0] - 1
    umb = np.zeros((n, 3))
    inward = np.zeros((n, 3))
    for i in range(n):
        for a in range(s_off[i], s_off[i + 1]):
            p, k, s = _unslot(inst_slots[a])
            e1 = cur[p, (k + 1) % 3, s] - cur[p, k, s]
            e2 = cur[p, (k + 2) % 3, s] - cur[p, k, s]
            umb[i] += 0.5 * (e1 + e2)
            sign = 1.0 if s == 0 else -1.0  # outward for the instance's label
            nrm = np.array([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0]]) * sign
            sin = np.sqrt(nrm @ nrm)
            if sin > 0.0:
                inward[i] -= nrm * (np.arctan2(sin, e1 @ e2) / sin)
        umb[i] = _unit(umb[i])
        inward[i] = _unit(inward[i])
    return umb, inward


@njit(cache=True)
def _move_group(cur, g, fans, umb, here, near, disp, gap, rel_eps):
    """Move separable group ``g`` as one; returns 1 if it had to cross."""
    g_members, g_off = fans[2], fans[3]
    mine = g_members[g_off[g]:g_off[g + 1]]
    own = np.zeros(3)
    for i in mine:
        own += umb[i]
    others = np.zeros(3)
    for h in here:
        if h != g:
            for a in range(g_off[h], g_off[h + 1]):
                others += umb[g_members[a]]
    return _place(cur, mine, _unit(own) - _unit(others), own, fans, near, disp, gap, rel_eps)


@njit(cache=True)
def _move_copies(cur, g, fans, inst_copy, inward, umb, here, near, disp, gap, rel_eps):
    """Move each copy of a group that is not separable alone, into its label's material;
    returns how many had to cross."""
    g_members, g_off = fans[2], fans[3]
    crossing = 0
    for a in range(g_off[g], g_off[g + 1]):
        i = g_members[a]
        if inst_copy[i] > 0:
            crossing += _place(cur, g_members[a:a + 1], inward[i], umb[i], fans, near, disp, gap,
                               rel_eps)
    return crossing


@njit(cache=True)
def _place(cur, mine, first, second, fans, near, disp, gap, rel_eps):
    """Move the slots of instances ``mine`` (all at one point) ``gap`` along the first clear try
    (``first``, ``second``, then the 26 directions); returns 1 if none was clear."""
    inst_slots, s_off = fans[0], fans[1]
    p0, k0, s0 = _unslot(inst_slots[s_off[mine[0]]])
    start = cur[p0, k0, s0].copy()
    chosen = np.zeros(3)
    have = False
    for t in range(_TRIES):
        d = _unit(_try(t, first, second))
        if d @ d == 0.0:
            continue
        if not have:
            chosen[:] = d
            have = True
        _set_slots(cur, mine, fans, _as_float32(start + gap * d))
        if _clear(cur, mine, fans, near, rel_eps):
            _record(mine, disp, cur, fans, start)
            return 0
    _set_slots(cur, mine, fans, _as_float32(start + gap * chosen))
    _record(mine, disp, cur, fans, start)
    return 1


@njit(cache=True)
def _try(t, first, second):
    """Direction ``t``: ``first``, ``second``, then (i, j, k) in {-1, 0, 1}³ other than 0."""
    if t == 0:
        return first.copy()
    if t == 1:
        return second.copy()
    m = t - 2 if t - 2 < 13 else t - 1
    return np.array([m // 9 - 1.0, (m // 3) % 3 - 1.0, m % 3 - 1.0])


@njit(cache=True)
def _clear(cur, mine, fans, near, rel_eps):
    """No face of ``mine`` crosses a candidate face in the cells around its point: pinch faces
    as their shells' sides show them, the others at the set positions (faces with a corner at
    the same position are not tested: they touch there)."""
    inst_slots, s_off = fans[0], fans[1]
    pos, cand, cand_pinch, cell_keys, cell_off, grid, real, cand_box = near
    box = _fan_box(cur, mine, fans)
    lo = cell_of(box[0, 0], box[0, 1], box[0, 2], grid)
    hi = cell_of(box[1, 0], box[1, 1], box[1, 2], grid)
    other = np.empty((3, 3))
    scratch = np.empty((6, 3))
    for i in range(lo[0], hi[0] + 1):
        for j in range(lo[1], hi[1] + 1):
            for k in range(lo[2], hi[2] + 1):
                key = cell_key(i, j, k, grid)
                c = np.searchsorted(cell_keys, key)
                if c == cell_keys.shape[0] or cell_keys[c] != key:
                    continue
                for q in range(cell_off[c], cell_off[c + 1]):
                    r = cand_pinch[q]
                    if r >= 0:
                        for t in range(2):
                            if real[r, t] and _box_meets(cur[r, :, t], box) and \
                                    not _apart(cur, mine, fans, cur[r, :, t], r, rel_eps, scratch):
                                return False
                        continue
                    if not _stored_box_meets(cand_box, q, box):  # no positions read (memory)
                        continue
                    for e in range(3):
                        other[e] = pos[cand[q, e]]
                    if not _apart(cur, mine, fans, other, -1, rel_eps, scratch):
                        return False
    return True


@njit(cache=True)
def _apart(cur, mine, fans, tri, face, rel_eps, scratch):
    """No face of ``mine`` (but pinch face ``face`` itself) crosses ``tri`` (3, 3); ``scratch``
    (6, 3) float64 is work space."""
    inst_slots, s_off = fans[0], fans[1]
    for i in mine:
        for b in range(s_off[i], s_off[i + 1]):
            p, _, s = _unslot(inst_slots[b])
            if p != face and _boxes_meet(cur[p, :, s], tri) and _crosses(cur[p, :, s], tri, rel_eps, scratch):
                return False
    return True


@njit(cache=True)
def _boxes_meet(a, b):
    """Do the bounding boxes of triangles ``a`` and ``b`` (3, 3) meet?"""
    for j in range(3):
        if max(a[0, j], a[1, j], a[2, j]) < min(b[0, j], b[1, j], b[2, j]) or \
                min(a[0, j], a[1, j], a[2, j]) > max(b[0, j], b[1, j], b[2, j]):
            return False
    return True


@njit(cache=True)
def _fan_box(cur, mine, fans):
    """The bounding box (2, 3) of the faces of ``mine``."""
    inst_slots, s_off = fans[0], fans[1]
    box = np.empty((2, 3))
    box[0] = np.inf
    box[1] = -np.inf
    for i in mine:
        for b in range(s_off[i], s_off[i + 1]):
            p, _, s = _unslot(inst_slots[b])
            for c in range(3):
                for j in range(3):
                    box[0, j] = min(box[0, j], cur[p, c, s, j])
                    box[1, j] = max(box[1, j], cur[p, c, s, j])
    return box


@njit(cache=True)
def _box_meets(tri, box):
    """Does triangle ``tri`` (3, 3) reach into ``box`` (2, 3) (closed)?"""
    for j in range(3):
        if max(tri[0, j], tri[1, j], tri[2, j]) < box[0, j] or \
                min(tri[0, j], tri[1, j], tri[2, j]) > box[1, j]:
            return False
    return True


@njit(cache=True, inline="always")
def _stored_box_meets(boxes, q, box):
    """Does the bounding box ``boxes[q]`` (lo (3), hi (3)) meet ``box`` (2, 3) (closed)?"""
    for j in range(3):
        if boxes[q, 3 + j] < box[0, j] or boxes[q, j] > box[1, j]:
            return False
    return True


@njit(cache=True)
def face_boxes(pos, faces, out):
    """The bounding box of every face (M, 3) into ``out`` (M, 6): lo (3) then hi (3)."""
    for f in range(faces.shape[0]):
        for j in range(3):
            a, b, c = pos[faces[f, 0], j], pos[faces[f, 1], j], pos[faces[f, 2], j]
            out[f, j] = min(a, b, c)
            out[f, 3 + j] = max(a, b, c)


@njit(cache=True)
def cell_of(x, y, z, grid):
    """The integer cell ``(i, j, k)`` of the point (x, y, z) mm in ``grid`` (origin (3), size,
    base)."""
    return (np.int64(np.floor((x - grid[0]) / grid[3])), np.int64(np.floor((y - grid[1]) / grid[3])),
            np.int64(np.floor((z - grid[2]) / grid[3])))


@njit(cache=True)
def cell_key(i, j, k, grid):
    """One int64 per cell: cells are 1 .. base - 2 on every axis (0 and base - 1 pad)."""
    base = np.int64(grid[4])
    return ((i + 1) * base + (j + 1)) * base + (k + 1)


@njit(cache=True)
def candidate_cells(pos, faces, grid, near, out_face, out_key):
    """Every (face, cell) pair of a face and a cell near a pinch vertex (``near`` (base³,) bool
    by :func:`cell_key`) that the face's bounding box meets, into ``out_face``/``out_key``
    (int64; empty: count only); returns how many pairs there are."""
    n = 0
    for f in range(faces.shape[0]):
        a, b, c = pos[faces[f, 0]], pos[faces[f, 1]], pos[faces[f, 2]]
        lo = cell_of(min(a[0], b[0], c[0]), min(a[1], b[1], c[1]), min(a[2], b[2], c[2]), grid)
        hi = cell_of(max(a[0], b[0], c[0]), max(a[1], b[1], c[1]), max(a[2], b[2], c[2]), grid)
        for x in range(lo[0], hi[0] + 1):
            for y in range(lo[1], hi[1] + 1):
                for z in range(lo[2], hi[2] + 1):
                    key = cell_key(x, y, z, grid)
                    if near[key]:
                        if out_face.shape[0]:
                            out_face[n] = f
                            out_key[n] = key
                        n += 1
    return n


@njit(cache=True)
def _crosses(a, b, rel_eps, scratch):
    """Do triangles ``a`` and ``b`` ((3, 3) corners) cross, sharing no corner position? Möller's
    test on scalars (:func:`._face_pair_kernels.tri_tri`, the arithmetic of
    ``kernels.tri_tri_intersect``) over the corners copied into ``scratch`` (6, 3)."""
    for i in range(3):
        for j in range(3):
            if a[i, 0] == b[j, 0] and a[i, 1] == b[j, 1] and a[i, 2] == b[j, 2]:
                return False
    scratch[:3] = a
    scratch[3:] = b
    return tri_tri(scratch, 0, 1, 2, 3, 4, 5, rel_eps)


@njit(cache=True)
def _set_slots(cur, mine, fans, at):
    inst_slots, s_off = fans[0], fans[1]
    for i in mine:
        for b in range(s_off[i], s_off[i + 1]):
            p, k, s = _unslot(inst_slots[b])
            cur[p, k, s] = at


@njit(cache=True)
def _record(mine, disp, cur, fans, start):
    inst_slots, s_off = fans[0], fans[1]
    for i in mine:
        p, k, s = _unslot(inst_slots[s_off[i]])
        disp[i] = cur[p, k, s] - start


@njit(cache=True)
def _unslot(slot):
    """``(pinch face, corner, side)`` of a slot ``6 p + 2 k + s``."""
    return slot // 6, (slot % 6) // 2, slot % 2


@njit(cache=True)
def _unit(d):
    length = np.sqrt(d @ d)
    return d / length if length > 0.0 else d * 0.0


@njit(cache=True)
def _as_float32(p):
    """The float32 position (as files store it) of ``p``, as float64."""
    return p.astype(np.float32).astype(np.float64)
