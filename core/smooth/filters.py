"""Mesh smoothing filters on plain arrays, with hard bounds on how far a vertex moves.

Every filter takes ``vertices (N, 3)`` float in mm and ``faces (M, 3)`` int and returns new vertex
positions (same dtype as the input; connectivity never changes, so smoothing cannot change the
topology of the mesh, only its shape). Each is one Jacobi pass per step over a cached CSR
neighbourhood (numba, parallel; Mönch, Lawonn, Tietjen & Preim 2012, "Interactive mesh smoothing
for medical applications"); the uniform passes of :func:`taubin` and :func:`laplacian` take the
fast padded-column path of :mod:`~anatomesh.core.smooth.passes` (same results to ~1e-12 mm).

=====================  =========================================================================
:func:`laplacian`      umbrella operator, uniform or edge-length weights (Fujiwara 1995, "Eine
                       Verallgemeinerung des Laplace-Operators für Dreiecksnetze")
:func:`taubin`         λ|μ low-pass filter (Taubin 1995, "A signal processing approach to fair
                       surface design"): barely shrinks; the organ default
:func:`hc_laplacian`   Laplacian + HC correction (Vollmer, Mencl & Müller 1999, "Improved
                       Laplacian smoothing of noisy surface meshes")
:func:`mean_curvature_flow`  cotangent weights, explicit (Desbrun, Meyer, Schröder & Barr 1999,
                       "Implicit fairing of irregular meshes using diffusion and curvature flow")
:func:`normal_filter`  mean or median filtering of face normals + vertex update (Yagou, Ohtake
                       & Belyaev 2002, "Mesh smoothing via mean and median filtering applied to
                       face normals")
=====================  =========================================================================

Common keywords: ``constraint`` (:class:`~anatomesh.core.smooth.constraints.Constraint`, re-applied
after every pass), ``gain`` (per-vertex damping in [0, 1]), ``face_groups`` (a group id per face,
or an (M, 2) pair per face compared unordered, e.g. a SurfaceSet's ``face_labels``: vertices on
curves where groups meet — junctions of 3+ labels, open boundaries, non-manifold edges — smooth
only along the curve, curve ends and corners stay fixed), ``structure`` (a cached :class:`~anatomesh.core.geometry.neighbors.MeshStructure`),
``progress``, and for :func:`taubin` and :func:`laplacian` ``keep_buffers`` (False: the rings and
working buffers the passes cache in the structure are freed as soon as they are used, one-shot
runs' memory). Bade, Haase & Preim 2006 ("Comparison of fundamental mesh smoothing algorithms for
medical surface models") recommend λ 0.5–0.7 with about 20 iterations (Taubin or HC) for compact
and flat organs.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from . import _filter_kernels as _k
from .checks import check_factor, check_iterations, check_rings, check_taubin, precision_dtype
from .constraints import EYE, Constraint
from .passes import uniform_passes
from .prepare import Setup, constrain, finish, merge_rows, prepare, umbrella, weight_mode
from ..geometry.neighbors import MeshStructure
from ..model.errors import AnatomeshError
from ..model.progress import Progress, report


def laplacian(vertices, faces, *, iterations: int = 10, lam: float = 0.5, weights: str = "uniform",
              rings: int = 1, constraint: Optional[Constraint] = None, gain=None, face_groups=None,
              structure: Optional[MeshStructure] = None, progress: Optional[Progress] = None,
              precision: str = "float64", keep_buffers: bool = True):
    """Laplacian (umbrella) smoothing (Fujiwara 1995): ``v' = v + λ Σ w_j (u_j − v) / Σ w_j``.

    Parameters
    ----------
    vertices : (N, 3) float, mm
    faces : (M, 3) int
    iterations : int — passes (Bade et al. 2006: ~20 for organs; shrinks volume steadily)
    lam : float in (0, 1] — step λ (0.5–0.9 usual)
    weights : "uniform" (umbrella) or "edge_length" (w = 1/|u_j − v|, Fujiwara 1995)
    rings : 1 or 2 — neighbourhood (the 2-ring smooths faster)
    constraint, gain, face_groups, structure, progress : see the module docstring.
    precision : "float64" (default) or "float32" — the arithmetic of the uniform 1-ring passes:
        float32 is faster (live sliders) and within ~1e-4 mm of float64; other weights and
        rings always run in float64.

    Returns (N, 3) positions, the dtype of ``vertices``.
    """
    check_factor("lam", lam, 0.0, 1.0)
    precision_dtype(precision)
    mode = weight_mode(weights)
    if mode == 0 and check_rings(rings) == 1:
        check_iterations(iterations)
        n = int(iterations)
        return uniform_passes(vertices, faces, [lam] * n, [False] * n, None,
                               structure=structure, constraint=constraint, gain=gain,
                               face_groups=face_groups, progress=progress, per_report=1,
                               text="Laplacian smoothing", precision=precision,
                               keep_buffers=keep_buffers)
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                  rings=rings, face_groups=face_groups, iterations=iterations)
    buf = np.empty_like(st.pos)
    for it in range(int(iterations)):
        umbrella(st, st.pos, buf, lam, mode=mode)
        st.pos, buf = buf, st.pos
        report(progress, (it + 1) / iterations, "Laplacian smoothing")
    return finish(st)


def taubin(vertices, faces, *, iterations: int = 20, lam: float = 0.5, mu: float = -0.53,
           weights: str = "uniform", rings: int = 1, constraint: Optional[Constraint] = None,
           gain=None, face_groups=None, slice_axis=None, slice_iterations: int = 0,
           structure: Optional[MeshStructure] = None, progress: Optional[Progress] = None,
           precision: str = "float64", keep_buffers: bool = True):
    """Taubin's λ|μ low-pass filter (Taubin 1995, "A signal processing approach to fair surface
    design"): each iteration is a Laplacian pass with factor ``lam`` > 0 then one with ``mu`` < −lam,
    which removes high frequencies without the shrinkage of plain Laplacian smoothing.

    Pass-band ``k_PB = 1/lam + 1/mu`` must be > 0 (0.1 for the defaults λ = 0.5, μ = −0.53).
    Bade et al. 2006: λ 0.5–0.7, ~20 iterations for compact and flat organs.

    slice_axis : (3,) vector, optional; slice_iterations : int
        Staircase-aware smoothing: first run ``slice_iterations`` extra λ|μ iterations whose
        displacement is projected onto ``slice_axis`` (see :func:`staircase_params`).

    Other parameters as :func:`laplacian`. Returns (N, 3) positions, the dtype of ``vertices``.
    """
    check_taubin(lam, mu)
    precision_dtype(precision)
    mode = weight_mode(weights)
    check_iterations(iterations)
    axis = None
    n_slice = 0
    if slice_axis is not None and slice_iterations:
        a = np.asarray(slice_axis, np.float64).reshape(-1)
        if a.shape != (3,) or not np.linalg.norm(a) > 0:
            raise AnatomeshError(f"slice_axis must be a non-zero 3-vector, got {slice_axis}")
        a = a / np.linalg.norm(a)
        axis = np.ascontiguousarray(np.outer(a, a))
        n_slice = int(slice_iterations)
    total = n_slice + int(iterations)
    if mode == 0 and check_rings(rings) == 1:
        return uniform_passes(vertices, faces, [lam, mu] * total,
                               [it < n_slice for it in range(total) for _ in (0, 1)], axis,
                               structure=structure, constraint=constraint, gain=gain,
                               face_groups=face_groups, progress=progress, per_report=2,
                               text="Taubin smoothing", precision=precision,
                               keep_buffers=keep_buffers)
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                  rings=rings, face_groups=face_groups, iterations=iterations)
    buf = np.empty_like(st.pos)
    for it in range(total):
        ax = axis if it < n_slice else None
        for factor in (lam, mu):
            umbrella(st, st.pos, buf, factor, mode=mode, axis=ax)
            st.pos, buf = buf, st.pos
        report(progress, (it + 1) / total, "Taubin smoothing")
    return finish(st)


def hc_laplacian(vertices, faces, *, iterations: int = 20, lam: float = 1.0, alpha: float = 0.1,
                 beta: float = 0.5, rings: int = 1, constraint: Optional[Constraint] = None,
                 gain=None, face_groups=None, structure: Optional[MeshStructure] = None,
                 progress: Optional[Progress] = None):
    """Laplacian smoothing with HC correction (Vollmer, Mencl & Müller 1999, "Improved Laplacian
    smoothing of noisy surface meshes").

    Each iteration: ``p = q + lam (mean(q_j) − q)``; ``b = p − (alpha o + (1 − alpha) q)``
    (``o`` the original positions, ``q`` the previous ones); ``p −= beta b + (1 − beta) mean(b_j)``:
    the Laplacian's shrinkage is pushed back. ``alpha`` in [0, 1] pulls towards the original,
    ``beta`` in [0, 1] weights a vertex's own correction against its neighbours'. With
    ``lam = 1`` this is Vollmer's original (Bade et al. 2006: λ 0.5–0.9, 20–50 iterations).

    Other parameters as :func:`laplacian`. Returns (N, 3) positions, the dtype of ``vertices``.
    """
    check_factor("lam", lam, 0.0, 1.0)
    if not (0 <= alpha <= 1 and 0 <= beta <= 1):
        raise AnatomeshError(f"alpha and beta must be in [0, 1], got alpha={alpha}, beta={beta}")
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                  rings=rings, face_groups=face_groups, iterations=iterations)
    orig = st.pos.copy()
    p = np.empty_like(st.pos)
    b = np.empty_like(st.pos)
    out = np.empty_like(st.pos)
    for it in range(int(iterations)):
        _k.hc_pass_a(st.pos, orig, p, b, st.offsets, st.nbr, float(lam), float(alpha))
        _k.hc_pass_b(st.pos, p, b, out, st.offsets, st.nbr, float(beta), st.gain)
        constrain(st, out)
        st.pos, out = out, st.pos
        report(progress, (it + 1) / iterations, "HC smoothing")
    return finish(st)


def mean_curvature_flow(vertices, faces, *, iterations: int = 10, step: float = 0.5,
                        constraint: Optional[Constraint] = None, gain=None, face_groups=None,
                        structure: Optional[MeshStructure] = None,
                        progress: Optional[Progress] = None):
    """Mean curvature flow with cotangent weights (Desbrun et al. 1999), explicit.

    Each iteration recomputes ``w_ij = (cot α_ij + cot β_ij) / 2`` (clipped at 0) and moves
    ``v' = v + step Σ w_ij (u_j − v) / Σ w_ij``: motion along the normal in proportion to
    curvature, nearly independent of the triangulation; stable for ``step`` in (0, 1]. It shrinks
    volume like the Laplacian; bound it with a constraint. On junction curves (``face_groups``)
    the 1D step uses uniform weights.

    Returns (N, 3) positions, the dtype of ``vertices``.
    """
    check_factor("step", step, 0.0, 1.0)
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                  face_groups=face_groups, iterations=iterations)
    s = st.s
    cot = np.empty(s.ring.shape[0])
    buf = np.empty_like(st.pos)
    curve = None if st.kind is None else np.repeat(st.kind == 1, np.diff(st.offsets))
    for it in range(int(iterations)):
        _k.cotan_weights(st.pos, s.faces, s.ring_offsets, s.ring, s.vf_offsets, s.vf, cot)
        w = cot if st.ring_index is None else cot[st.ring_index]
        if curve is not None:
            w[curve] = 1.0
        umbrella(st, st.pos, buf, step, mode=_k.WEIGHT_GIVEN, weights=w)
        st.pos, buf = buf, st.pos
        report(progress, (it + 1) / iterations, "mean curvature flow")
    return finish(st)


def normal_filter(vertices, faces, *, iterations: int = 5, kind: str = "mean", step: float = 1.0,
                  constraint: Optional[Constraint] = None, gain=None, face_groups=None,
                  structure: Optional[MeshStructure] = None, progress: Optional[Progress] = None):
    """Mean or median filtering of face normals with vertex update (Yagou, Ohtake & Belyaev 2002,
    "Mesh smoothing via mean and median filtering applied to face normals").

    Each iteration: face normals ``n_f``; filtered normals ``m_f`` over the faces sharing a vertex
    with ``f`` (``kind="mean"``: area-weighted mean; ``"median"``: the neighbour normal with the
    least summed angle to the others); then every vertex moves towards the planes through its
    faces' centroids with normals ``m_f``:
    ``p' = p + step Σ A_f m_f (m_f · (c_f − p)) / Σ A_f``. Sharp features survive better than
    with Laplacian filters (median more so). With ``face_groups``, junction-curve vertices take
    a 1D Laplacian pass (λ = 0.5) along their curve instead, corners stay.

    Returns (N, 3) positions, the dtype of ``vertices``.
    """
    if kind not in ("mean", "median"):
        raise AnatomeshError(f"normal filter kind must be 'mean' or 'median', got {kind!r}")
    check_factor("step", step, 0.0, 1.0)
    st = prepare(vertices, faces, structure=structure, constraint=constraint, gain=gain,
                  face_groups=face_groups, iterations=iterations)
    s = st.s
    m = s.n_faces
    fr_off, fr = s.face_ring()
    normals, filt = np.empty((m, 3)), np.empty((m, 3))
    areas, centroids = np.empty(m), np.empty((m, 3))
    movable = np.ones(s.n_vertices, np.uint8) if st.kind is None else (st.kind == 0).astype(np.uint8)
    buf = np.empty_like(st.pos)
    curve_rows = None
    if st.kind is not None and np.any(st.kind == 1):
        curve_rows = merge_rows(st.kind == 1, (st.offsets, st.nbr),
                                 (np.zeros(s.n_vertices + 1, np.int64), np.zeros(0, np.int32)))
    for it in range(int(iterations)):
        _k.face_normals_areas(st.pos, s.faces, normals, areas, centroids)
        if kind == "mean":
            _k.mean_filter_normals(normals, areas, fr_off, fr, filt)
        else:
            _k.median_filter_normals(normals, fr_off, fr, filt)
        _k.normal_vertex_update(st.pos, buf, s.vf_offsets, s.vf, filt, areas, centroids,
                                float(step), st.gain, movable)
        if curve_rows is not None:
            _curve_pass(st, buf, curve_rows)
        constrain(st, buf)
        st.pos, buf = buf, st.pos
        report(progress, (it + 1) / iterations, f"{kind} normal filtering")
    return finish(st)


def _curve_pass(st: Setup, dst: np.ndarray, curve_rows) -> None:
    """Junction-curve vertices: a uniform λ = 0.5 pass along the curve, from the old positions."""
    tmp = np.empty_like(st.pos)
    _k.umbrella_pass(st.pos, tmp, curve_rows[0], curve_rows[1], np.zeros(0), 0, 0.5, st.gain,
                     EYE, False)
    on_curve = st.kind == 1
    dst[on_curve] = tmp[on_curve]


#: filter name (:data:`~anatomesh.core.smooth.driver.METHODS`) → function
FILTERS = {
    "laplacian": laplacian,
    "taubin": taubin,
    "hc": hc_laplacian,
    "mean_curvature": mean_curvature_flow,
    "normal_mean": lambda v, f, **kw: normal_filter(v, f, kind="mean", **kw),
    "normal_median": lambda v, f, **kw: normal_filter(v, f, kind="median", **kw),
}
