"""Vertex and face neighbourhoods of a triangle mesh as compressed (CSR) arrays.

Smoothing visits every vertex's neighbours once per iteration; a generic half-edge structure
costs too many indirections for that. Following Mönch et al. 2012 ("Interactive mesh smoothing
for medical applications", Computer Graphics Forum 32(8)), neighbours are stored as
one flat index array plus per-vertex offsets: the neighbours of vertex ``i`` are
``indices[offsets[i]:offsets[i + 1]]``. The structure is built once per mesh (numba, linear
time) and reused across iterations and parameter changes: :func:`structure` caches
the last few it built, keyed by the faces array.

Example
-------
>>> s = structure(faces, len(vertices))
>>> s.ring_offsets, s.ring            # 1-ring CSR
>>> s.two_ring()                      # 2-ring CSR, built on first use
>>> s.vf_offsets, s.vf                # vertex → incident faces CSR
>>> s.padded(s.ring_offsets, s.ring)  # fixed-width neighbour columns for the smoothing hot loop, cached
"""
from __future__ import annotations

import hashlib
import weakref
from collections import OrderedDict
from typing import NamedTuple, Optional, Tuple

import numpy as np

from . import _neighbors_kernels as _k
from ..model.errors import AnatomeshError
from ..model.fingerprint import sample_fingerprint
from ..model.memory import release_free_memory

CSR = Tuple[np.ndarray, np.ndarray]


def check_faces(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Faces as contiguous int32 (M, 3) with every index in [0, n_vertices); else AnatomeshError."""
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3:
        raise AnatomeshError(f"faces must be an (M, 3) integer array of vertex indices, got shape "
                             f"{f.shape}")
    if f.size and not np.issubdtype(f.dtype, np.integer):
        raise AnatomeshError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
    f = np.ascontiguousarray(f, dtype=np.int32)
    if f.size and (int(f.min()) < 0 or int(f.max()) >= n_vertices):
        bad = int(f.max()) if f.max() >= n_vertices else int(f.min())
        raise AnatomeshError(f"faces refer to vertex {bad} but the mesh has {n_vertices} vertices: "
                             "pass the matching vertex array")
    return f


def vertex_faces(faces: np.ndarray, n_vertices: int) -> CSR:
    """Vertex → incident faces CSR ``(offsets (N+1,) int64, faces (3M,) int32)``, faces
    ascending per vertex; ``faces`` (M, 3) int, checked."""
    return _k.vertex_faces(check_faces(faces, int(n_vertices)), np.int64(n_vertices))


class PaddedRing(NamedTuple):
    """A neighbourhood as fixed-width columns (column-major ELLPACK), :meth:`MeshStructure.padded`.

    Column ``i`` of ``cols`` lists the neighbours of vertex ``i`` padded with ``N`` (the index of
    a zero column appended to the positions), so the smoothing loop has a fixed trip count, no
    branch and contiguous index loads over consecutive vertices. The few rows
    with more neighbours than the width (3 % of a marching-cubes surface's vertices for 8) end
    in a *helper column* ``N + 1 + h`` holding the sum of their other neighbours, listed in
    ``ext[:, h]`` and summed level by level before each pass (see
    ``_neighbors_kernels.padded_columns``): the positions then have ``N + 1 + H`` columns.
    """
    cols: np.ndarray       #: (width, N) uint32
    inv_count: np.ndarray  #: (N,) float: 1 / valence (0: no neighbour)
    ext: np.ndarray        #: (ext_width, H) uint32: what each helper column sums
    level_at: np.ndarray   #: (levels + 1,) int64: helper levels, to sum in this order

    @property
    def n_columns(self) -> int:
        """Columns of a position array for these rows: vertices, the zero pad, the helpers."""
        return self.cols.shape[1] + 1 + self.ext.shape[1]


class MeshStructure:
    """Neighbourhoods of one triangle mesh (connectivity only: positions may change freely).

    Attributes
    ----------
    n_vertices : int
    faces : (M, 3) int32
    ring_offsets, ring : (N+1,) int64, (R,) int32
        1-ring: vertices sharing an edge with each vertex (Mönch et al. 2012); built on
        first use.
    vf_offsets, vf : (N+1,) int64, (3M,) int32
        Faces incident to each vertex, ascending.
    """

    def __init__(self, faces: np.ndarray, n_vertices: int):
        self.n_vertices = int(n_vertices)
        self.faces = check_faces(faces, self.n_vertices)
        self.vf_offsets, self.vf = _k.vertex_faces(self.faces, np.int64(self.n_vertices))
        self._ring: Optional[CSR] = None
        self._two_ring: Optional[CSR] = None
        self._face_ring: Optional[CSR] = None
        self._feature: dict = {}
        self._components: Optional[np.ndarray] = None
        self._padded: dict = {}
        self._groups_seen: Optional[tuple] = None
        self._buffers: dict = {}

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def ring_offsets(self) -> np.ndarray:
        return self.one_ring()[0]

    @property
    def ring(self) -> np.ndarray:
        return self.one_ring()[1]

    def one_ring(self) -> CSR:
        """The 1-ring CSR ``(ring_offsets, ring)``, built on first use (and again after
        :meth:`release_ring`)."""
        if self._ring is None:
            self._ring = _k.one_ring(self.faces, np.int64(self.n_vertices), self.vf_offsets,
                                     self.vf)
        return self._ring

    def release_ring(self) -> None:
        """Drop the 1-ring (rebuilt on use): a one-shot smoothing of a label map needs it only
        to build its feature rings (memory: 4 bytes per ring entry + 8 per vertex)."""
        self._ring = None

    def valence(self) -> np.ndarray:
        """Number of 1-ring neighbours of each vertex, (N,) int64."""
        return np.diff(self.ring_offsets)

    def components(self) -> np.ndarray:
        """Connected component of each vertex through edges, (N,) int64 (unused vertices get
        their own component); cached."""
        if self._components is None:
            self._components = _k.components(self.faces, np.int64(self.n_vertices))
        return self._components

    def open_vertices(self) -> np.ndarray:
        """(N,) bool: vertices with an edge that has one face (an open boundary) or more than
        two (non-manifold), :meth:`feature_ring`'s ``kind != 0`` without groups, with no ring
        built."""
        return _k.open_vertices(self.faces, self.vf_offsets, self.vf)

    def two_ring(self) -> CSR:
        """2-ring CSR (neighbours and their neighbours, not the vertex itself); cached."""
        if self._two_ring is None:
            self._two_ring = _k.two_ring(self.ring_offsets, self.ring)
        return self._two_ring

    def face_ring(self) -> CSR:
        """Face → faces sharing a vertex with it (itself included) CSR; cached."""
        if self._face_ring is None:
            self._face_ring = _k.face_ring(self.faces, self.vf_offsets, self.vf)
        return self._face_ring

    def feature_ring(self, face_groups: Optional[np.ndarray] = None):
        """1-ring restricted along feature curves (open boundaries, junctions of 3+ labels).

        Parameters
        ----------
        face_groups : (M,) or (M, 2) integer, optional
            A group id per face, or a pair per face taken unordered (e.g. a label map set's
            ``face_labels``, the labels of the two sides: no group table to build); edges whose
            faces carry different groups, or that have one face or more than two, are feature
            edges.
            None: only open boundaries are features.

        Returns ``(offsets, indices, kind)``; kind (N,) int8 is 0 free, 1 on a feature curve
        (its ring is the two curve neighbours), 2 fixed (curve end or corner: empty ring).
        Cached per ``face_groups`` content; the same array passed again is recognised by identity
        and a sample of its entries (as :func:`structure` does for faces: after editing an array
        in place, pass a new one).
        """
        key = self._groups_key(face_groups)
        if key not in self._feature:
            self._feature[key] = _k.feature_rings(self.faces, self.ring_offsets, self.ring,
                                                  self.vf_offsets, self.vf,
                                                  _group_pairs(face_groups, self.n_faces))
            self._feature.pop(("index", key), None)
        self._last_feature_key = key
        return self._feature[key]

    def padded(self, offsets: np.ndarray, indices: np.ndarray, width: int = 8,
               dtype=np.float64, ext_width: int = 4) -> "PaddedRing":
        """A neighbourhood CSR of this structure (1-ring, feature ring, ...) as fixed-width
        columns (column-major ELLPACK) for the smoothing hot loop, cached: see
        :class:`PaddedRing`."""
        key = (id(indices), int(width), int(ext_width), np.dtype(dtype).str)
        hit = self._padded.get(key)
        if hit is not None and hit[0] is indices and hit[1] is offsets:
            return hit[2]
        cols, inv_count, ext, level_at = _k.padded_columns(offsets, indices, np.int64(width),
                                                           np.int64(ext_width))
        out = PaddedRing(cols, inv_count.astype(dtype), ext, level_at)
        self._padded[key] = (indices, offsets, out)
        return out

    def release_buffers(self) -> None:
        """Drop the padded rings, feature rings and working buffers of the smoothing passes
        (rebuilt on the next call): a one-shot smoothing frees them after its filter, and the
        heap's free pages go back to the system (:func:`~anatomesh.core.model.memory.
        release_free_memory`)."""
        self._padded.clear()
        self._feature.clear()
        self._buffers.clear()
        release_free_memory()

    def work_buffers(self, dtype=np.float64, count: int = 2,
                     columns: Optional[int] = None) -> Tuple[np.ndarray, ...]:
        """``count`` (3, columns) working arrays (one row per coordinate: the column layout of
        the smoothing passes; default N + 1 columns), allocated once per dtype and width; column
        N of the first two is zeroed (the pad of :meth:`padded`). Reused by every call on this
        structure, so a filter must copy its result out (the filters do); not for concurrent
        use."""
        width = self.n_vertices + 1 if columns is None else int(columns)
        key = (np.dtype(dtype), width)
        have = self._buffers.get(key, ())
        if len(have) < count:
            have = have + tuple(np.zeros((3, width), key[0]) for _ in range(count - len(have)))
            self._buffers[key] = have
        for buf in have[:2]:
            buf[:, self.n_vertices] = 0
        return have[:count]

    def _groups_key(self, face_groups) -> str:
        """Content key of a face-groups array; the full hash is skipped when the same array
        object comes again with the same sampled rows (re-smoothing with unchanged groups)."""
        if face_groups is None:
            return "none"
        arr = np.asarray(face_groups)
        if arr.shape not in ((self.n_faces,), (self.n_faces, 2)) or arr.dtype.kind not in "iub":
            raise AnatomeshError(f"face_groups must be {self.n_faces} integer group ids or "
                                 f"({self.n_faces}, 2) pairs, got {arr.dtype} {arr.shape}")
        sample = sample_fingerprint(arr)
        last = self._groups_seen
        if last is not None and last[0]() is face_groups and last[1] == sample:
            return last[2]
        # SHA-256 (hardware-accelerated) straight from the buffer: faster than blake2b of a copy
        content = hashlib.sha256(memoryview(np.ascontiguousarray(arr)).cast("B")).hexdigest()
        key = f"{arr.dtype.str}{arr.shape}:{content}"
        try:
            self._groups_seen = (weakref.ref(face_groups), sample, key)
        except TypeError:  # a list: no identity to rely on
            self._groups_seen = None
        return key

    def feature_ring_index(self, face_groups: Optional[np.ndarray] = None) -> np.ndarray:
        """For each entry ``(i, j)`` of :meth:`feature_ring`: its position in the 1-ring CSR
        (so per-edge weights computed on the 1-ring can be picked for it); cached."""
        offsets, idx, _ = self.feature_ring(face_groups)
        key = ("index", self._last_feature_key)
        if key not in self._feature:
            n = np.int64(max(self.n_vertices, 1))
            rows = np.repeat(np.arange(self.n_vertices, dtype=np.int64), np.diff(self.ring_offsets))
            full = rows * n + self.ring  # sorted: rows ascending, neighbours ascending in a row
            sub = np.repeat(np.arange(self.n_vertices, dtype=np.int64), np.diff(offsets))
            self._feature[key] = np.searchsorted(full, sub * n + idx)
        return self._feature[key]


def _group_pairs(face_groups: Optional[np.ndarray], n_faces: int) -> np.ndarray:
    """Face groups as the (M, 2) int32 pairs :func:`_k.feature_rings` compares unordered: pairs
    as they are, ids as (id, id), none as zeros; values beyond int32 renumbered (same equalities)."""
    if face_groups is None:
        return np.zeros((n_faces, 2), np.int32)
    g = np.asarray(face_groups).reshape(n_faces, -1)
    wide = not np.can_cast(g.dtype, np.int32)
    if wide and g.size and (g.min() < np.iinfo(np.int32).min or g.max() > np.iinfo(np.int32).max):
        g = np.unique(g, return_inverse=True)[1].reshape(g.shape)
    if g.shape[1] == 1:
        g = np.repeat(g, 2, axis=1)
    return np.ascontiguousarray(g, np.int32)


# -------------------------------------------------------------------------------------------
# cache
# -------------------------------------------------------------------------------------------
_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()
_CACHE_SIZE = 4


def structure(faces: np.ndarray, n_vertices: Optional[int] = None) -> MeshStructure:
    """The :class:`MeshStructure` of ``faces``, built once and cached.

    The cache holds the last four structures, keyed by the identity of the faces array, its
    shape, ``n_vertices`` and a hash of a sample of its rows. Editing a faces array in place is
    not reliably detected: build a new array (or call :func:`clear_cache`) after doing so.

    Parameters
    ----------
    faces : (M, 3) int array
    n_vertices : int, optional
        Number of vertices (default: ``faces.max() + 1``).
    """
    f = np.asarray(faces)
    if n_vertices is None:
        n_vertices = int(f.max()) + 1 if f.size else 0
    key = (id(faces), f.shape, int(n_vertices))
    hit = _CACHE.get(key)
    fp = sample_fingerprint(f)
    if hit is not None:
        ref, fp_cached, s = hit
        if ref() is faces and fp_cached == fp:
            _CACHE.move_to_end(key)
            return s
    s = MeshStructure(f, int(n_vertices))
    try:
        ref = weakref.ref(faces)
    except TypeError:  # e.g. a list: no identity to rely on, do not cache
        return s
    _CACHE[key] = (ref, fp, s)
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return s


def clear_cache() -> None:
    """Forget every cached structure."""
    _CACHE.clear()
