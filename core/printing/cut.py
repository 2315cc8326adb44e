"""Cut to fit: split a part by planes into closed pieces that each fit a printer's build volume.

* :func:`cut_by_plane` — the part's triangles crossing the plane are split along it
  (:func:`.surgery.split_by_level`, one new vertex per crossing edge, shared by both sides); the
  cut loops are nested by the even-odd rule (outer boundaries and holes,
  :func:`anatomesh.core.geometry.polygons.nest`) and each region is capped by ear clipping
  (:func:`anatomesh.core.geometry.polygons.triangulate`), then flipped to the constrained
  Delaunay triangulation (no slivers: pins can be drilled into it). Both halves use the same cap (one
  facing each way), so they are closed, manifold, consistently oriented, and their volumes add
  up to the part's.
* :func:`plan_cuts` — axis-aligned planes in the part's bounding box: the fewest cuts such that
  every piece fits the build volume in one of its 6 axis orientations (a piece fits when its
  sorted extents fit the sorted volume), placed where the cross-section is smallest among the
  positions that keep every slab short enough (dynamic programming over sampled positions).
* :func:`fit_part` / :func:`fit_to_volume` — plan, cut, optionally pins and pockets across each
  cut face (:func:`.connectors.add_connectors`).

Vertices are mm; planes are given by a point (mm) and a normal.
"""
from __future__ import annotations

import itertools
from typing import Dict, List, Sequence, Tuple

import numpy as np

from ..geometry.polygons import delaunay_flips, nest, signed_area, triangulate
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh, check_arrays, compact, signed_volume, weld_ids
from .connectors import add_connectors, interface_faces
from .fixes import boundary_loops
from .surgery import split_by_level

AXES = "xyz"
#: pieces are planned this much (mm) inside the build volume, so rounding never makes one too big
FIT_MARGIN_MM = 0.01
#: a cut plane keeps this far (mm) from every vertex (moved by as little as needed)
VERTEX_CLEARANCE_MM = 0.01
#: with connectors, pieces are planned this much (mm) smaller: a 5 mm pin stands up to 7.5 mm out
PIN_ALLOWANCE_MM = 8.0
#: cap triangles lower than this (mm) are avoided where ear clipping can (float32 flattens them)
SLIVER_MM = 1e-4
#: cut positions sampled per axis when planning
_SAMPLES = 256


def cut_by_plane(mesh: Mesh, point: Sequence[float], normal: Sequence[float]) -> Tuple[Mesh, Mesh]:
    """``mesh`` (closed) split by the plane through ``point`` (mm) with ``normal``: (below, above),
    the parts on the negative and positive side, each capped with the cut face. A plane closer
    than :data:`VERTEX_CLEARANCE_MM` to a vertex is moved along its normal by as little as keeps it
    that far from all. A side the plane leaves empty is a Mesh with no faces. Raises :class:`AnatomeshError` for an open mesh or a
    cut that touches itself at a vertex."""
    v, f = check_arrays(mesh.vertices, mesh.faces)
    v, f = v.astype(np.float64), f.astype(np.int64)
    n = np.asarray(normal, np.float64)
    if not (n.shape == (3,) and np.linalg.norm(n) > 0):
        raise AnatomeshError(f"cut_by_plane: the normal must be a non-zero 3-vector, got {normal!r}")
    n = n / np.linalg.norm(n)
    if boundary_loops(f, len(v))[0]:
        raise AnatomeshError(f"{mesh.name}: only closed surfaces can be cut into closed pieces; close "
                             "its holes first (anatomesh check --close-holes)")
    v2, f2, above = _split(v, f, np.asarray(point, np.float64), n)
    cap = _cap(v2, f2[~above], n, mesh.name)
    return _piece(v2, np.concatenate([f2[~above], cap]), mesh, first_new=len(v)), \
        _piece(v2, np.concatenate([f2[above], cap[:, ::-1]]), mesh, first_new=len(v))


def _split(v, f, point, n):
    """Split the triangles crossing the plane (moved by :func:`clear_offset` off any vertex);
    returns (vertices, faces, above (M,) bool). Each crossing point is interpolated from the
    edge's lower end, so pieces cut again by the same plane get bit-identical points."""
    phi = (v - point) @ n
    phi = phi - clear_offset(phi)

    def root(i, j):
        lo, hi = np.where(phi[i] < 0, i, j), np.where(phi[i] < 0, j, i)
        t = phi[lo] / (phi[lo] - phi[hi])
        return v[lo] + t[:, None] * (v[hi] - v[lo])

    v2, f2, above, _ = split_by_level(v, f, phi, root)
    return v2, f2, above


def clear_offset(phi: np.ndarray, clear: float = VERTEX_CLEARANCE_MM) -> float:
    """The smallest shift (mm) of a plane along its normal that leaves every vertex at least
    ``clear`` from it, given the vertices' signed distances ``phi`` (N,) to it: 0 when none is
    closer (a vertex on the plane would make degenerate slivers)."""
    for k in range(1000):
        for d in ((0.0,) if k == 0 else (1.5 * k * clear, -1.5 * k * clear)):
            if not np.any(np.abs(phi - d) < clear):
                return d
    raise AnatomeshError("no place for the cut plane clear of the vertices")


def plane_frame(n: np.ndarray) -> np.ndarray:
    """(2, 3): two unit vectors spanning the plane of unit normal ``n``, with e1 × e2 = n."""
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(n, e1)])


def _cap(v: np.ndarray, below: np.ndarray, n: np.ndarray, name: str) -> np.ndarray:
    """Faces (K, 3) closing the cut loops of the lower part ``below``, facing along ``n``."""
    loops, bad = boundary_loops(below, len(v))
    if bad:
        raise AnatomeshError(f"{name}: the cut touches itself at a vertex; move the plane slightly")
    if not loops:
        return np.zeros((0, 3), np.int64)
    a, b = loops[0][0], loops[0][1]  # a boundary half-edge of the part: the cap runs against it
    uv = [v[lp] @ plane_frame(n).T for lp in loops]
    loops = [lp[::-1] if signed_area(p) < 0 else lp for lp, p in zip(loops, uv)]
    uv = [p[::-1] if signed_area(p) < 0 else p for p in uv]
    holes, parents = nest(uv)
    out = []
    for k in range(len(loops)):
        if holes[k]:
            continue
        kids = [h for h in range(len(loops)) if holes[h] and parents[h] == k]
        ids = np.concatenate([loops[k]] + [loops[h] for h in kids])
        out.append(ids[triangulate(uv[k], [uv[h] for h in kids], min_height=SLIVER_MM)])
    cap = np.concatenate(out)
    cap = cap[(cap[:, 0] != cap[:, 1]) & (cap[:, 1] != cap[:, 2]) & (cap[:, 2] != cap[:, 0])]
    cap = delaunay_flips(v @ plane_frame(n).T, cap, SLIVER_MM)
    he = np.concatenate([cap[:, [0, 1]], cap[:, [1, 2]], cap[:, [2, 0]]])
    if np.any((he[:, 0] == a) & (he[:, 1] == b)):
        cap = cap[:, ::-1]
    return cap


def _piece(v: np.ndarray, f: np.ndarray, like: Mesh, name: str = None, first_new: int = None) -> Mesh:
    """The faces ``f`` as a float32 Mesh. New vertices (indices from ``first_new``: crossing
    points, drilled rings) that float32 puts on another vertex (a few µm apart where cut planes
    meet) are merged into it and the faces between them dropped; the part's own vertices are kept
    apart even where they coincide (a pinch)."""
    v32 = np.asarray(v, np.float32)
    ids = np.arange(len(v32))
    if first_new is not None and first_new < len(v32):
        w = weld_ids(v32)
        rep = np.zeros(w.max() + 1, np.int64)
        rep[w[::-1]] = ids[::-1]  # the first vertex at each position
        ids[first_new:] = rep[w[first_new:]]
    f = ids[f]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    vv, ff, _, _ = compact(v32, f)
    return Mesh(vv, ff.astype(np.int32), None, name=name or like.name,
                value=like.value, color=like.color, space=like.space)


# ---------------------------------------------------------------------------------------------
# planning
# ---------------------------------------------------------------------------------------------
def section_areas(mesh: Mesh, axis: int, positions: np.ndarray) -> np.ndarray:
    """Cross-section areas (mm²) of the closed ``mesh`` at the planes ``coordinate[axis] = t``
    for each of ``positions`` (K,): half the summed cross products of the cut segments, each
    taken in its face's winding (Green's theorem), so no loop needs assembling."""
    v, f = check_arrays(mesh.vertices, mesh.faces)
    v = v.astype(np.float64)
    p = v[f]  # (M, 3 corners, 3)
    lo, hi = p[:, :, axis].min(axis=1), p[:, :, axis].max(axis=1)
    u, w = (axis + 1) % 3, (axis + 2) % 3
    out = np.zeros(len(positions))
    for k, t in enumerate(np.asarray(positions, np.float64)):
        q = p[(lo <= t) & (hi >= t)]
        s = q[:, :, axis] - t
        s = np.where(s == 0, 1e-12, s)  # a vertex on the plane counts as above it
        cross = (s < 0).any(axis=1) & (s > 0).any(axis=1)
        q, s = q[cross], s[cross]
        if len(q) == 0:
            continue
        s1, q1 = np.roll(s, -1, axis=1), np.roll(q, -1, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):  # edges not crossing: unused
            x = q + (s / (s - s1))[:, :, None] * (q1 - q)  # crossing point of edge c -> c+1
        rows = np.arange(len(q))
        ex = x[rows, np.argmax((s < 0) & (s1 > 0), axis=1)]
        en = x[rows, np.argmax((s > 0) & (s1 < 0), axis=1)]
        out[k] = -0.5 * np.sum(ex[:, u] * en[:, w] - ex[:, w] * en[:, u])
    return out


def _best_cuts(t: np.ndarray, cost: np.ndarray, lo: float, hi: float, count: int, slab: float):
    """``count`` positions among ``t`` (sorted) with the least summed ``cost`` such that the
    slabs between ``lo``, the cuts and ``hi`` are all at most ``slab`` long; None if impossible."""
    if count == 0:
        return [] if hi - lo <= slab else None
    best = np.where(t - lo <= slab, cost, np.inf)
    back = []
    for _ in range(count - 1):
        reach = (t[None, :] - t[:, None] <= slab) & (t[None, :] > t[:, None])  # [from, to]
        total = np.where(reach, best[:, None], np.inf)
        prev = np.argmin(total, axis=0)
        best = total[prev, np.arange(len(t))] + cost
        back.append(prev)
    best = np.where(hi - t <= slab, best, np.inf)
    j = int(np.argmin(best))
    if not np.isfinite(best[j]):
        return None
    chosen = [j]
    for prev in reversed(back):
        chosen.append(int(prev[chosen[-1]]))
    return [float(t[i]) for i in reversed(chosen)]


def plan_cuts(mesh: Mesh, size: Sequence[float], allowance: float = 0.0) -> List[Tuple[int, float]]:
    """Axis-aligned cuts ``[(axis 0..2, position mm)]`` so that every piece of ``mesh`` fits the
    build volume ``size`` (3,) mm in some axis orientation: the fewest cuts, then the least
    summed cross-section; when cut, pieces are planned ``allowance`` mm shorter (room for pins
    standing out of a cut face). Raises :class:`AnatomeshError` for a bad size."""
    size = np.asarray(size, np.float64)
    if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 2 * FIT_MARGIN_MM):
        raise AnatomeshError(f"the build volume must be three sizes in mm > 0, got {list(np.ravel(size))}")
    v = np.asarray(mesh.vertices, np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = hi - lo
    if np.all(np.sort(ext) <= np.sort(size)):
        return []
    if np.any(size - allowance <= 2 * FIT_MARGIN_MM):
        raise AnatomeshError(f"the build volume {size.tolist()} mm leaves no room for pins of {allowance:g} mm")
    size = size - allowance
    samples, areas = [], []
    for a in range(3):
        t = lo[a] + ext[a] * (np.arange(1, _SAMPLES) / _SAMPLES)
        samples.append(t)
        areas.append(section_areas(mesh, a, t))
    best = None
    for perm in set(itertools.permutations(size.tolist())):
        slab = np.asarray(perm) - FIT_MARGIN_MM
        counts = [max(0, int(np.ceil(ext[a] / slab[a])) - 1) for a in range(3)]
        for extra in range(3):  # sampled positions may need one more cut than the lengths say
            plan = [_best_cuts(samples[a], areas[a], lo[a], hi[a], counts[a] + extra * (counts[a] > 0), slab[a])
                    for a in range(3)]
            if all(p is not None for p in plan):
                break
        if any(p is None for p in plan):
            continue
        cuts = [(a, x) for a in range(3) for x in plan[a]]
        cost = sum(float(np.interp(x, samples[a], areas[a])) for a, x in cuts)
        key = (len(cuts), cost)
        if best is None or key < best[0]:
            best = (key, cuts)
    if best is None:
        raise AnatomeshError(f"{mesh.name} cannot be cut to fit {size.tolist()} mm")
    return best[1]


# ---------------------------------------------------------------------------------------------
# the whole tool
# ---------------------------------------------------------------------------------------------
def cut_along(mesh: Mesh, cuts: Sequence[Tuple[int, float]]) -> Tuple[List[Mesh], List[Tuple[int, float]]]:
    """``mesh`` cut by every axis-aligned plane of ``cuts`` (each piece only by the planes that
    cross it), pieces named ``<part>_1``, ``<part>_2``, ... (the part alone keeps its name).
    Returns (pieces, the cuts as made: each plane moved off the vertices, :func:`clear_offset`)."""
    pieces, made = [mesh], []
    for axis, pos in cuts:
        pos = pos + clear_offset(np.concatenate([np.asarray(p.vertices, np.float64)[:, axis] for p in pieces]) - pos)
        made.append((axis, pos))
        n = np.zeros(3)
        n[axis] = 1.0
        point = np.zeros(3)
        point[axis] = pos
        out = []
        for p in pieces:
            c = np.asarray(p.vertices)[:, axis]
            if c.min() < pos < c.max():
                out += [q for q in cut_by_plane(p, point, n) if len(q.faces)]
            else:
                out.append(p)
        pieces = out
    if len(pieces) == 1:
        return pieces, made
    return [_piece(p.vertices, p.faces, mesh, f"{mesh.name}_{k + 1}") for k, p in enumerate(pieces)], made


def fits(extents: Sequence[float], size: Sequence[float]) -> bool:
    """Whether a box of ``extents`` (3,) mm fits one of ``size`` (3,) mm in some axis orientation."""
    return bool(np.all(np.sort(extents) <= np.sort(size) + 1e-6))


def fit_part(mesh: Mesh, size: Sequence[float], connectors: bool = False, clearance: float = 0.2,
             min_wall: float = 0.8) -> Tuple[List[Mesh], Dict]:
    """``mesh`` cut into pieces that each fit the build volume ``size`` (3,) mm, with pins and
    pockets across each cut face when ``connectors``. Returns (pieces, info ``{"build_volume_mm",
    "volume_mm3", "cuts": [{"axis", "position_mm"}], "pieces": [{"name", "extents_mm",
    "volume_mm3", "fits"}], "connectors": [...]}``)."""
    pieces, cuts = cut_along(mesh, plan_cuts(mesh, size, PIN_ALLOWANCE_MM if connectors else 0.0))
    joints = []
    if connectors and len(pieces) > 1:
        pieces, joints = connect_pieces(pieces, clearance, min_wall)
    rows = []
    for p in pieces:
        e = np.ptp(np.asarray(p.vertices, np.float64), axis=0)
        rows.append({"name": p.name, "extents_mm": [round(float(x), 2) for x in e],
                     "volume_mm3": round(signed_volume(p.vertices, p.faces), 3), "fits": fits(e, size)})
    info = {"build_volume_mm": [float(x) for x in size],
            "volume_mm3": round(signed_volume(mesh.vertices, mesh.faces), 3),
            "cuts": [{"axis": AXES[a], "position_mm": round(x, 3)} for a, x in cuts],
            "pieces": rows}
    if connectors:
        info["connectors"] = joints
    return pieces, info


def fit_to_volume(mesh: Mesh, size_xyz_mm: Sequence[float]) -> List[Mesh]:
    """The pieces of :func:`fit_part` without connectors."""
    return fit_part(mesh, size_xyz_mm)[0]


def connect_pieces(pieces: List[Mesh], clearance: float, min_wall: float) -> Tuple[List[Mesh], List[Dict]]:
    """Pins on the first and pockets in the second piece of every pair sharing a cut face
    (:func:`.connectors.add_connectors`); a face with no room for a pin is listed with a note."""
    pieces = list(pieces)
    joints = []
    for i, j in itertools.combinations(range(len(pieces)), 2):
        if interface_faces(pieces[i], pieces[j]).size == 0:
            continue
        try:
            a, b, info = add_connectors(pieces[i], pieces[j], clearance, min_wall=min_wall)
            pieces[i] = _piece(a.vertices, a.faces, a, first_new=len(pieces[i].vertices))
            pieces[j] = _piece(b.vertices, b.faces, b, first_new=len(pieces[j].vertices))
        except AnatomeshError as exc:
            info = {"pair": [pieces[i].name, pieces[j].name], "pins": [], "note": str(exc)}
        joints.append(info)
    return pieces, joints
