"""Decimation with an error bound in mm that keeps shells closed and seams shared.

Quadric error metric edge collapse (Garland & Heckbert 1997, "Surface simplification using
quadric error metrics", SIGGRAPH): every vertex carries the sum of the squared distances to the
planes of its original faces; an edge (a, b) collapses to the point minimising the summed quadric
(3x3 solve, or the best point of the segment ab when the system is ill conditioned). Edges are
collapsed in sweeps over the faces with a rising cost threshold (a quantile of the current edge
costs), each vertex at most once per sweep — multiple-choice / independent-set style decimation
(Wu & Kobbelt 2002, "Fast mesh decimation by multiple-choice techniques"), which is nearly
cheapest-first but cache friendly and deterministic (numba, arrays only: vertex → face lists with
lazy deletion, no half-edges). Flat regions cost nothing and reduce strongly, curved ones mildly.

A collapse is refused when it would

* change topology: the link condition (Dey, Edelsbrunner, Guha & Nekhayev 1999, "Topology
  preserving edge contraction") — ``link(a) ∩ link(b) == link(ab)`` — checked on the shell of
  *every label* around the edge, plus no shell fan may drop below 3 faces (no tetrahedron
  collapse). Components and genus of each shell therefore stay as they were;
* move a junction vertex (faces of 3+ labels meet there) off its junction curve: such vertices
  collapse only along junction edges, to a point of the segment, and free vertices may slide into
  them; constraint planes through every junction (and open-boundary) edge, perpendicular to its
  faces, keep the curves in place (the classic boundary quadrics);
* flip a face normal by more than ``max_normal_angle``, create a degenerate face, or a sliver
  whose quality ``2√3·|n| / Σl²`` (1 = equilateral) is below ``min_quality`` and below its
  quality before. When the optimal point fails only these geometric tests, the two endpoints
  are tried (subset placement) at their own, higher cost, if the sweep's threshold allows it:
  fewer refused edges, so fewer retries and a cheaper collapse order.

Each interior edge of a single surface is stored and tried once (in the face where it runs
from the lower to the higher vertex index), and a face's 3 edge costs, unit normal and quality
share one 64-byte row: the collapse loop touches one cache line per face.

Interface faces are stored once (a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`), so every
interface is decimated once for both labels and seams stay bit-identical. Vertices where a
label's shell is not a closed manifold fan (pinch points, ``splits``) and caller-``locked``
vertices never move.

Error in mm: the running estimate of a merged vertex is ``sqrt(cost / n)``, its quadric cost
(the summed squared distances to the planes of every input face merged into it) per input
vertex merged (``n``). The sum alone grows with the number of planes, not with the distance: on
a strongly reduced smooth shell a vertex carries dozens of planes and ``sqrt(cost)`` is several
times the true distance, so a cap on it would stop small shells far short of their face target
while they are still well within the bound. A ``max_error`` bound (or a cap) refuses collapses
whose estimate exceeds it; the result is then *measured* — symmetric Hausdorff and mean distance
per shell, exact point-to-triangle distances from the vertices and face centroids of each surface
to the other (:func:`anatomesh.core.geometry.measure.surface_distance`; after Cignoni, Rocchini &
Scopigno 1998, "Metro: measuring error on simplified surfaces") — and the labels whose shells
exceed the bound are decimated again with their bound scaled down (by bound / measured,
0.125-0.5 each time; up to 5 runs). A shell that still exceeds it after one stricter run (a
rough shell whose vertices carry few planes: CT skin and bone under a large face budget) is then
bounded on the whole quadric cost, which bounds the squared distance to every merged plane
(Garland & Heckbert 1997) and is the conservative estimate; ``info["error_bound_met"]`` tells
whether it held.

The pieces shared with :mod:`.progressive` (input checks, budgets, the collapse driver,
SurfaceSets in and out, measuring) are in :mod:`.engine`.

Example
-------
>>> v, f, fl, info = decimate(vertices, faces, ratio=0.1)          # keep 10 % of the faces
>>> v, f, fl, info = decimate(vertices, faces, max_error=0.5)      # at most 0.5 mm away
>>> surfaces, report = decimate_surfaces(surface_set, max_error={5: 1.0, 7: 0.3})
"""
from __future__ import annotations

import dataclasses
import time
from typing import Dict, Optional, Tuple, Union

import numpy as np

from . import engine
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.progress import Progress, report
from ..model.surfaceset import SurfaceSet

Target = Union[None, float, int, Dict[int, float]]

#: runs of an error-bounded decimation: measured, and redone stricter where a shell is over
_ATTEMPTS = 5


def decimate(vertices: np.ndarray, faces: np.ndarray, *, face_labels: Optional[np.ndarray] = None,
             locked: Optional[np.ndarray] = None, ratio: Target = None, target_faces: Target = None,
             max_error: Target = None, progress: Optional[Progress] = None,
             max_normal_angle: float = 60.0, min_quality: float = 0.05, measure: bool = True,
             shell_values=None):
    """Simplify a triangle mesh or a multi-label surface by quadric edge collapse.

    Parameters
    ----------
    vertices : (N, 3) float, mm
    faces : (M, 3) int, counter-clockwise seen from outside (or from ``face_labels[:, 0]``)
    face_labels : (M, 2) int, optional
        (inside, outside) label of each face of a multi-label surface (each interface once).
        Without it the mesh is one surface (its junctions are its open boundary edges, if any).
    locked : (N,) bool or (K,) int, optional
        Vertices that must not move; no edge touching them collapses.
    ratio : float in (0, 1] or {label: ratio}
        Fraction of faces to keep (0.1 keeps 10 %), of the whole set or per label.
    target_faces : int or {label: int}
        Number of faces to keep, of the whole set or per label (a label's count includes its
        faces shared with other labels).
    max_error : float or {label: float}, mm
        Largest allowed distance between the result and the input (symmetric Hausdorff,
        measured; see the module docstring).
    progress : callable(fraction, text), optional
    max_normal_angle : degrees a face normal may turn in one collapse.
    min_quality : triangle quality under which a collapse may not make a face worse.
    measure : measure the true distances (and volume change) per shell after decimating
        (always done for ``max_error``).
    shell_values : label values to measure (default: all; plain meshes: the one surface).

    One of ``ratio``, ``target_faces``, ``max_error`` must be given; ``max_error`` (one number)
    may also come with ``ratio`` or ``target_faces`` as a cap: the face target is pursued but no
    collapse may exceed the bound (measured and enforced as for ``max_error`` alone), so a target
    the shapes cannot reach within it stops short (``target_met`` False). Per-label dicts
    budget the listed labels only; edges touching no listed label are not collapsed.

    Returns
    -------
    vertices : (N', 3) float32 mm
    faces : (M', 3) int32
    face_labels : (M', 2) int32 or None (None when none were given)
    info : dict
        ``faces_before/after``, ``vertices_before/after``, ``collapses``, ``quadric_error_mm``
        (sqrt of the largest accepted quadric cost), ``estimated_error_mm`` (the largest
        accepted error estimate, see the module docstring), ``seconds``, ``vertex_ids`` (N',) and
        ``face_ids`` (M',) (the input index of each output vertex and face), ``refused``
        {reason: edges refused}, for ratio and target_faces ``target_met``, for max_error
        ``error_bound_mm``, ``error_bound_met``, ``attempts``; with measuring ``hausdorff_mm``,
        ``mean_mm`` (worst shell) and ``shells``: {label: {faces_before, faces_after,
        hausdorff_mm, mean_mm, volume_change_pct}} (label ``None`` for a plain mesh).
    """
    t0 = time.perf_counter()
    p = engine.prepare(vertices, faces, face_labels, locked, max_normal_angle, min_quality)
    kind, value, cap = _check_target(ratio, target_faces, max_error, p.multi)
    bound = value if cap is None else cap
    bounded = kind == "max_error" or cap is not None
    factor = np.ones(len(p.values))            # per dense label: scale of its error bound
    whole = np.zeros(len(p.values), np.bool_)  # per dense label: bound on the whole cost
    for attempt in range(_ATTEMPTS if bounded else 1):
        lim = engine.limits(kind, value, p, factor)
        if cap is not None:
            lim = engine.error_bound(lim, cap, factor)
        lim.whole = whole
        out, info = _attempt(p, lim, kind, value, progress, attempt, measure or bounded,
                             shell_values)
        if not bounded:
            break
        over = _over_bound(info["shells"], bound, p.values)
        info.update(error_bound_mm=bound, error_bound_met=not over, attempts=attempt + 1)
        if not over:
            break
        if attempt > 0:                        # the stricter bound did not hold either: pin
            p = _pinned(p, out, info, over, bound)
        _stricter(over, factor, whole)
    info["seconds"] = time.perf_counter() - t0
    report(progress, 1.0, "decimated")
    return out + (info,)


def _pinned(p, out, info, over, bound):
    """``p`` with the input vertices the over-bound shells strayed from locked as well
    (:func:`engine.stray_vertices`)."""
    labels = [None] if not p.multi else sorted({int(p.values[i]) for i in over})
    pins = engine.stray_vertices(p, out[0].astype(np.float64), out[1], out[2],
                                 info["vertex_ids"], labels, bound)
    return dataclasses.replace(p, lock=p.lock | pins)


def _stricter(over, factor, whole):
    """Redo the shells over their bound ({dense label: Hausdorff / bound}) more strictly: a
    smaller bound on the error estimate first, then (when that did not hold either) the bound on
    the whole quadric cost at full size, then smaller whole bounds. ``factor`` (K,) float64 and
    ``whole`` (K,) bool change in place."""
    for i, excess in over.items():
        if factor[i] < 1.0 and not whole[i]:
            whole[i], factor[i] = True, 1.0
        else:
            factor[i] *= min(0.5, max(0.125, 0.8 / excess))


def _attempt(p, lim, kind, value, progress, attempt, measure, shell_values):
    """One collapse run under ``lim``; returns ((vertices, faces, face_labels), info)."""
    r = engine.collapse(p, lim, progress, attempt)
    out_v = (r.v + p.centre).astype(np.float32)
    out_fl = p.fl[r.face_ids] if p.multi else None
    s = r.stats
    info = {"faces_before": int(len(p.f)), "faces_after": int(len(r.f)),
            "vertices_before": s["vertices_before"], "vertices_after": int(len(out_v)),
            "collapses": s["collapses"], "candidates_checked": s["candidates"],
            "quadric_error_mm": float(np.sqrt(s["max_cost"])),
            "estimated_error_mm": float(np.sqrt(s["max_error"])), "refused": s["refused"],
            "vertex_ids": r.vertex_ids, "face_ids": r.face_ids}
    if kind != "max_error":
        # ratio / face targets can stop short: every remaining collapse would break a shell's
        # topology, a junction, or triangle quality (e.g. many tiny closed components)
        info["target_met"] = _target_met(value, p.values, r.f, out_fl, lim)
    if measure:
        report(progress, 0.97, "measuring the error")
        shells = engine.measure_shells(p.v, p.f, p.fl, out_v, r.f, out_fl, shell_values)
        info["shells"] = shells
        info["hausdorff_mm"] = max((x["hausdorff_mm"] for x in shells.values()), default=0.0)
        info["mean_mm"] = max((x["mean_mm"] for x in shells.values()), default=0.0)
    return (out_v, r.f, out_fl), info


# ---------------------------------------------------------------------------------------------
# one Mesh, one SurfaceSet
# ---------------------------------------------------------------------------------------------
def decimate_mesh(mesh: Mesh, *, ratio: Target = None, target_faces: Target = None,
                  max_error: Target = None, locked=None, progress: Optional[Progress] = None,
                  **options) -> Tuple[Mesh, Dict]:
    """Decimate one surface (:class:`Mesh`, closed or with an open boundary that stays in place);
    returns the new mesh and the report (:func:`decimate`'s ``info`` without the index arrays).
    Normals are dropped (recompute them)."""
    if not isinstance(mesh, Mesh):
        raise AnatomeshError(f"decimate_mesh needs a Mesh, got {type(mesh).__name__}: use "
                             "decimate_surfaces for a SurfaceSet")
    v, f, _, info = decimate(mesh.vertices, mesh.faces, locked=locked, ratio=ratio,
                             target_faces=target_faces, max_error=max_error, progress=progress,
                             **options)
    out = Mesh(v, f, None, name=mesh.name, value=mesh.value, color=mesh.color, space=mesh.space,
               meta=dict(mesh.meta))
    return out, _public(info)


def decimate_surfaces(surfaces: SurfaceSet, *, ratio: Target = None, target_faces: Target = None,
                      max_error: Target = None, locked=None, progress: Optional[Progress] = None,
                      **options) -> Tuple[SurfaceSet, Dict]:
    """Decimate a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`, all labels at once.

    Seams stay shared (each interface face is decimated once), every label shell stays closed
    and manifold with its topology, junction curves stay in place. Per-label targets are dicts
    keyed by label value. The vertices of faces carrying ``splits`` rows are locked, so the split
    rows stay valid (remapped to the new face indices). ``lattice`` keeps the lattice point of
    each surviving vertex (its position may have moved off it); a set of independent surfaces
    (:meth:`SurfaceSet.from_meshes`, no lattice) keeps its ``shell_values``.

    Returns ``(SurfaceSet, report)``; report as :func:`decimate`'s ``info`` (without the index
    arrays), ``shells`` keyed by label value, the background excluded.
    """
    lock, values = engine.surface_lock(surfaces, locked)
    v, f, fl, info = decimate(surfaces.vertices, surfaces.faces, face_labels=surfaces.face_labels,
                              locked=lock, ratio=ratio, target_faces=target_faces,
                              max_error=max_error, progress=progress, shell_values=values,
                              **options)
    out = engine.surfaces_result(surfaces, v, f, fl, info["vertex_ids"], info["face_ids"])
    return out, _public(info)


def _public(info: Dict) -> Dict:
    return {k: val for k, val in info.items() if k not in ("vertex_ids", "face_ids")}


# ---------------------------------------------------------------------------------------------
# targets
# ---------------------------------------------------------------------------------------------
def _check_target(ratio, target_faces, max_error, multi):
    cap = None
    if max_error is not None and (ratio is not None or target_faces is not None):
        if isinstance(max_error, dict):
            raise AnatomeshError("a max_error cap with a ratio or target_faces must be one number (mm)")
        cap, max_error = _check_value("max_error", max_error), None
    given = [(k, x) for k, x in (("ratio", ratio), ("target_faces", target_faces),
                                 ("max_error", max_error)) if x is not None]
    if len(given) != 1:
        raise AnatomeshError(
            "give exactly one decimation target: ratio (fraction of faces to keep), target_faces "
            f"or max_error (mm); got {', '.join(k for k, _ in given) or 'none'}")
    kind, value = given[0]
    if isinstance(value, dict):
        if not multi:
            raise AnatomeshError(f"a per-label {kind} (dict) needs face_labels (a multi-label "
                                 "surface); give one number for a single mesh")
        if not value:
            raise AnatomeshError(f"the per-label {kind} dict is empty: name at least one label")
        out = {}
        for lab, x in value.items():
            try:
                out[int(lab)] = _check_value(kind, x)
            except (TypeError, ValueError):
                raise AnatomeshError(f"{kind} keys must be label values (integers), got {lab!r}")
        return kind, out, cap
    return kind, _check_value(kind, value), cap


def _check_value(kind, x):
    try:
        x = float(x)
    except (TypeError, ValueError):
        raise AnatomeshError(f"{kind} must be a number, got {x!r}")
    if kind == "ratio" and not 0.0 < x <= 1.0:
        raise AnatomeshError(f"ratio is the fraction of faces to keep and must be in (0, 1], got {x}")
    if kind == "target_faces" and (x < 0 or x != int(x)):
        raise AnatomeshError(f"target_faces must be a whole number >= 0, got {x}")
    if kind == "max_error" and not (x >= 0 and np.isfinite(x)):
        raise AnatomeshError(f"max_error is a distance in mm and must be >= 0, got {x}")
    return int(x) if kind == "target_faces" else x


def _target_met(value, values, nf, out_fl, lim):
    if not isinstance(value, dict):
        return bool(len(nf) <= lim.final)
    counts = np.bincount(np.searchsorted(values, out_fl.ravel()), minlength=len(values))
    return bool(np.all(counts[lim.listed] <= np.maximum(lim.lab_target[lim.listed], 0) + 2))


def _over_bound(shells, bound, values):
    """{dense label index: measured Hausdorff / bound} of the shells over their bound (a plain
    mesh's one shell, label None, stands for both its sides)."""
    over = {}
    for lab, sh in shells.items():
        excess = sh["hausdorff_mm"] / max(_bound_of(bound, lab), 1e-12)
        if sh["hausdorff_mm"] > _bound_of(bound, lab) + 1e-9:
            ids = range(len(values)) if lab is None else np.flatnonzero(values == lab)
            over.update({int(i): excess for i in ids})
    return over


def _bound_of(value, label):
    if isinstance(value, dict):
        return value.get(label, np.inf)
    return value
