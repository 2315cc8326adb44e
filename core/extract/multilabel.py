"""Conforming multi-label surfaces from a label map, in one pass.

Method: cuberille / surface-nets topology (Gibson 1998, "Constrained elastic surface nets";
``vtkSurfaceNets3D`` has the same connectivity). The boundary between two voxels of different
labels is their shared voxel face, a unit square in index space, stored once as two triangles
tagged (inside label, outside label) and shared by both labels' shells. Vertices are voxel
corners (lattice points), so two touching labels use the very same vertices along their
interface, and each raw shell encloses exactly its voxels. Outside the grid counts as background,
so shells close at the border. Per-label fans around a corner are resolved by the table in
``shell_table.py`` (6-connectivity for each label, joined where needed), which keeps every
per-label shell a closed, oriented 2-manifold.
"""
from __future__ import annotations

import warnings as _warnings
from typing import Iterable, List, Optional, Union

import numba
import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import distinct_color, label_table_for
from ..model.progress import Progress, report
from ..model.surfaceset import SurfaceSet
from ..model.volume import SPACES, Volume, convert_affine
from ..model.labels import LabelInfo
from . import _multilabel_kernels as K
from .shell_table import tables

MAX_LABEL = 65535
#: Below this many (cropped, padded) voxels the two parallel kernels' serial twins run: starting
#: threads costs more than it saves there, and far more when other processes keep the cores busy
#: (the serial twins also compile in a fraction of the time: a first run on a small map is quicker).
PARALLEL_MIN_VOXELS = 4_000_000


def label_surfaces(volume_or_array: Union[Volume, np.ndarray],
                   values: Optional[Iterable[int]] = None, affine: Optional[np.ndarray] = None,
                   space: Optional[str] = None, background: int = 0,
                   progress: Optional[Progress] = None) -> SurfaceSet:
    """One closed, 2-manifold, outward-oriented shell per label, with shared seams.

    Parameters
    ----------
    volume_or_array : Volume or ndarray (I, J, K)
        Label map of integers in 0..65535 (float arrays must hold whole numbers).
    values : int or iterable of int, optional
        Labels to mesh (default: all present). Other labels count as background; work is
        cropped to the chosen labels' bounding box plus one voxel. Requested values absent from
        the map are skipped with a warning in ``SurfaceSet.warnings`` (and a Python warning).
    affine : (4, 4) array, optional
        Voxel index → mm at voxel centres (default: the volume's, or identity for an array).
    space : "RAS" or "LPS", optional
        For a Volume: express the output in this space (default: the volume's). For an array:
        the space ``affine`` maps into (default "RAS").
    background : int
        The value of "no structure" (default 0). It is stored as is, as the outside label of the
        outer surface faces.
    progress : callable, optional
        ``progress(fraction, text)``.

    Returns
    -------
    SurfaceSet
        Vertices at voxel corners in mm; faces with (inside, outside) labels, the background
        only ever outside; per-label shells via ``SurfaceSet.shell(value)``; ``voxel_counts``
        (each raw shell encloses exactly count x voxel volume). An all-background map gives an
        empty set. The numbering of vertices and faces does not depend on the thread count.

    Raises
    ------
    AnatomeshError
        For a map that is not 3D, holds values outside 0..65535 or fractions, or a bad affine.
    """
    data, A, space_out, names = _inputs(volume_or_array, affine, space)
    bg = _label_value(background, "background")
    wanted = None if values is None else sorted({_label_value(v, "label value") for v in
                                                 np.atleast_1d(np.asarray(values, object))})
    warn = []
    if wanted is not None and bg in wanted:
        warn.append(f"label {bg} is the background value; it gets no surface")
        wanted.remove(bg)
    report(progress, 0.0, "finding labels")
    # work in the array's memory order: a C-order view, the affine's columns permuted to match
    axes = np.argsort([-st for st in data.strides], kind="stable")
    P, lo, top = _crop(data.transpose(axes), bg, wanted)
    report(progress, 0.2, "making faces")
    origin = A[:3, 3] + A[:3, :3] @ (_unpermute(lo, axes) - 1.5)
    M = np.ascontiguousarray(A[:3, :3][:, axes])
    flip = int(np.linalg.det(M) < 0)
    vertices, faces, face_labels, lattice, splits = _surface(P, bg, lo, origin, M, flip)
    report(progress, 0.9, "counting voxels")
    counts = np.zeros(top + 1, np.int64)
    K.voxel_counts(faces, face_labels, lattice, flip, counts)
    if np.any(axes != np.arange(3)):  # back to the volume's (i, j, k), in place
        K.permute_columns(lattice, np.argsort(axes))
    present = [int(v) for v in np.flatnonzero(counts > 0) if v != bg]
    missing = [v for v in (wanted or []) if v not in set(present)]
    if missing:
        warn.append(f"labels not in the volume, no surface made: {missing}")
    for w in warn:
        _warnings.warn(w, stacklevel=2)
    report(progress, 1.0, "label surfaces done")
    return SurfaceSet(vertices, faces, face_labels, lattice, A, space_out,
                      _label_table(present, names), splits, bg,
                      {v: int(counts[v]) for v in present}, warn)


def _crop(data: np.ndarray, bg: int, wanted: Optional[List[int]]):
    """``(P, lo, top)``: the labels' bounding box (from index ``lo``) padded with one voxel of
    background, uint8 or uint16, labels not in ``wanted`` set to background; ``top`` bounds the
    values in P. No labels: a 3x3x3 block of background. ``data`` should be C-ordered (rows are
    read contiguously)."""
    top = max(_max_label(data), bg)
    select = np.zeros(top + 1, np.uint8)  # 1 for the labels to keep, when it is used
    use_select = wanted is not None or bg > np.iinfo(data.dtype).max
    if wanted is None:
        select[:] = 1  # only used when the background cannot occur in this dtype
    else:
        select[[v for v in wanted if v <= top]] = 1
        top = max([bg] + [v for v in wanted if v <= top])
    box = np.empty(6, np.int64)
    K.bounding_box(data, min(bg, np.iinfo(data.dtype).max), select, use_select,
                   np.empty((data.shape[0], 4), np.int64), box)
    dtype = np.uint8 if top <= 255 else np.uint16
    if box[0] > box[1]:
        return np.full((3, 3, 3), bg, dtype), np.zeros(3, np.int64), top
    lo, hi = box[0::2], box[1::2]
    P = np.empty(tuple(int(h - l + 3) for l, h in zip(lo, hi)), dtype)  # crop_pad fills all
    lut = np.where(select > 0, np.arange(select.size), bg).astype(dtype)
    K.crop_pad(data, int(lo[0]), int(lo[1]), int(lo[2]), lut, wanted is not None, dtype(bg), P)
    return P, lo, top


def _surface(P, bg, lo, origin, M, flip):
    """The kernels' three passes over ``P``: count, emit, split. Returns vertices, faces,
    face_labels, lattice (in P's axis order) and splits (ordered by face)."""
    parallel = P.size >= PARALLEL_MIN_VOXELS
    nv, nq = np.zeros(P.shape[0] + 1, np.int64), np.zeros(P.shape[0] + 1, np.int64)
    if parallel:
        K.count(P, nv, nq)
    else:
        K.count_serial(P, nv, nq, np.zeros((2, P.shape[2]), np.uint8))
    voff = np.cumsum(nv) - nv
    qoff = np.cumsum(nq) - nq
    n, q = int(nv.sum()), int(nq.sum())
    cycle, joinable, needs = tables()
    vertices = np.empty((n, 3), np.float32)
    lattice = np.empty((n, 3), np.int32)
    complex_ = np.empty(n, np.uint8)
    faces = np.empty((2 * q, 3), np.int32)
    face_labels = np.empty((2 * q, 2), np.int32)
    offset = np.asarray(lo, np.int64)
    if parallel:
        nchunks = max(1, min(P.shape[0] - 1, 4 * numba.get_num_threads()))
        K.emit(P, P.dtype.type(bg), voff, qoff, origin, M, offset, flip, needs, nchunks,
               vertices, lattice, complex_, faces, face_labels)
    else:  # one run of planes on this thread
        mask = np.zeros(8 * (P.shape[2] // 8 + 1), np.uint8)
        K.emit_run(P, P.dtype.type(bg), voff, qoff, origin, M, offset, flip, needs, 1, 0,
                   vertices, lattice, complex_, faces, face_labels,
                   np.empty((2, P.shape[1] * P.shape[2]), np.int32), mask, mask.view(np.uint64))
    args = (P, bg, lattice, offset, faces, face_labels, complex_, cycle, joinable)
    splits = np.empty((K.splits(*args, np.zeros((0, 4), np.int32)), 4), np.int32)  # count, fill
    if len(splits):
        K.splits(*args, splits)
    splits = splits[np.argsort(splits[:, 0], kind="stable")]
    return vertices, faces, face_labels, lattice, splits


def _unpermute(x, axes) -> np.ndarray:
    """Values given per transposed axis, back in the volume's axis order (float64)."""
    out = np.empty(3)
    out[np.asarray(axes)] = np.asarray(x, np.float64)
    return out


# ---------------------------------------------------------------------------------------------
# inputs
# ---------------------------------------------------------------------------------------------
def _inputs(obj, affine, space):
    """(data, affine, space, names) from a Volume or an array, validated."""
    names = None
    if isinstance(obj, Volume):
        data = obj.data
        A = obj.affine if affine is None else np.asarray(affine, np.float64)
        src_space = obj.space
        names = obj.labels
        if space is not None:
            _check_space(space)
            A = convert_affine(A, src_space, space)
        space = src_space if space is None else space
    else:
        data = np.asarray(obj)
        A = np.eye(4) if affine is None else np.asarray(affine, np.float64)
        space = "RAS" if space is None else space
        _check_space(space)
    if data.ndim != 3:
        raise AnatomeshError(f"a label map must be 3D; got shape {data.shape}")
    if A.shape != (4, 4) or not np.all(np.isfinite(A)) or abs(np.linalg.det(A[:3, :3])) < 1e-12:
        raise AnatomeshError("the affine must be a finite, invertible 4x4 voxel→mm matrix")
    if data.dtype == bool:
        data = data.view(np.uint8)
    elif data.dtype.kind == "f":
        if not np.all(np.isfinite(data)) or not np.array_equal(data, np.round(data)):
            raise AnatomeshError("a label map must hold whole numbers; this one has fractions "
                                 "or NaN — is it a scan rather than a segmentation?")
        if data.size and (data.min() < 0 or data.max() > MAX_LABEL):
            raise AnatomeshError(_range_message(data.min() if data.min() < 0 else data.max()))
        data = data.astype(np.uint16)
    elif data.dtype.kind not in "iu":
        raise AnatomeshError(f"a label map must hold integers; got dtype {data.dtype}")
    return data, A, space, names


def _check_space(space):
    if space not in SPACES:
        raise AnatomeshError(f"space must be one of {SPACES}, got {space!r}")


def _label_value(v, what) -> int:
    try:
        iv = int(v)
    except (TypeError, ValueError):
        raise AnatomeshError(f"{what} must be an integer in 0..{MAX_LABEL}; got {v!r}") from None
    if iv != v or not 0 <= iv <= MAX_LABEL:
        raise AnatomeshError(f"{what} must be an integer in 0..{MAX_LABEL}; got {v!r}")
    return iv


def _range_message(v) -> str:
    return (f"label values must be integers in 0..{MAX_LABEL}; found {v!r} — is this a scan "
            "rather than a segmentation?")


def _max_label(data: np.ndarray) -> int:
    """The largest value of an integer map, checking all values lie in 0..65535."""
    if data.size == 0:
        return 0
    if data.dtype == np.uint8:
        return 255  # an upper bound is enough here; saves a pass
    hi = int(data.max())
    if data.dtype != np.uint16:
        lo = int(data.min())
        if lo < 0 or hi > MAX_LABEL:
            raise AnatomeshError(_range_message(lo if lo < 0 else hi))
    return hi


def _label_table(values, names):
    """Name and colour of each value: the volume's table, else generic names and colours."""
    table = label_table_for(values, names or None)
    for v in values:  # label_table_for skips 0 (background by convention); keep a real label 0
        if v not in table:
            info = (names or {}).get(v)
            table[v] = info if isinstance(info, LabelInfo) else LabelInfo(v, f"label_{v}",
                                                                          distinct_color(v))
    return {v: table[v] for v in values}
