"""The decimation engine shared by :mod:`.qem` (one result) and :mod:`.progressive` (levels of detail).

* :func:`prepare` checks the inputs (positions in mm, faces, optional (inside, outside) labels,
  locked vertices, triangle-quality limits) and centres the positions;
* :func:`limits` turns a face or error target into per-label budgets;
* :func:`collapse` runs the quadric edge-collapse sweeps (Garland & Heckbert 1997, "Surface
  simplification using quadric error metrics"; sweeps under a rising cost threshold after Wu &
  Kobbelt 2002, "Fast mesh decimation by multiple-choice techniques") and can log every collapse
  for a progressive mesh (Hoppe 1996, "Progressive meshes");
* :func:`stray_vertices` finds the input vertices a bounded run pins when it tries again;
* :func:`surface_lock` and :func:`surfaces_result` take a
  :class:`~anatomesh.core.model.surfaceset.SurfaceSet` in and out (split rows and lattice carried
  over; sets of independent surfaces, ``lattice is None``, work alike);
* :func:`measure_shells` measures each shell against the input (symmetric Hausdorff and mean
  distance, volume change).

The numba kernels live in the private ``_*_kernels`` modules beside this one: quadrics and
placement, vertex classes, vertex → face lists, the collapse guards (link condition, normals,
quality), the collapse sweeps and the log replay. numba caches each kernel next to its own
source file only: after editing a kernel that kernels of another module call, clear
``core/decimate/__pycache__``.
"""
from __future__ import annotations

import dataclasses
from typing import Dict, Optional

import numpy as np

from . import _collapse_kernels as CK
from ._classify_kernels import classify, feature_constraints
from ._guard_kernels import face_frames
from ._quadric_kernels import bounds, build_quadrics
from ._refs_kernels import compact_refs, initial_refs
from ..geometry.neighbors import check_faces
from ..model.errors import AnatomeshError
from ..model.mesh import signed_volume
from ..model.progress import Progress, report
from ..model.surfaceset import SurfaceSet


@dataclasses.dataclass
class Prepared:
    """Checked inputs of one decimation run."""

    v: np.ndarray             # (N, 3) float64 input positions, mm
    f: np.ndarray             # (M, 3) int32
    fl: Optional[np.ndarray]  # (M, 2) int32 (inside, outside) labels, or None
    lock: np.ndarray          # (N,) bool
    multi: bool               # labelled faces (a SurfaceSet)
    values: np.ndarray        # label values (dense index -> value); [0, 1] for a plain mesh
    dense: np.ndarray         # (M, 2) int32 dense labels
    counts: np.ndarray        # faces per dense label
    centre: np.ndarray        # (3,) the run works on v - centre
    v64: np.ndarray           # (N, 3) float64 centred positions
    cos_max: float            # cosine of the largest normal turn of one collapse
    min_quality: float        # triangle quality a collapse may not go under (unless better)


@dataclasses.dataclass
class Limits:
    """What one run may do: per dense label a face target (-1: none), an error bound and
    whether the label is budgeted at all; the faces to stop at. Error bounds (mm²) are on a merged vertex's quadric cost per input vertex merged into it
    (see :mod:`.qem`)."""

    lab_target: np.ndarray    # (K,) int64
    lab_err: np.ndarray       # (K,) float64
    listed: np.ndarray        # (K,) bool
    final: int
    whole: Optional[np.ndarray] = None   # (K,) bool: bound on the whole cost (None: none)


@dataclasses.dataclass
class Collapsed:
    """Result of :func:`collapse`: the kept vertices ``v`` (N', 3) float64 (centred, mm), faces
    ``f`` (M', 3) int32, ``face_ids`` (M',) and ``vertex_ids`` (N',) into the input, ``stats``
    and, for a logged run, ``log`` = (keep, drop (C,) int32, where (C, 3) float64, face_death
    (M,) int32 with C for the faces that survive)."""

    v: np.ndarray
    f: np.ndarray
    face_ids: np.ndarray
    vertex_ids: np.ndarray
    stats: Dict
    log: Optional[tuple] = None


# ---------------------------------------------------------------------------------------------
# inputs
# ---------------------------------------------------------------------------------------------
def prepare(vertices, faces, face_labels=None, locked=None, max_normal_angle: float = 60.0,
            min_quality: float = 0.05) -> Prepared:
    """Check the inputs of a run (see :func:`anatomesh.core.decimate.qem.decimate`) and centre
    the positions on their bounding box (the quadrics keep their precision far from the origin).

    Raises
    ------
    AnatomeshError
        Bad shapes or values, NaN positions, faces with one label on both sides.
    """
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
    lo, hi, _ = bounds(v)
    centre = 0.5 * (lo + hi) if len(v) else np.zeros(3)
    return Prepared(v, f, fl, lock, multi, values, dense, counts, centre, v - centre,
                    float(np.cos(np.radians(max_normal_angle))), float(min_quality))


def _check_inputs(vertices, faces, face_labels, locked):
    v = np.asarray(vertices)
    if v.ndim != 2 or v.shape[1] != 3:
        raise AnatomeshError(f"vertices must be an (N, 3) array of positions in mm, got shape {v.shape}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    if not bounds(v)[2]:
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
    return v, f, fl, _lock_mask(locked, len(v))


def _lock_mask(locked, n):
    lock = np.zeros(n, bool)
    if locked is None:
        return lock
    lk = np.asarray(locked)
    if lk.dtype == bool:
        if lk.shape != (n,):
            raise AnatomeshError(f"locked must be a ({n},) bool mask or vertex indices, "
                                 f"got a bool array of shape {lk.shape}")
        lock |= lk
    elif lk.size:
        if not np.issubdtype(lk.dtype, np.integer) or lk.min() < 0 or lk.max() >= n:
            raise AnatomeshError(f"locked must hold vertex indices in [0, {n}) or be a bool mask")
        lock[lk.ravel()] = True
    return lock


def limits(kind: str, value, p: Prepared, factor=1.0) -> Limits:
    """Budgets of a ``ratio``, ``target_faces`` or ``max_error`` target (one number, or a dict
    {label value: number} budgeting the listed labels only). An error bound applies to every
    label (each shell is measured against it), scaled by ``factor``: one number or (K,) per dense
    label (the stricter retries of a bounded run)."""
    k = len(p.values)
    f = np.broadcast_to(np.asarray(factor, np.float64), (k,))
    out = Limits(np.full(k, -1, np.int64), np.full(k, np.inf), np.ones(k, np.bool_), 0)
    if isinstance(value, dict):
        out.listed[:] = False
        index = {int(x): i for i, x in enumerate(p.values)}
        for lab, x in value.items():
            if lab not in index:
                raise AnatomeshError(f"label {lab} has no faces in this surface; labels present: "
                                     f"{', '.join(str(int(x)) for x in p.values[:20])}")
            i = index[lab]
            out.listed[i] = True
            if kind == "ratio":
                out.lab_target[i] = int(round(x * p.counts[i]))
            elif kind == "target_faces":
                out.lab_target[i] = int(x)
            else:
                out.lab_err[i] = (f[i] * x) ** 2
    elif kind == "ratio":
        out.final = int(round(value * len(p.f)))
    elif kind == "target_faces":
        out.final = int(value)
    else:
        out.lab_err[:] = (f * value) ** 2
    return out


def error_bound(lim: Limits, bound: float, factor=1.0) -> Limits:
    """Add an error cap of ``bound`` mm (scaled by ``factor``, one number or per dense label) to
    every label of a face target's limits."""
    lim.lab_err = np.minimum(lim.lab_err, (np.asarray(factor, np.float64) * bound) ** 2)
    return lim


# ---------------------------------------------------------------------------------------------
# the collapse driver
# ---------------------------------------------------------------------------------------------
def collapse(p: Prepared, lim: Limits, progress: Optional[Progress] = None, attempt: int = 0,
             log_size: Optional[int] = None, log_stop: bool = False) -> Collapsed:
    """Run collapse sweeps with rising cost thresholds until the target is met or nothing is
    left to collapse under the limits.

    ``log_size`` (not None) records the first ``log_size`` collapses (``Collapsed.log``); with
    ``log_stop`` the run ends when the log is full. ``stats``: ``collapses``, ``max_cost``
    (largest accepted quadric cost, mm²), ``max_error`` (largest accepted cost per merged
    vertex, mm²), ``candidates`` (edges checked), ``logged``,
    ``vertices_before`` and ``refused`` {reason: edges refused} (see
    :mod:`._collapse_kernels`), ``endpoint_placements``.
    """
    st, rf, nref, used_before = _initial_state(p)
    bud = CK.Budget(lim.final, np.bincount(p.dense.ravel(), minlength=len(p.values)).astype(np.int64),
                    lim.lab_target, lim.lab_err, lim.listed,
                    np.zeros(len(p.values), np.bool_) if lim.whole is None else lim.whole,
                    bool(np.any(lim.lab_target >= 0) or np.any(np.isfinite(lim.lab_err))
                         or not lim.listed.all()))
    c = int(log_size or 0)
    log = CK.Log(np.zeros(c, np.int32), np.zeros(c, np.int32), np.zeros((c, 3)),
                 np.full(0 if log_size is None else len(p.f), -1, np.int32), bool(log_stop))
    opt = CK.Options(p.multi, p.cos_max, p.min_quality)
    stats = np.zeros(11)
    mark = np.zeros(len(p.v), np.int64)           # scratch vertex marks of the link test
    text = "decimating" if attempt == 0 else f"decimating (attempt {attempt + 1}, stricter bound)"
    report(progress, 0.0, text)
    nalive, nlog, m = len(p.f), 0, len(p.f)
    span, step = max(m - lim.final, 1), max(1, m // 30000)
    boost, tau, retried = 1.0, 0.0, False
    live = np.arange(m, dtype=np.int32)
    for stamp in range(1, 10000):
        if nalive <= lim.final:
            break
        need = nalive - lim.final
        frac = min(0.5, max(0.002, need / (2.0 * nalive))) * boost
        tau = _threshold(st, step, frac, tau)
        if tau is None:
            break
        if nalive < 0.6 * len(live):
            live = np.flatnonzero(st.falive).astype(np.int32)
        code, nalive, nref, nlog, done, rf = _sweep(st, rf, bud, log, opt, live, stamp, tau,
                                                    (nalive, nref, nlog), stats, mark)
        report(progress, 0.95 * (m - nalive) / span, text)
        if code == CK.DONE:
            break
        if done == 0 and frac >= 1.0:
            if retried:
                break                   # nothing collapsible is left under the bound
            # refused edges were parked; their neighbourhoods may have changed: try all again
            costs = st.FD[:, :3]
            np.copyto(costs, -1.0 - costs, where=costs < 0.0)
            retried = True
            continue
        retried = retried and done == 0
        # few collapses for the need: admit more candidates next sweep; plenty: tighten again
        if done < 0.125 * need:
            boost *= 2.0
        elif done > 0.5 * need:
            boost = max(1.0, boost / 2.0)
    return _result(st, log, log_size is not None, nlog, stats, used_before)


def _initial_state(p: Prepared):
    """The kernels' state of a run: faces, vertex classes, quadrics, face rows, edge costs."""
    n, m = len(p.v64), len(p.f)
    V, F = p.v64.copy(), p.f.copy()
    refs, vstart, vcount, nref = initial_refs(F, n, max(m, 1024))
    used_before = int(np.count_nonzero(vcount))
    vclass = classify(F, p.dense, refs, vstart, vcount, p.multi)
    vclass[p.lock] = 2
    ca, cb, cf = feature_constraints(F, p.dense, refs, vstart, vcount, vclass, p.multi)
    Q = build_quadrics(V, F, ca, cb, cf)
    FD = face_frames(V, F)             # per face: 3 edge costs, unit normal, quality
    CK.edge_costs(V, Q, F, vclass, FD, p.multi)
    st = CK.State(V, Q, np.ones(n), F, FD, np.ones(m, np.bool_), p.dense, vclass,
                  np.zeros(n, np.int32), np.zeros(n, np.int32))
    return st, CK.Refs(refs, vstart, vcount), nref, used_before


def _threshold(st, step, frac, tau):
    """The sweep's cost threshold: the ``frac`` quantile of a sample of the current edge costs,
    never below the last one (what was allowed and failed stays failed until it changes); every
    edge for ``frac`` >= 1; None when no edge is left."""
    sample = CK.sample_costs(st.FD, st.falive, step)
    if sample.size == 0:
        return None
    if frac >= 1.0:
        return np.inf
    i = int(frac * (sample.size - 1))
    return max(tau, float(np.partition(sample, i)[i]))


def _sweep(st, rf, bud, log, opt, live, stamp, tau, counts, stats, mark):
    """One sweep, compacting (and growing) the vertex → face lists when they fill up."""
    start, done = 0, 0
    while True:
        code, nalive, nref, start, got, nlog = CK.collapse_pass(st, rf, bud, log, opt, live, stamp,
                                                                tau, start, counts, stats, mark)
        done += got
        if code != CK.REFS_FULL:
            return code, nalive, nref, nlog, done, rf
        refs, nref = compact_refs(rf.refs, rf.vstart, rf.vcount, st.ver, st.falive, len(rf.refs))
        if nref > len(refs) // 2:
            refs = np.concatenate([refs, np.empty(len(refs), np.int32)])
        rf = rf._replace(refs=refs)
        counts = (nalive, nref, nlog)


def _result(st, log, logged, nlog, stats, used_before) -> Collapsed:
    keep_f = np.flatnonzero(st.falive)
    nf = st.F[keep_f]
    n = len(st.V)
    used = np.flatnonzero(np.bincount(nf.ravel(), minlength=n))
    remap = np.full(n, -1, np.int64)
    remap[used] = np.arange(used.size)
    info = {"collapses": int(np.count_nonzero(st.ver < 0)), "max_cost": float(stats[CK.MAX_COST]),
            "max_error": float(stats[CK.MAX_ERROR]),
            "candidates": int(stats[CK.CANDIDATES]), "logged": int(nlog),
            "vertices_before": used_before,
            "refused": {k: int(x) for k, x in zip(CK.REFUSALS, stats[CK.LOCKED:CK.ENDPOINT])},
            "endpoint_placements": int(stats[CK.ENDPOINT])}
    out = Collapsed(st.V[used], remap[nf].astype(np.int32), keep_f, used, info)
    if logged:
        death = log.face_death
        death[death < 0] = nlog
        out.log = (log.keep[:nlog].copy(), log.drop[:nlog].copy(), log.where[:nlog].copy(), death)
    return out


# ---------------------------------------------------------------------------------------------
# SurfaceSets in and out
# ---------------------------------------------------------------------------------------------
def surface_lock(surfaces: SurfaceSet, locked=None):
    """Locked vertices of a SurfaceSet run, (N,) bool: the caller's ``locked`` (mask or indices)
    plus every corner of a face with split rows (so the rows stay valid); and the label values
    to measure (those with faces, the background excluded)."""
    if not isinstance(surfaces, SurfaceSet):
        raise AnatomeshError(f"expected a SurfaceSet, got {type(surfaces).__name__}: use the Mesh "
                             "variant (decimate_mesh) for one surface")
    lock = _lock_mask(locked, surfaces.n_vertices)
    if len(surfaces.splits):
        lock[surfaces.faces[surfaces.splits[:, 0]].ravel()] = True
    return lock, surfaces.values()


def surfaces_result(surfaces: SurfaceSet, v, f, fl, vertex_ids, face_ids) -> SurfaceSet:
    """A copy of ``surfaces`` with the decimated arrays (``vertex_ids``/``face_ids``: the input
    index of each kept vertex and face): the lattice point of each kept vertex (none for a set
    of independent surfaces), split rows remapped to the new faces; labels, ``shell_values``
    and the rest unchanged."""
    changes = {"vertices": v, "faces": f, "face_labels": fl, "warnings": list(surfaces.warnings)}
    if surfaces.lattice is not None:
        changes["lattice"] = surfaces.lattice[vertex_ids]
    splits = surfaces.splits
    if len(splits):
        new_face = np.full(surfaces.n_faces, -1, np.int64)
        new_face[face_ids] = np.arange(len(face_ids))
        rows = splits[new_face[splits[:, 0]] >= 0].copy()
        rows[:, 0] = new_face[rows[:, 0]]
        changes["splits"] = rows.astype(np.int32)
    return dataclasses.replace(surfaces, **changes)


# ---------------------------------------------------------------------------------------------
# measuring the result
# ---------------------------------------------------------------------------------------------
def _shell_faces(faces, face_labels, value):
    """Faces of one label's shell, oriented outward (faces with the label outside flipped)."""
    inside = face_labels[:, 0] == value
    outside = face_labels[:, 1] == value
    return np.concatenate([faces[inside], faces[outside][:, ::-1]])


def stray_vertices(p: Prepared, out_v, out_f, out_fl, vertex_ids, labels, bound) -> np.ndarray:
    """Input vertices to pin in a stricter run, (N,) bool: on each shell of ``labels`` (label
    values; None: a plain mesh), the input vertices farther than half its ``bound`` (mm; one
    number or {label: mm}) from the decimated shell, and the input vertices (``vertex_ids``) of
    the output vertices farther than that from the input shell. Where the quadric cost let a
    vertex slide along its planes (a thin tip pulled in), pinning holds the shape."""
    from ..geometry.measure import point_to_surface

    pins = np.zeros(len(p.v), bool)
    for lab in labels:
        a = p.f if lab is None else _shell_faces(p.f, p.fl, lab)
        b = out_f if lab is None else _shell_faces(out_f, out_fl, lab)
        limit = 0.5 * (bound.get(lab, np.inf) if isinstance(bound, dict) else bound)
        ia, ib = np.unique(a), np.unique(b)
        pins[ia[point_to_surface(p.v[ia], out_v, b) > limit]] = True
        pins[vertex_ids[ib[point_to_surface(out_v[ib], p.v, a) > limit]]] = True
    return pins


def measure_shells(v0, f0, fl0, v1, f1, fl1, values=None) -> Dict:
    """Per shell of the input (``v0`` mm, ``f0``, ``fl0`` labels or None) and its decimation
    (``v1``, ``f1``, ``fl1``): ``faces_before``/``faces_after``, symmetric Hausdorff and mean
    distance (mm; exact point-to-triangle distances from the vertices and face centroids of each
    surface to the other, :func:`anatomesh.core.geometry.measure.surface_distance`) and
    ``volume_change_pct``. Keyed by label value (``values``, default all), ``None`` for a plain
    mesh."""
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
