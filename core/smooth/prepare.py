"""The per-call set-up shared by the general (CSR) smoothing filters: checked positions, the
neighbourhood (1-ring, 2-ring or junction-aware feature ring), gain and constraint arrays, and one
constrained umbrella pass (Jacobi update over a CSR ring; Mönch, Lawonn, Tietjen & Preim 2012,
"Interactive mesh smoothing for medical applications")."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import _filter_kernels as _k
from .checks import (check_gain, check_iterations, check_rings, check_vertices, mesh_structure,
                     out_dtype)
from .constraints import EYE, Constraint
from ..geometry.neighbors import MeshStructure
from ..model.errors import AnatomeshError

WEIGHTS = {"uniform": 0, "edge_length": 1}


@dataclass
class Setup:
    """Working state of one general filter call."""
    pos: np.ndarray            # (N, 3) float64 working positions (a copy)
    dtype: np.dtype            # output dtype
    s: MeshStructure
    offsets: np.ndarray        # neighbourhood CSR used by the filter
    nbr: np.ndarray
    ring_index: Optional[np.ndarray]  # per entry of (offsets, nbr): index into the 1-ring (None: same)
    kind: Optional[np.ndarray]        # (N,) int8 vertex kind from face_groups, or None
    gain: np.ndarray
    cons: tuple


def prepare(vertices, faces, *, structure, constraint, gain, rings=1, face_groups=None,
            iterations=0) -> Setup:
    """Check the inputs and set up one general filter call (positions copied to float64)."""
    v = check_vertices(vertices)
    dtype = out_dtype(vertices)
    check_iterations(iterations)
    s = mesh_structure(faces, v.shape[0], structure)
    kind = None
    ring_index = None
    if face_groups is None:
        offsets, nbr = (s.ring_offsets, s.ring) if check_rings(rings) == 1 else s.two_ring()
    else:
        offsets, nbr, kind = s.feature_ring(face_groups)
        if check_rings(rings) == 2:
            offsets, nbr = merge_rows(kind == 0, s.two_ring(), (offsets, nbr))
        else:
            ring_index = s.feature_ring_index(face_groups)
    g = check_gain(gain, v.shape[0])
    cons = (constraint or Constraint()).arrays(v)
    st = Setup(v.copy(), dtype, s, offsets, nbr, ring_index, kind, g, cons)
    constrain(st, st.pos)  # a start outside its box is moved in first
    return st


def merge_rows(take_a: np.ndarray, a, b):
    """CSR whose row i is row i of ``a`` where ``take_a[i]`` else row i of ``b``."""
    (oa, ia), (ob, ib) = a, b
    length = np.where(take_a, np.diff(oa), np.diff(ob))
    offsets = np.zeros(len(length) + 1, np.int64)
    np.cumsum(length, out=offsets[1:])
    row = np.repeat(np.arange(len(length)), length)
    k = np.arange(offsets[-1]) - offsets[row]
    ta = take_a[row]
    out = np.empty(offsets[-1], np.int32)
    out[ta] = ia[oa[row[ta]] + k[ta]]
    out[~ta] = ib[ob[row[~ta]] + k[~ta]]
    return offsets, out


def finish(st: Setup) -> np.ndarray:
    """The working positions in the output dtype."""
    return st.pos.astype(st.dtype, copy=False)


def constrain(st: Setup, pos: np.ndarray) -> None:
    """Put every vertex back into its constraint (in place), if there is one."""
    if st.cons[0] != 0 or st.cons[4] < np.inf:
        _k.constrain_all(pos, *st.cons)


def umbrella(st: Setup, src, dst, factor, *, mode=0, weights=None, axis=None):
    """One umbrella pass ``src`` → ``dst`` (weights: ``mode``), then the constraint."""
    w = np.zeros(0) if weights is None else weights
    _k.umbrella_pass(src, dst, st.offsets, st.nbr, w, mode, float(factor), st.gain,
                     EYE if axis is None else axis, axis is not None)
    constrain(st, dst)


def weight_mode(weights: str) -> int:
    if weights not in WEIGHTS:
        raise AnatomeshError(f"weights must be 'uniform' or 'edge_length', got {weights!r}")
    return WEIGHTS[weights]

