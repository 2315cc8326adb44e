"""The fast uniform umbrella passes of :func:`~anatomesh.core.smooth.filters.taubin` and
:func:`~anatomesh.core.smooth.filters.laplacian`: padded neighbour columns and working buffers cached
in the :class:`~anatomesh.core.geometry.neighbors.MeshStructure`, positions in the column layout of
``_pass_kernels`` in the constraint's normalised frame (where the box is a min/max), the
constraint fused into each pass, all passes in one numba call."""
from __future__ import annotations

from typing import Optional

import numpy as np

from . import _pass_kernels as _k
from .checks import check_gain, mesh_structure, out_dtype, precision_dtype
from .constraints import EYE, Constraint
from ..model.errors import AnatomeshError
from ..model.progress import report


def uniform_passes(vertices, faces, factors, on_axis, axis, *, structure, constraint, gain,
                   face_groups, progress, per_report: int, text: str,
                   precision: str = "float64", keep_buffers: bool = True) -> np.ndarray:
    """Uniform umbrella passes ``factors[p]`` (the 1-ring or feature ring), the hot path of
    :func:`taubin` and :func:`laplacian`: padded neighbour columns and working buffers cached
    in the structure, positions in the column layout of ``_pass_kernels`` (in the
    constraint's normalised frame, where the box is a min/max: the uniform umbrella commutes
    with linear maps), constraint fused into each pass, all passes in one numba call when there
    is no ``progress`` (else ``per_report`` passes per call). Same result as the CSR
    :func:`~anatomesh.core.smooth.prepare.umbrella` passes (differences ~1e-13 mm in float64
    from the order of operations; ~1e-4 mm in float32, the precision Blender stores positions
    in). ``keep_buffers=False`` (one-shot runs, memory): the neighbourhood CSR is freed once
    its padded columns exist (and the structure's 1-ring: rebuilt if used again), the columns
    and buffers before the result is allocated."""
    v = np.asarray(vertices)
    if v.ndim != 2 or v.shape[1] != 3:
        raise AnatomeshError(f"vertices must be an (N, 3) array of positions in mm, got shape {v.shape}")
    if not np.issubdtype(v.dtype, np.number):
        raise AnatomeshError(f"vertices must be numeric, got dtype {v.dtype}")
    if not np.isfinite(v).all():
        raise AnatomeshError("vertices contain NaN or infinite coordinates; fix the mesh first")
    dt = precision_dtype(precision)
    n = v.shape[0]
    s = mesh_structure(faces, n, structure)
    if face_groups is None:
        offsets, nbr = s.ring_offsets, s.ring
    else:
        offsets, nbr, _ = s.feature_ring(face_groups)
    ring = s.padded(offsets, nbr, _k.PAD_WIDTH, dt, _k.EXT_WIDTH)
    if not keep_buffers:  # memory: the ring's CSR and the 1-ring are not needed once padded
        del offsets, nbr
        s.release_buffers()
        s.release_ring()
    g = check_gain(gain, n)
    c = constraint or Constraint()
    kind, center, frame, frame_inv, radius, start = c.arrays(v)
    boxed, capped = kind != 0, radius < np.inf
    bufs = s.work_buffers(dt, 2 + boxed + capped, ring.n_columns)  # memory: only those used
    a, b = bufs[:2]
    box_c = bufs[2] if boxed else None  # None: numba compiles the step out of the pass
    cap_s = bufs[-1] if capped else None
    to_frame, metric = (frame, frame_inv) if boxed else (EYE, EYE)
    _k.to_columns(v, to_frame, a)
    if boxed:
        _k.to_columns(center, frame, box_c)
    if capped:
        _k.to_columns(start, to_frame, cap_s)
    r2, metric = dt.type(radius * radius if capped else 0.0), metric.astype(dt)
    if (boxed or capped) and not (c.origin is None and c.center is None):
        # the start is not the centre of the box or cap: move it in first
        _k.constrain_columns(a, n, box_c, cap_s, r2, metric, kind == 2)
    if axis is not None:
        axis = (to_frame @ axis @ np.linalg.inv(to_frame)).astype(dt)
    along = _projector_axis(axis)
    factors = np.asarray(factors, dt)
    on_axis = np.asarray(on_axis, np.bool_)
    total = factors.shape[0]
    step = total if progress is None else max(1, int(per_report))
    which, src_dst = 0, None
    for p0 in range(0, total, step):
        src_dst = (a, b) if which == 0 else (b, a)
        r = _k.padded_passes(*src_dst, *ring, factors[p0:p0 + step], on_axis[p0:p0 + step],
                             None if g.size == 0 else g.astype(dt), axis, along, kind == 2, box_c,
                             cap_s, r2, metric)
        which ^= r
        report(progress, min(p0 + step, total) / total, text)
    result = a if which == 0 else b
    if not keep_buffers:  # memory: only the result's buffer is left when the output is made
        del ring, bufs, a, b, src_dst, box_c, cap_s
        s.release_buffers()
    out = np.empty((n, 3), out_dtype(vertices))
    _k.from_columns(result, frame_inv if boxed else EYE, out)
    return out


def _projector_axis(axis: Optional[np.ndarray]) -> int:
    """k when the (3, 3) axis map is exactly ``e_k e_kᵀ`` (moves along frame axis k only: the
    passes then gather that coordinate alone), else -1."""
    if axis is None or np.count_nonzero(axis) != 1:
        return -1
    k = int(np.argmax(np.abs(np.diag(axis))))
    return k if axis[k, k] == 1 else -1
