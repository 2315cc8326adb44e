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

Error in mm: the running estimate is ``sqrt(quadric cost)`` (an upper bound of the distance to
every original plane merged into the vertex). For a ``max_error`` target the collapse stops when
that estimate exceeds the bound; the result is then *measured* — symmetric Hausdorff and mean
distance per shell, exact point-to-triangle distances from the vertices and face centroids of
each surface to the other (:func:`anatomesh.core.geometry.measure.surface_distance`) — and if the measured
Hausdorff distance exceeds the bound, decimation is redone with the quadric bound scaled by 0.5
(up to 4 times); ``info["error_bound_met"]`` tells whether it held.

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

from . import _kernels as _k
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh, signed_volume
from ..geometry.neighbors import check_faces
from ..model.progress import Progress, report

Target = Union[None, float, int, Dict[int, float]]

#: quadric bound scale factor for each attempt of a max_error target (measured, then redone)
_ERROR_FACTORS = (1.0, 0.5, 0.25, 0.125, 0.0625)


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
        (sqrt of the largest accepted quadric cost), ``seconds``, ``vertex_ids`` (N',) and
        ``face_ids`` (M',) (the input index of each output vertex and face), for ratio and
        target_faces ``target_met``, for max_error ``error_bound_mm``, ``error_bound_met``,
        ``attempts``; with measuring ``hausdorff_mm``,
        ``mean_mm`` (worst shell) and ``shells``: {label: {faces_before, faces_after,
        hausdorff_mm, mean_mm, volume_change_pct}} (label ``None`` for a plain mesh).
    """
    t0 = time.perf_counter()
    p = _prepare(vertices, faces, face_labels, locked, max_normal_angle, min_quality)
    v, f, fl, multi, values, centre = p.v, p.f, p.fl, p.multi, p.values, p.centre
    kind, value, cap = _check_target(ratio, target_faces, max_error, multi)

    bounded = kind == "max_error" or cap is not None
    factors = _ERROR_FACTORS if bounded else (None,)
    for attempt, factor in enumerate(factors):
        budget = _budget(kind, value, values, p.counts, len(f), multi, factor)
        if cap is not None:
            budget = budget[:4] + ((factor * cap) ** 2,)
        nv, nf, keep_f, keep_v, stats = _collapse(p.v64, f, p.dense, multi, p.lock, budget,
                                                  len(values), p.cos_max, min_quality, progress,
                                                  attempt)
        out_v = (nv + centre).astype(np.float32)
        out_fl = fl[keep_f] if multi else None
        info = {"faces_before": int(len(f)), "faces_after": int(len(nf)),
                "vertices_before": stats["vertices_before"],
                "vertices_after": int(len(out_v)), "collapses": int(stats["collapses"]),
                "candidates_checked": stats["candidates"],
                "quadric_error_mm": float(np.sqrt(stats["max_cost"])),
                "vertex_ids": keep_v, "face_ids": keep_f}
        if bounded:
            info["error_bound_mm"] = value if cap is None else cap
        if kind != "max_error":
            # ratio / face targets can stop short: every remaining collapse would break a shell's
            # topology, a junction, or triangle quality (e.g. many tiny closed components)
            info["target_met"] = bool(_target_met(kind, value, values, fl, nf, out_fl, budget))
        if measure or bounded:
            report(progress, 0.97, "measuring the error")
            shells = _measure_shells(v, f, fl, out_v, nf, out_fl, shell_values)
            info["shells"] = shells
            info["hausdorff_mm"] = max((s["hausdorff_mm"] for s in shells.values()), default=0.0)
            info["mean_mm"] = max((s["mean_mm"] for s in shells.values()), default=0.0)
        if not bounded:
            break
        met = all(s["hausdorff_mm"] <= _bound_of(value if cap is None else cap, lab) + 1e-9
                  for lab, s in info["shells"].items())
        info["error_bound_met"] = bool(met)
        info["attempts"] = attempt + 1
        if met:
            break
    info["seconds"] = time.perf_counter() - t0
    report(progress, 1.0, "decimated")
    return out_v, nf, out_fl, info


# ---------------------------------------------------------------------------------------------
# convenience wrappers
# ---------------------------------------------------------------------------------------------
def decimate_mesh(mesh: Mesh, *, ratio: Target = None, target_faces: Target = None,
                  max_error: Target = None, locked=None, progress: Optional[Progress] = None,
                  **options) -> Tuple[Mesh, Dict]:
    """Decimate one closed surface (:class:`Mesh`); returns the new mesh and the report
    (:func:`decimate`'s ``info`` without the index arrays). Normals are dropped (recompute them)."""
    v, f, _, info = decimate(mesh.vertices, mesh.faces, locked=locked, ratio=ratio,
                             target_faces=target_faces, max_error=max_error, progress=progress,
                             **options)
    out = Mesh(v, f, None, name=mesh.name, value=mesh.value, color=mesh.color, space=mesh.space,
               meta=dict(mesh.meta))
    return out, _public(info)


def decimate_surfaces(surfaces, *, ratio: Target = None, target_faces: Target = None,
                      max_error: Target = None, locked=None, progress: Optional[Progress] = None,
                      **options):
    """Decimate a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`, all labels at once.

    Seams stay shared (each interface face is decimated once), every label shell stays closed
    and manifold with its topology, junction curves stay in place. Per-label targets are dicts
    keyed by label value. The vertices of faces carrying ``splits`` rows are locked, so the split
    rows stay valid (remapped to the new face indices). ``lattice`` keeps the lattice point of
    each surviving vertex (its position may have moved off it).

    Returns ``(SurfaceSet, report)``; report as :func:`decimate`'s ``info`` (without the index
    arrays), ``shells`` keyed by label value, the background excluded.
    """
    for name in ("vertices", "faces", "face_labels"):
        if not hasattr(surfaces, name):
            raise AnatomeshError(f"decimate_surfaces needs a SurfaceSet (with {name}), got "
                                 f"{type(surfaces).__name__}: use decimate_mesh for one Mesh")
    lock, values = _surface_lock(surfaces, locked)
    v, f, fl, info = decimate(surfaces.vertices, surfaces.faces, face_labels=surfaces.face_labels,
                              locked=lock, ratio=ratio, target_faces=target_faces,
                              max_error=max_error, progress=progress, shell_values=values,
                              **options)
    out = _surfaces_result(surfaces, v, f, fl, info["vertex_ids"], info["face_ids"])
    return out, _public(info)


def _surface_lock(surfaces, locked):
    """Locked vertices of a SurfaceSet run (caller's, plus every corner of a face with split
    rows) and the label values to measure (the background excluded)."""
    for name in ("vertices", "faces", "face_labels"):
        if not hasattr(surfaces, name):
            raise AnatomeshError(f"expected a SurfaceSet (with {name}), got "
                                 f"{type(surfaces).__name__}: use the Mesh variant for one surface")
    lock = np.zeros(len(surfaces.vertices), bool)
    if locked is not None:
        lock |= _check_inputs(surfaces.vertices, surfaces.faces, None, locked)[3]
    splits = _splits(surfaces)
    if len(splits):
        lock[np.asarray(surfaces.faces)[splits[:, 0]].ravel()] = True
    bg = getattr(surfaces, "background", None)
    labels = np.unique(np.asarray(surfaces.face_labels))
    return lock, [int(x) for x in labels if bg is None or x != bg]


def _splits(surfaces) -> np.ndarray:
    return np.asarray(getattr(surfaces, "splits", np.zeros((0, 4), np.int32))).reshape(-1, 4)


def _surfaces_result(surfaces, v, f, fl, vertex_ids, face_ids):
    """A copy of ``surfaces`` with the decimated arrays; lattice and split rows carried over
    (``vertex_ids``/``face_ids``: the input index of each kept vertex and face)."""
    splits = _splits(surfaces)
    changes = {"vertices": v, "faces": f, "face_labels": fl}
    if getattr(surfaces, "lattice", None) is not None:
        changes["lattice"] = np.asarray(surfaces.lattice)[vertex_ids]
    if len(splits):
        new_face = np.full(len(surfaces.faces), -1, np.int64)
        new_face[face_ids] = np.arange(len(face_ids))
        rows = splits[new_face[splits[:, 0]] >= 0].copy()
        rows[:, 0] = new_face[rows[:, 0]]
        changes["splits"] = rows.astype(np.int32)
    if hasattr(surfaces, "warnings"):
        changes["warnings"] = list(surfaces.warnings)
    if dataclasses.is_dataclass(surfaces):
        return dataclasses.replace(surfaces, **changes)
    out = surfaces  # pragma: no cover - duck-typed containers
    for k, val in changes.items():
        setattr(out, k, val)
    return out


def _public(info: Dict) -> Dict:
    return {k: val for k, val in info.items() if k not in ("vertex_ids", "face_ids")}


# ---------------------------------------------------------------------------------------------
# input checks
# ---------------------------------------------------------------------------------------------
@dataclasses.dataclass
class _Prepared:
    """Checked inputs of one decimation run (shared with :mod:`anatomesh.core.decimate.progressive`)."""

    v: np.ndarray            # (N, 3) float64 input positions, mm
    f: np.ndarray            # (M, 3) int32
    fl: Optional[np.ndarray]  # (M, 2) int32 or None
    lock: np.ndarray         # (N,) bool
    multi: bool
    values: np.ndarray       # label values (dense index -> value); [0, 1] for a plain mesh
    dense: np.ndarray        # (M, 2) int32 dense labels
    counts: np.ndarray       # faces per dense label
    centre: np.ndarray       # (3,) the run works on v - centre
    v64: np.ndarray          # (N, 3) float64 centred positions
    cos_max: float


def _prepare(vertices, faces, face_labels, locked, max_normal_angle, min_quality) -> _Prepared:
    v, f, fl, lock = _check_inputs(vertices, faces, face_labels, locked)
    if not 0.0 < max_normal_angle <= 180.0:
        raise AnatomeshError(f"max_normal_angle must be in (0, 180] degrees, got {max_normal_angle}")
    if not 0.0 <= min_quality < 1.0:
        raise AnatomeshError(f"min_quality must be in [0, 1), got {min_quality}")
    multi = fl is not None
    if multi:
        values, dense = np.unique(fl, return_inverse=True)
        dense = dense.reshape(-1, 2).astype(np.int32)
        counts = np.bincount(dense.ravel(), minlength=len(values)).astype(np.int64)
    else:
        values = np.array([0, 1])
        dense = np.zeros((len(f), 2), np.int32)
        dense[:, 1] = 1
        counts = np.array([len(f), len(f)], np.int64)
    lo, hi, _ = _k.bounds(v)
    centre = 0.5 * (lo + hi) if len(v) else np.zeros(3)
    return _Prepared(v, f, fl, lock, multi, values, dense, counts, centre, v - centre,
                     float(np.cos(np.radians(max_normal_angle))))


def _check_inputs(vertices, faces, face_labels, locked):
    v = np.asarray(vertices)
    if v.ndim != 2 or v.shape[1] != 3:
        raise AnatomeshError(f"vertices must be an (N, 3) array of positions in mm, got shape {v.shape}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    if not _k.bounds(v)[2]:
        raise AnatomeshError("vertices contain NaN or infinite coordinates: clean the mesh first")
    f = check_faces(faces, len(v))
    fl = None
    if face_labels is not None:
        fl = np.asarray(face_labels)
        if fl.shape != (len(f), 2) or (fl.size and not np.issubdtype(fl.dtype, np.integer)):
            raise AnatomeshError(f"face_labels must be an ({len(f)}, 2) integer array (inside, "
                                 f"outside label of each face), got {fl.shape} {fl.dtype}")
        fl = np.ascontiguousarray(fl, dtype=np.int32)
        if np.any(fl[:, 0] == fl[:, 1]):
            raise AnatomeshError("face_labels has faces with the same label on both sides: such "
                                 "faces separate nothing; drop them before decimating")
    lock = np.zeros(len(v), bool)
    if locked is not None:
        lk = np.asarray(locked)
        if lk.dtype == bool:
            if lk.shape != (len(v),):
                raise AnatomeshError(f"locked must be a ({len(v)},) bool mask or vertex indices, "
                                     f"got a bool array of shape {lk.shape}")
            lock |= lk
        elif lk.size:
            if not np.issubdtype(lk.dtype, np.integer) or lk.min() < 0 or lk.max() >= len(v):
                raise AnatomeshError(f"locked must hold vertex indices in [0, {len(v)}) or be a "
                                     f"bool mask")
            lock[lk.ravel()] = True
    return v, f, fl, lock


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


def _target_met(kind, value, values, fl, nf, out_fl, budget):
    lab_target, _, listed, final, _ = budget
    if not isinstance(value, dict):
        return len(nf) <= final
    counts = np.bincount(np.searchsorted(values, out_fl.ravel()), minlength=len(values))
    return bool(np.all(counts[listed] <= np.maximum(lab_target[listed], 0) + 2))


def _bound_of(value, label):
    if isinstance(value, dict):
        return value.get(label, np.inf)
    return value


# ---------------------------------------------------------------------------------------------
# budgets and the collapse driver
# ---------------------------------------------------------------------------------------------
def _budget(kind, value, values, counts, n_faces, multi, factor):
    """Per-dense-label arrays (target faces, max quadric cost, listed) and the global limits."""
    k = len(values)
    lab_target = np.full(k, -1, np.int64)
    lab_cost = np.full(k, np.inf)
    listed = np.ones(k, np.bool_)
    final, max_cost = 0, np.inf
    if isinstance(value, dict):
        listed[:] = False
        index = {int(x): i for i, x in enumerate(values)}
        for lab, x in value.items():
            if lab not in index:
                raise AnatomeshError(f"label {lab} has no faces in this surface; labels present: "
                                     f"{', '.join(str(int(x)) for x in values[:20])}")
            i = index[lab]
            listed[i] = True
            if kind == "ratio":
                lab_target[i] = int(round(x * counts[i]))
            elif kind == "target_faces":
                lab_target[i] = int(x)
            else:
                lab_cost[i] = (factor * x) ** 2
        if kind == "max_error":
            max_cost = float(lab_cost[listed].max())
    elif kind == "ratio":
        final = int(round(value * n_faces))
    elif kind == "target_faces":
        final = int(value)
    else:
        max_cost = (factor * value) ** 2
    return lab_target, lab_cost, listed, final, max_cost


def _collapse(v64, f, dense, multi, lock, budget, nlab, cos_max, q_min, progress, attempt,
              log=None, log_stop=False):
    """Run collapse sweeps with rising cost thresholds until the target is met or nothing is
    left to collapse; returns (vertices, faces, kept face ids, kept vertex ids, stats).

    ``log``: optional ``(keep, drop, where, face_death)`` arrays receiving the collapse sequence
    (see :func:`_k.collapse_pass`); with ``log_stop`` the run stops when the log is full.
    ``stats["logged"]`` is the number of collapses recorded."""
    lab_target, lab_cost, listed, final, max_cost = budget
    n, m = len(v64), len(f)
    V = v64.copy()
    F = f.copy()
    falive = np.ones(m, np.bool_)
    refs, vstart, vcount, nref = _k.initial_refs(F, n, max(m, 1024))
    used_before = int(np.count_nonzero(vcount))
    vclass = _k.classify(F, dense, refs, vstart, vcount, multi)
    vclass[lock] = 2
    ca, cb, cf = _k.feature_constraints(F, dense, refs, vstart, vcount, vclass, multi)
    Q = _k.build_quadrics(V, F, ca, cb, cf)
    FD = _k.face_frames(V, F)             # per face: 3 edge costs, unit normal, quality
    _k.edge_costs(V, Q, F, vclass, FD, multi)
    mark = np.zeros(n, np.int64)          # scratch vertex marks of the link test
    budgets = bool(np.any(lab_target >= 0) or np.any(np.isfinite(lab_cost)) or not listed.all())
    ver = np.zeros(n, np.int32)
    vstamp = np.zeros(n, np.int32)
    lab_count = np.bincount(dense.ravel(), minlength=nlab).astype(np.int64)
    if log is None:
        log = (np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros(0, np.int32))
    log_a, log_b, log_p, fdeath = log
    stats = np.zeros(9)
    nalive, nlog = m, 0
    span = max(m - final, 1)
    step = max(1, m // 30000)
    boost = 1.0
    tau = 0.0
    retried = False
    live = np.arange(m, dtype=np.int32)
    text = "decimating" if attempt == 0 else f"decimating (attempt {attempt + 1}, stricter bound)"
    report(progress, 0.0, text)
    for stamp in range(1, 10000):
        if nalive <= final:
            break
        need = nalive - final
        frac = min(0.5, max(0.002, need / (2.0 * nalive))) * boost
        sample = _k.sample_costs(FD, falive, step)
        if sample.size == 0:
            break
        if frac >= 1.0:
            tau = max_cost
        else:
            i = int(frac * (sample.size - 1))
            # thresholds never fall: what was allowed and failed stays failed until it changes
            tau = min(max_cost, max(tau, float(np.partition(sample, i)[i])))
        if nalive < 0.6 * len(live):
            live = np.flatnonzero(falive).astype(np.int32)
        start, done = 0, 0
        while True:
            code, nalive, nref, start, got, nlog = _k.collapse_pass(
                live, V, Q, F, falive, dense, vclass, ver, refs, vstart, vcount, nref, FD, vstamp,
                stamp, tau, start, nalive, final, lab_count, lab_target, lab_cost, listed, budgets,
                multi, cos_max, q_min, log_a, log_b, log_p, fdeath, log_stop, nlog, stats, mark)
            done += got
            if code != _k.REFS_FULL:
                break
            refs, nref = _k.compact_refs(refs, vstart, vcount, ver, falive, len(refs))
            if nref > len(refs) // 2:
                refs = np.concatenate([refs, np.empty(len(refs), np.int32)])
        report(progress, 0.95 * (m - nalive) / span, text)
        if code == _k.DONE:
            break
        if done == 0 and (tau >= max_cost or frac >= 1.0):
            if retried:
                break                   # nothing collapsible is left under the bound
            # refused edges were parked; their neighbourhoods may have changed: try all again
            costs = FD[:, :3]
            np.copyto(costs, -1.0 - costs, where=costs < 0.0)
            retried = True
            continue
        retried = retried and done == 0
        # few collapses for the need: admit more candidates next sweep; plenty: tighten again
        if done < 0.125 * need:
            boost *= 2.0
        elif done > 0.5 * need:
            boost = max(1.0, boost / 2.0)
    keep_f = np.flatnonzero(falive)
    nf = F[keep_f]
    used = np.flatnonzero(np.bincount(nf.ravel(), minlength=n))
    remap = np.full(n, -1, np.int64)
    remap[used] = np.arange(used.size)
    return V[used], remap[nf].astype(np.int32), keep_f, used, {
        "collapses": int(np.count_nonzero(ver < 0)), "max_cost": float(stats[0]),
        "candidates": int(stats[1]), "logged": int(nlog), "vertices_before": used_before,
        "refused": stats[2:].astype(np.int64)}


# ---------------------------------------------------------------------------------------------
# measuring the result
# ---------------------------------------------------------------------------------------------
def _shell_faces(faces, face_labels, value):
    """Faces of one label's shell, oriented outward (faces with the label outside flipped)."""
    inside = face_labels[:, 0] == value
    outside = face_labels[:, 1] == value
    return np.concatenate([faces[inside], faces[outside][:, ::-1]])


def _measure_shells(v0, f0, fl0, v1, f1, fl1, values) -> Dict:
    """Per shell: faces before/after, symmetric Hausdorff and mean distance (mm), volume change."""
    from ..geometry.measure import surface_distance

    if fl0 is None:
        groups = [(None, f0, f1)]
    else:
        if values is None:
            values = [int(x) for x in np.unique(fl0)]
        groups = [(lab, _shell_faces(f0, fl0, lab), _shell_faces(f1, fl1, lab)) for lab in values]
    out = {}
    for lab, a, b in groups:
        entry = {"faces_before": int(len(a)), "faces_after": int(len(b))}
        if len(a) == 0 or len(b) == 0:
            entry.update(hausdorff_mm=0.0 if len(a) == len(b) else np.inf, mean_mm=0.0,
                         volume_change_pct=0.0)
        else:
            d = surface_distance(v0, a, v1, b)
            vol0, vol1 = signed_volume(v0, a), signed_volume(v1, b)
            entry.update(hausdorff_mm=d["hausdorff_mm"], mean_mm=d["mean_mm"],
                         volume_change_pct=100.0 * (vol1 - vol0) / abs(vol0) if vol0 else 0.0)
        out[lab] = entry
    return out
