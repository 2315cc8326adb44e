"""Thin features a printer would mind: sheets, rods and knife edges, told apart from the rims of
smooth shapes that a printer builds slightly blunted, each with a reason a person understands.

Material thinner than the minimum wall ``w`` is judged by how far it reaches beyond the part's
*body* — the union of the balls of diameter ``w`` that fit inside (:mod:`.reach`) — and by the
angle θ at which its two sides meet (the angle between the inward normal at a point and the
outward normal where that ray leaves the other side: 0 for a sheet or a rod, the full opening
angle on a wedge). ``e`` is the printer's line (the profile's ``min_feature``: the nozzle, a
resin printer's smallest detail) and ``tol`` how much of a shape it may lose (the same).

**How far a printer cuts a rim back.** A slicer lays the outermost line of a layer with its
centre ``e/2`` inside the outline (the outline offset inward by half the line width). In a
wedge of full angle θ the two offset sides meet on the bisector at the point ``e/2`` from both
sides, ``(e/2)/sin(θ/2)`` from the tip; the line's round end reaches ``e/2`` beyond it. The
printed tip lies ``b = (e/2)·(1/sin(θ/2) − 1)`` behind the true one: the material outside the
part's opening by a ball of diameter ``e`` (Serra 1982, "Image Analysis and Mathematical
Morphology"), measured here as the reach beyond that body (:func:`.reach.reach_beyond_body` at
wall ``e``). For e = 0.4 mm: 0.08 mm at 90°, 0.20 mm at 60°, 0.30 mm at 47°, 0.57 mm at 30°.

**The rule** (:func:`thin_features`), per region of material thinner than ``w``:

* it reaches no farther than ``tol`` beyond the body: a *rim*, passes (a printer blunts it by
  at most ``tol·e/w``, the self-similar wedge scaled to the line);
* it tapers at θ ≥ θmin = 2·asin(e / (e + 2·tol)) (38.9° when tol = e: the angle at which the
  cut-back ``b`` of a straight wedge is ``tol``), the printer cuts it back by at most ``tol``
  (measured ``b``), and it reaches no farther beyond the body than a straight wedge at θmin,
  ``w·tol/e`` (0.8 mm for fdm: the thin band belongs to a full-thickness body): a *tapering
  rim*, passes with a warning stating ``b`` and where ("rim tapering to 47° at (x, y, z): a
  printer blunts it by about 0.30 mm");
* otherwise it fails: ``edge`` (a knife edge: it tapers, thickness from the 10th percentile
  below half the 90th, or at θ ≥ θmin, but sharper, cut back more, or reaching too far),
  ``sheet`` (thin in one direction: thickness, area of one side) or ``rod`` (thin across an
  axis: diameter, length = area / (π d)).

Sheet and rod are told apart at the regions' inscribed-ball centres (the medial axis): rays
across the inward direction travel far along a sheet in every direction, along a rod only
along its axis.
"""
from __future__ import annotations

from typing import Dict, List, Optional

import numpy as np

from ..geometry.spatial import TriangleGrid
from ..model.mesh import vertex_areas
from .locate import location, location_text
from .reach import cone_directions, reach_beyond_body, reach_by_balls
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
#: are a corner or a crease vertex of a coarse mesh (a cone's tip, blunted like a rim); the
#: cut-back of a tapering rim is likewise the this-many-th largest of its tip's
_MIN_FAR_VERTICES = 3
#: a region's taper angle is measured on its faces whose inward ray leaves the other side within
#: this many minimum walls
_ANGLE_RAY = 1.5
#: the cut-back of a tapering rim is measured at this many of its thinnest vertices at most
_TIP_VERTICES = 400


def taper_limits(min_wall: float, tolerance: float, line_width: Optional[float] = None):
    """The limits of a printable tapering rim (module docstring): (θmin degrees, the angle at which
    a straight wedge is cut back by ``tolerance``; the farthest such a rim reaches beyond the body
    at wall ``min_wall``, ``min_wall·tolerance/line_width`` mm). ``line_width`` defaults to
    ``tolerance``; all in mm."""
    e = float(tolerance if line_width is None else line_width)
    return 2.0 * np.degrees(np.arcsin(e / (e + 2.0 * tolerance))), float(min_wall) * tolerance / e


def wedge_cut_back(angle_deg, line_width: float):
    """How far, mm, a printer laying lines ``line_width`` mm wide cuts back the tip of a straight
    wedge of full angle ``angle_deg``: ``(e/2)·(1/sin(θ/2) − 1)`` (derivation in the module
    docstring)."""
    return 0.5 * line_width * (1.0 / np.sin(np.radians(np.asarray(angle_deg, np.float64)) / 2.0) - 1.0)


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
                  min_area_mm2: Optional[float] = None, line_width: Optional[float] = None) -> List[Dict]:
    """The thin regions of a closed part, each judged by the rule of the module docstring.

    Parameters
    ----------
    vertices (N, 3) mm, faces (M, 3) int : the part (closed)
    thickness : (N,) mm, from :func:`.thickness.wall_thickness`; ``details`` its details
        (``"inward"``, ``"centre"``, ``"ball"``, ``"inscribed"`` are used)
    min_wall : mm, thinner is thin; ``tolerance`` mm, how far thin material may reach beyond
        the body and still be a rim, and how much a printer may cut off a tapering rim
    min_area_mm2 : a region fails only when its part reaching too far covers at least this
        much (default ``min_wall²``: one printed line by one printed line) and has at least
        three vertices (one or two alone are a corner of a coarse mesh: the tip of a cone,
        which a slicer blunts like a rim)
    line_width : mm, the printer's line (default ``tolerance``)

    Returns
    -------
    list of dicts, largest area first: ``vertices`` (index array), ``location``, ``area_mm2``,
    ``min_mm``, ``median_mm``, ``min_location`` (as :func:`.thickness.thin_regions`; the two
    sides of a sheet are one region), and ``fails`` (bool), ``reach_area_mm2`` (area reaching
    beyond the tolerance), ``kind`` ("rim" when it passes, else "sheet", "rod" or "edge"),
    ``thickness_mm`` (the sheet's thickness or the rod's diameter), ``extent`` (sheet/edge:
    ``{"sheet_area_mm2"}``, the area of one side; rod: ``{"length_mm"}``; rim: ``{}``),
    ``reason`` (one line) and, for regions reaching beyond the tolerance, ``angle_deg`` (θ),
    ``cut_back_mm`` (``b``, inf when beyond ``min_wall``) and ``cut_back_location``; a tapering
    rim has ``warning`` (one line).
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
    e = float(tolerance if line_width is None else line_width)
    angle_min, cap = taper_limits(min_wall, tolerance, e)
    balls = _balls(details)
    far = _far_areas(g, v, inward, area_v, [r["vertices"] for r in regions], near, balls, min_wall,
                     tolerance, cap)
    for r, (far_area, far_count, over_area, over_count) in zip(regions, far):
        r["reach_area_mm2"] = far_area
        if not (far_area >= min_area and far_area > 0 and far_count >= _MIN_FAR_VERTICES):
            r.update(fails=False, kind="rim", thickness_mm=r["median_mm"], extent={},
                     reason=_rim_reason(r, min_wall, tolerance))
            continue
        r.update(_taper(g, v, f, t, details, balls, inward, r["vertices"], min_wall, e))
        over = over_area >= min_area and over_count >= _MIN_FAR_VERTICES
        r["fails"] = bool(over or r["angle_deg"] < angle_min or not r["cut_back_mm"] <= tolerance)
        if r["fails"]:
            _describe(r, g, v, t, inward, area_v, min_wall, tolerance, angle_min, cap)
        else:
            r.update(kind="rim", thickness_mm=r["median_mm"], extent={},
                     reason=_rim_reason(r, min_wall, tolerance),
                     warning=f"rim tapering to {r['angle_deg']:.0f}° at {location_text(r['cut_back_location'])}: "
                             f"a printer blunts it by about {r['cut_back_mm']:.2f} mm")
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


def _balls(details: Dict):
    """The valid inscribed balls of the thickness details: (centres (B, 3) mm, radii (B,) mm)."""
    ok = details["inscribed"]
    return details["centre"][ok], 0.5 * details["ball"][ok]


def _far_areas(g, v, inward, area_v, groups, near, balls, min_wall, tolerance, cap) -> List[tuple]:
    """Per group of vertices (a region): the area (mm²) and the number of those farther than
    ``tolerance`` from the body, and the same for those farther than ``cap`` (≥ tolerance).
    Vertices near a ball of the body count as near; of the others at most :data:`_MAX_TRACED`
    per group (drawn at random) are traced with :func:`.reach.reach_beyond_body`, all groups in
    one call, and their far fractions (by area) are applied to the group; beyond ``cap`` counts
    what is that far both by the rays and from the inscribed ``balls`` (:func:`.reach.reach_by_balls`:
    two upper bounds of the distance). Folds of the surface (no inward direction, reach NaN) do
    not count as far."""
    rng = np.random.default_rng(0)
    rests, picks = [], []
    for vi in groups:
        rest = vi[~near[vi]]
        rests.append(rest)
        picks.append(rest if rest.size <= _MAX_TRACED else rng.choice(rest, _MAX_TRACED, replace=False))
    allp = np.concatenate(picks) if picks else np.zeros(0, np.int64)
    far = reach_beyond_body(g, v[allp], inward[allp], min_wall, tolerance) > tolerance  # NaN: False
    over = far.copy()
    if cap > tolerance and np.any(far):
        q = allp[far]
        over[far] = ((reach_beyond_body(g, v[q], inward[q], min_wall, cap) > cap)
                     & (reach_by_balls(v[q], *balls, min_wall, cap) > cap))
    out, start = [], 0
    for rest, pick in zip(rests, picks):
        w = np.maximum(area_v[pick], 1e-12)
        row = []
        for flag in (far[start:start + pick.size], over[start:start + pick.size]):
            frac = float(np.sum(w * flag) / np.sum(w)) if pick.size else 0.0
            row += [float(area_v[rest].sum()) * frac, int(round(frac * rest.size))]
        start += pick.size
        out.append(tuple(row))
    return out


def _taper(g: TriangleGrid, v, f, t, details: Dict, balls, inward, vi: np.ndarray, min_wall: float,
           line_width: float) -> Dict:
    """How a region (vertex indices ``vi``) tapers at its tip, its thinnest vertices (up to
    :data:`_TIP_VERTICES`): ``angle_deg`` θ, the area-weighted median over the faces around
    the thinnest quarter of them of the angle between a face's inward normal and the outward normal where its inward
    ray leaves the other side (within :data:`_ANGLE_RAY` walls; 0 on a sheet or a rod);
    ``cut_back_mm``, how far a printer laying ``line_width`` lines cuts it back: their distance
    to the body at wall ``line_width`` (the smaller of two upper bounds, by the rays of
    :func:`.reach.reach_beyond_body` and from the inscribed ``balls``,
    :func:`.reach.reach_by_balls`), the :data:`_MIN_FAR_VERTICES`-th largest (inf beyond
    ``min_wall``); and ``cut_back_location``, where that is (mm)."""
    tips = vi[np.argsort(t[vi], kind="stable")[:_TIP_VERTICES]]
    at_tip = np.zeros(len(v), bool)
    at_tip[tips[:max(tips.size // 4, _MIN_FAR_VERTICES)]] = True
    fi = np.flatnonzero(at_tip[f].any(axis=1) & (np.linalg.norm(details["inward"], axis=1) > 0))
    angle = 0.0
    if fi.size:
        d = details["inward"][fi]
        span = max(float(np.ptp(v, axis=0).max()), 1e-3)
        _, hit, _, _ = g.cast(v[f[fi]].mean(axis=1), d, t_min=1e-6 * span, t_max=_ANGLE_RAY * min_wall)
        ok = hit >= 0
        if np.any(ok):
            cos = -np.einsum("ij,ij->i", d[ok], details["inward"][hit[ok]])
            ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
            p = v[f[fi[ok]]]
            area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
            order = np.argsort(ang)
            cum = np.cumsum(area[order])
            angle = float(ang[order][min(np.searchsorted(cum, 0.5 * cum[-1]), ok.sum() - 1)])
    cut = np.fmin(reach_beyond_body(g, v[tips], inward[tips], line_width, min_wall),
                  reach_by_balls(v[tips], *balls, line_width, min_wall))  # a fold (NaN): the balls
    k = np.argsort(-cut, kind="stable")[min(_MIN_FAR_VERTICES, tips.size) - 1]
    return {"angle_deg": round(angle, 1), "cut_back_mm": float(cut[k]),
            "cut_back_location": location(v[tips[k]])}


def _describe(r: Dict, g: TriangleGrid, v, t, inward, area_v, min_wall: float, tolerance: float,
              angle_min: float, cap: float):
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
    at = location_text(r["location"])
    if pct(0.1) < _TAPER * pct(0.9) or r["angle_deg"] >= angle_min:
        r.update(kind="edge", thickness_mm=round(thick, 3), extent={"sheet_area_mm2": round(r["area_mm2"] / 2, 2)},
                 reason=f"sharp edge tapering at {r['angle_deg']:.0f}° to {r['min_mm']:.2f} mm over "
                        f"{r['area_mm2'] / 2:.0f} mm² at {location_text(r['cut_back_location'])}: "
                        + _edge_clause(r, min_wall, tolerance, angle_min, cap))
    elif frac < _ROD_FRACTION:
        length = r["area_mm2"] / (np.pi * thick)
        r.update(kind="rod", thickness_mm=round(thick, 3), extent={"length_mm": round(length, 2)},
                 reason=f"rod {thick:.2f} mm across, {length:.0f} mm long at {at} "
                        f"(thinner than the {min_wall:g} mm minimum)")
    else:
        r.update(kind="sheet", thickness_mm=round(thick, 3), extent={"sheet_area_mm2": round(r["area_mm2"] / 2, 2)},
                 reason=f"sheet {thick:.2f} mm thick over {r['area_mm2'] / 2:.0f} mm² at {at} "
                        f"(thinner than the {min_wall:g} mm minimum)")


def _edge_clause(r: Dict, min_wall: float, tolerance: float, angle_min: float, cap: float) -> str:
    """Why a tapering region is no printable rim (the first rule it breaks), for its reason."""
    b = r["cut_back_mm"]
    if not b <= tolerance:
        cut = f"about {b:.2f} mm" if np.isfinite(b) else f"more than {min_wall:g} mm"
        return f"a printer cuts {cut} off it, more than its {tolerance:g} mm detail"
    if r["angle_deg"] < angle_min:
        return (f"thinner than the {min_wall:g} mm wall over a band sharper than the {angle_min:.0f}° "
                f"a printer blunts by at most {tolerance:g} mm")
    return f"reaching more than {cap:g} mm beyond the {min_wall:g} mm wall, farther than a printable rim"


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
    if "cut_back_mm" in r:
        return (f"rim down to {r['min_mm']:.2f} mm over {r['area_mm2']:.0f} mm² at {location_text(r['location'])}: "
                f"tapering at {r['angle_deg']:.0f}°, a printer blunts it by about {r['cut_back_mm']:.2f} mm")
    return (f"rim down to {r['min_mm']:.2f} mm over {r['area_mm2']:.0f} mm² at {location_text(r['location'])}: "
            f"within {tolerance:g} mm of the {min_wall:g} mm body, prints slightly blunted")

