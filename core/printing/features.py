"""Thin features a printer would mind: sheets, rods and sharp edges, told apart from the rims of
smooth shapes, each with a reason a person understands.

The rule (see :mod:`.reach`): material thinner than the minimum wall ``w`` is a thin feature
when it reaches more than ``tolerance`` (the nozzle, or a resin printer's smallest detail) beyond
the part's body — the union of the balls of diameter ``w`` that fit inside. The rim of a smooth
wedge or a rounded crease reaches less far (a wedge of half-angle α: ``w/2 · (1/sin α − 1)``, a
slicer blunts its tip by about that much), a sheet or a rod reaches as far as it is long.

:func:`thin_features` groups the thin vertices (:func:`.thickness.thin_regions`), measures how
far each reaches (:func:`.reach.reach_beyond_body`) and describes the regions that reach too far:

* ``sheet`` — thin in one direction only: its thickness (area-weighted median) and the area of
  one side ("sheet 0.50 mm thick over 40 mm² at (x, y, z)");
* ``rod`` — thin in every direction across an axis: its diameter and length (area / (π d));
* ``edge`` — a sheet whose thickness tapers (the 10th percentile below half the 90th): a knife
  edge sharper than the tolerance allows.

Sheet and rod are told apart at the regions' inscribed-ball centres (the medial axis): rays
across the inward direction travel far along a sheet in every direction, along a rod only
along its axis.
"""
from __future__ import annotations

from typing import Dict, List, Optional

import numpy as np

from ..geometry.spatial import TriangleGrid
from ..model.mesh import vertex_areas
from .locate import location
from .reach import cone_directions, reach_beyond_body
from .thickness import thin_regions

#: rays across the inward direction at the medial points (rod/sheet test)
_ACROSS_RAYS = 8
#: an across ray is "long" beyond this many times the local thickness
_LONG_RAY = 1.5
#: a region whose long-ray fraction is below this is a rod (a rod has 2 of 8: its axis)
_ROD_FRACTION = 0.5
#: a region whose 10th-percentile thickness is below this fraction of its 90th is an edge
_TAPER = 0.5
#: at most this many vertices of a region are traced (the far fraction of a sample)
_MAX_TRACED = 2000
#: a region fails only when at least this many of its vertices reach too far: one or two alone
#: are a corner or a crease vertex of a coarse mesh (a cone's tip, blunted like a rim)
_MIN_FAR_VERTICES = 3


def vertex_inward(faces: np.ndarray, n_vertices: int, face_inward: np.ndarray,
                  face_area: np.ndarray) -> np.ndarray:
    """Per vertex the area-weighted mean of its faces' unit inward directions (N, 3), unit
    length (zero where no face has one): the bisector at a crease or a wedge's rim."""
    acc = np.zeros((n_vertices, 3))
    w = face_inward * face_area[:, None]
    for k in range(3):
        np.add.at(acc, faces[:, k], w)
    ln = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.where(ln > 0, acc / np.maximum(ln, 1e-300), 0.0)


def thin_features(vertices: np.ndarray, faces: np.ndarray, thickness: np.ndarray, details: Dict,
                  min_wall: float, tolerance: float, grid: Optional[TriangleGrid] = None,
                  min_area_mm2: Optional[float] = None) -> List[Dict]:
    """The thin regions of a closed part, each judged by the rule of the module docstring.

    Parameters
    ----------
    vertices (N, 3) mm, faces (M, 3) int : the part (closed)
    thickness : (N,) mm, from :func:`.thickness.wall_thickness`; ``details`` its details
        (``"inward"``, ``"centre"``, ``"ball"``, ``"inscribed"`` are used)
    min_wall : mm, thinner is thin; ``tolerance`` mm, how far thin material may reach beyond
        the body and still be a rim
    min_area_mm2 : a region fails only when its part reaching too far covers at least this
        much (default ``min_wall²``: one printed line by one printed line) and has at least
        three vertices (one or two alone are a corner of a coarse mesh: the tip of a cone,
        which a slicer blunts like a rim)

    Returns
    -------
    list of dicts, largest area first: ``vertices`` (index array), ``location``, ``area_mm2``,
    ``min_mm``, ``median_mm``, ``min_location`` (as :func:`.thickness.thin_regions`; the two
    sides of a sheet are one region), and ``fails`` (bool), ``reach_area_mm2`` (area reaching
    beyond the tolerance), ``kind`` ("rim" when it passes, else "sheet", "rod" or "edge"),
    ``thickness_mm`` (the sheet's thickness or the rod's diameter), ``extent`` (sheet/edge:
    ``{"sheet_area_mm2"}``, the area of one side; rod: ``{"length_mm"}``; rim: ``{}``) and
    ``reason`` (one line).
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    t = np.asarray(thickness, np.float64)
    thin = np.flatnonzero(np.isfinite(t) & (t < min_wall))
    if thin.size == 0 or f.shape[0] == 0:
        return []
    g = grid if grid is not None else TriangleGrid(v, f)
    area_v = vertex_areas(v, f)
    fa = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    inward = vertex_inward(f, len(v), details["inward"], fa)
    links = _across_links(g, v, f, thin, inward[thin], t)
    regions = thin_regions(v, f, t, min_wall, min_area_mm2=0.0, min_vertices=1, links=links)
    near = _near_body(v, f, details, min_wall, tolerance)
    min_area = float(min_wall) ** 2 if min_area_mm2 is None else float(min_area_mm2)
    far = _far_areas(g, v, inward, area_v, [r["vertices"] for r in regions], near, min_wall, tolerance)
    for r, (far_area, far_count) in zip(regions, far):
        r["reach_area_mm2"] = far_area
        r["fails"] = bool(far_area >= min_area and far_area > 0 and far_count >= _MIN_FAR_VERTICES)
        if r["fails"]:
            _describe(r, g, v, t, inward, area_v, min_wall, tolerance)
        else:
            r.update(kind="rim", thickness_mm=r["median_mm"], extent={},
                     reason=_rim_reason(r, min_wall, tolerance))
    return regions


def _across_links(g: TriangleGrid, v, f, thin, inward, t) -> np.ndarray:
    """(K, 2) pairs (thin vertex, the nearest corner of the face its inward ray hits, within 1.5x
    the thinnest wall): they join the two sides of a sheet into one region."""
    span = max(float(np.ptp(v, axis=0).max()), 1e-3)
    ok = np.linalg.norm(inward, axis=1) > 0
    src, d = thin[ok], inward[ok]
    tt, face, _, _ = g.cast(v[src], d, t_min=1e-6 * span, t_max=float(np.nanmax(t[src])) * 1.5 + 1e-9)
    hit = face >= 0
    src, face, q = src[hit], face[hit], v[src[hit]] + tt[hit, None] * d[hit]
    corners = f[face]
    k = np.argmin(np.linalg.norm(v[corners] - q[:, None], axis=2), axis=1)
    dst = corners[np.arange(len(face)), k]
    keep = dst != src  # thin_regions keeps the links between two thin vertices only
    return np.stack([src[keep], dst[keep]], axis=1)


def _near_body(v, f, details, min_wall: float, tolerance: float) -> np.ndarray:
    """(N,) bool: vertices within ``tolerance`` of an inscribed ball of diameter ≥ ``min_wall``
    (a ball of the body): certainly within the tolerance, no search needed."""
    big = np.flatnonzero(details["inscribed"] & (details["ball"] >= min_wall))
    cover = np.zeros(len(v))
    if big.size:
        used = np.unique(f.ravel())
        pts = TriangleGrid(v, np.repeat(used[:, None], 3, axis=1).astype(np.int32),
                           cell_size=max(2.0 * float(np.mean(np.linalg.norm(v[f[:, 1]] - v[f[:, 0]], axis=1))), 1e-6))
        pts.ball_cover(details["centre"][big], 0.5 * details["ball"][big], float(tolerance),
                       used[pts.items].astype(np.int32), cover)
    return cover > 0


def _far_areas(g, v, inward, area_v, groups, near, min_wall, tolerance) -> List[tuple]:
    """Per group of vertices (a region) the area (mm²) and the number of those farther than
    ``tolerance`` from the body: vertices near a ball of the body count as near; of the others at most
    :data:`_MAX_TRACED` per group (drawn at random) are traced with
    :func:`.reach.reach_beyond_body`, all groups in one call, and their far fraction (by area)
    is applied to the group. Folds of the surface (no inward direction, reach NaN) do not count
    as far."""
    rng = np.random.default_rng(0)
    rests, picks = [], []
    for vi in groups:
        rest = vi[~near[vi]]
        rests.append(rest)
        picks.append(rest if rest.size <= _MAX_TRACED else rng.choice(rest, _MAX_TRACED, replace=False))
    allp = np.concatenate(picks) if picks else np.zeros(0, np.int64)
    reach = reach_beyond_body(g, v[allp], inward[allp], min_wall, tolerance)
    out, start = [], 0
    for rest, pick in zip(rests, picks):
        w = np.maximum(area_v[pick], 1e-12)
        far = reach[start:start + pick.size] > tolerance  # NaN (a fold) compares False
        start += pick.size
        frac = float(np.sum(w * far) / np.sum(w)) if pick.size else 0.0
        out.append((float(area_v[rest].sum()) * frac, int(round(frac * rest.size))))
    return out


def _describe(r: Dict, g: TriangleGrid, v, t, inward, area_v, min_wall: float, tolerance: float):
    """Kind, measures and reason of a failing region ``r`` (in place)."""
    vi = r["vertices"]
    tv = np.where(np.isfinite(t[vi]), t[vi], 0.0)
    order = np.argsort(tv)
    cum = np.cumsum(area_v[vi][order])
    pct = lambda q: float(tv[order][min(np.searchsorted(cum, q * cum[-1]), vi.size - 1)])  # noqa: E731
    thick = max(pct(0.5), 1e-6)
    centres = v[vi] + 0.5 * tv[:, None] * inward[vi]
    long = _long_across(g, centres, inward[vi], np.maximum(tv, 0.05 * min_wall))
    frac = float(np.average(long, weights=np.maximum(area_v[vi], 1e-12)))
    at = _at(r["location"])
    if pct(0.1) < _TAPER * pct(0.9):
        r.update(kind="edge", thickness_mm=round(thick, 3), extent={"sheet_area_mm2": round(r["area_mm2"] / 2, 2)},
                 reason=f"sharp edge tapering to {r['min_mm']:.2f} mm over {r['area_mm2'] / 2:.0f} mm² "
                        f"at {at}, reaching more than {tolerance:g} mm beyond the {min_wall:g} mm wall")
    elif frac < _ROD_FRACTION:
        length = r["area_mm2"] / (np.pi * thick)
        r.update(kind="rod", thickness_mm=round(thick, 3), extent={"length_mm": round(length, 2)},
                 reason=f"rod {thick:.2f} mm across, {length:.0f} mm long at {at} "
                        f"(thinner than the {min_wall:g} mm minimum)")
    else:
        r.update(kind="sheet", thickness_mm=round(thick, 3), extent={"sheet_area_mm2": round(r["area_mm2"] / 2, 2)},
                 reason=f"sheet {thick:.2f} mm thick over {r['area_mm2'] / 2:.0f} mm² at {at} "
                        f"(thinner than the {min_wall:g} mm minimum)")


def _long_across(g: TriangleGrid, centres: np.ndarray, inward: np.ndarray, thick: np.ndarray) -> np.ndarray:
    """Per point the fraction of :data:`_ACROSS_RAYS` rays, perpendicular to ``inward``, that
    travel farther than :data:`_LONG_RAY` × ``thick`` inside the part."""
    dirs = cone_directions(inward, 90.0, rings=1, per_ring=_ACROSS_RAYS)[1:]
    n = np.zeros(len(centres))
    for d in dirs:
        hit, _, _, _ = g.cast(centres, d, t_min=0.0, t_max=float(np.max(thick)) * _LONG_RAY * 2)
        n += hit > _LONG_RAY * thick
    return n / len(dirs)


def _rim_reason(r: Dict, min_wall: float, tolerance: float) -> str:
    return (f"rim down to {r['min_mm']:.2f} mm over {r['area_mm2']:.0f} mm² at {_at(r['location'])}: "
            f"within {tolerance:g} mm of the {min_wall:g} mm body, prints slightly blunted")


def _at(p) -> str:
    return "(" + ", ".join(f"{x:.0f}" for x in p) + ")"
