"""Where a vertex may go while it is smoothed, and how strongly it is smoothed.

* :class:`Constraint` — after every pass each vertex is put back into a box (Gibson 1998,
  "Constrained elastic surface nets: generating smooth surfaces from binary segmented data") or
  a diamond (L1 ball; Bade, Konrad & Preim 2007, "Reducing artifacts in surface meshes
  extracted from binary volumes") around its cell or start, and/or within
  ``max_deviation`` mm of its start (clamped per pass: a hard bound).
  :func:`lattice_constraint` builds the voxel-cell box of a label surface,
  :func:`voxel_constraint` a box of ± half a voxel around each start; the box half-sizes are per
  voxel axis, so anisotropic voxels get an anisotropic box.
* :func:`staircase_params` — staircase-aware smoothing for thick slices (after Mönch, Adler &
  Preim 2010, "Staircase-aware smoothing of medical surface meshes"): extra passes that move
  vertices only along the slice axis, inside the box.
* :func:`distance_gain` — per-vertex damping in [0, 1] that fades smoothing where another
  structure is nearer than a distance (Mönch, Gasteiger, Janiga, Theisel & Preim 2011,
  "Context-aware mesh smoothing for biomedical applications").
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from . import _filter_kernels as _k
from .checks import check_vertices
from ..model.errors import AnatomeshError

KINDS = {"none": 0, "box": 1, "diamond": 2}
EMPTY3 = np.zeros((0, 3))
EYE = np.eye(3)


@dataclass
class Constraint:
    """Where each vertex may go while it is smoothed.

    Attributes
    ----------
    kind : {"none", "box", "diamond"}
        ``box``: ``|u_k| <= half_k`` per frame axis (Gibson 1998, constrained elastic surface
        nets); ``diamond``: ``Σ |u_k| / half_k <= 1`` (Bade et al. 2007), where
        ``u = frame @ (p − center)``.
    center : (N, 3) float, mm, optional
        Centre of each vertex's box or diamond; None = the vertex's start position.
    frame : (3, 3) float, optional
        Linear map from mm offsets to the frame the box is expressed in; None = identity (mm).
        For voxel cells use ``inv(affine[:3, :3])`` (voxel index units).
    half : (3,) float
        Half extents along the frame axes (0.5 = half a voxel in the voxel frame).
    max_deviation : float, optional
        Also keep every vertex within this distance (mm) of its start; clamped after every
        pass, so it is a hard bound on vertex displacement.
    origin : (N, 3) float, mm, optional
        The start positions ``center`` (when None) and ``max_deviation`` refer to; None = the
        positions the filter is given. Set it (see :meth:`anchored`) when a later step continues
        from already-smoothed positions, so the bounds stay relative to the unsmoothed surface.
    """

    kind: str = "none"
    center: Optional[np.ndarray] = None
    frame: Optional[np.ndarray] = None
    half: Sequence[float] = (0.5, 0.5, 0.5)
    max_deviation: Optional[float] = None
    origin: Optional[np.ndarray] = None

    def anchored(self, origin: np.ndarray) -> "Constraint":
        """The same constraint with its bounds fixed to ``origin`` (N, 3) mm (the unsmoothed
        positions), whatever positions a later filter starts from."""
        o = np.ascontiguousarray(origin, np.float64)
        return Constraint(self.kind, o if self.center is None else self.center, self.frame,
                          self.half, self.max_deviation, o)

    def arrays(self, start: np.ndarray):
        """Kernel arguments ``(kind, center, frame, frame_inv, radius, start)`` (frame scaled by 1/half)."""
        if self.kind not in KINDS:
            raise AnatomeshError(f"constraint kind must be one of {tuple(KINDS)}, got {self.kind!r}")
        kind = KINDS[self.kind]
        n = start.shape[0]
        if self.origin is not None:
            start = np.ascontiguousarray(self.origin, np.float64)
            if start.shape != (n, 3):
                raise AnatomeshError(f"constraint origin must be ({n}, 3) like the vertices, got "
                                     f"{start.shape}")
        frame = EYE if self.frame is None else np.asarray(self.frame, np.float64)
        if frame.shape != (3, 3) or not np.all(np.isfinite(frame)) or abs(np.linalg.det(frame)) < 1e-12:
            raise AnatomeshError("constraint frame must be an invertible 3x3 matrix (e.g. the "
                                 "inverse of the affine's 3x3 part)")
        half = np.asarray(self.half, np.float64).reshape(-1)
        if half.size == 1:
            half = np.repeat(half, 3)
        if half.shape != (3,) or not np.all(half > 0):
            raise AnatomeshError(f"constraint half extents must be three positive numbers, got {self.half}")
        center = EMPTY3
        if kind:
            center = start if self.center is None else np.ascontiguousarray(self.center, np.float64)
            if center.shape != (n, 3):
                raise AnatomeshError(f"constraint center must be ({n}, 3) like the vertices, got "
                                     f"{center.shape}")
        radius = np.inf
        if self.max_deviation is not None:
            radius = float(self.max_deviation)
            if not radius >= 0:
                raise AnatomeshError(f"max_deviation must be >= 0 mm, got {self.max_deviation}")
        scaled = frame / half[:, None]  # normalised frame: the set is max|u| <= 1 or sum|u| <= 1
        return (kind, center, np.ascontiguousarray(scaled), np.ascontiguousarray(np.linalg.inv(scaled)),
                radius, start)


def lattice_constraint(affine: np.ndarray, lattice: np.ndarray, *, half: float = 0.5,
                       kind: str = "box", max_deviation: Optional[float] = None) -> Constraint:
    """The voxel-cell box of a label surface (Gibson 1998, constrained elastic surface nets).

    Parameters
    ----------
    affine : (4, 4) voxel index → mm (voxel centres)
    lattice : (N, 3) int
        Lattice corner of each vertex: vertex ``(a, b, c)`` sits at voxel-index position
        ``(a − 0.5, b − 0.5, c − 0.5)``, the centre of its voxel-sized cell.
    half : float
        Half extent in voxels (0.5 = the whole cell; smaller keeps neighbouring vertices apart).
    kind : "box" or "diamond"
    """
    A = check_affine(affine)
    lat = np.asarray(lattice)
    if lat.ndim != 2 or lat.shape[1] != 3 or lat.dtype.kind not in "iu":
        raise AnatomeshError(f"lattice must be (N, 3) integer corners, got {lat.dtype} {lat.shape}")
    center = np.empty((lat.shape[0], 3))
    _k.lattice_centres(np.ascontiguousarray(lat, np.int32), A, center)  # corners of a grid: int32
    return Constraint(kind=kind, center=center, frame=np.linalg.inv(A[:3, :3]), half=(half,) * 3,
                      max_deviation=max_deviation)


def voxel_constraint(affine: np.ndarray, *, half: float = 0.5, kind: str = "box",
                     max_deviation: Optional[float] = None) -> Constraint:
    """A box (or diamond) of ± ``half`` voxel along each voxel axis around each start position.

    For surfaces extracted from a voxel grid without a lattice (marching cubes); ``affine`` is the
    grid's voxel index → mm matrix, so the box follows anisotropic spacing and oblique axes.
    """
    A = check_affine(affine)
    return Constraint(kind=kind, frame=np.linalg.inv(A[:3, :3]), half=(half,) * 3,
                      max_deviation=max_deviation)


def check_affine(affine) -> np.ndarray:
    A = np.asarray(affine, np.float64)
    if A.shape != (4, 4) or not np.all(np.isfinite(A)) or abs(np.linalg.det(A[:3, :3])) < 1e-12:
        raise AnatomeshError("affine must be a finite, invertible 4x4 voxel-index-to-mm matrix")
    return A


def staircase_params(affine: np.ndarray, iterations: int, *, min_ratio: float = 1.5,
                     max_factor: float = 3.0) -> dict:
    """Slice-axis passes for thick slices (staircase-aware smoothing after Mönch et al. 2010).

    With slices ``r`` times thicker than the in-plane spacing, terraces are about ``r`` voxels
    wide and a Laplacian needs ~r² times more passes to turn them into ramps. Moving vertices
    only along the slice axis (inside the voxel-cell box) does that without touching in-plane
    detail. Returns ``{"slice_axis": (3,) unit vector in mm, "slice_iterations": n}``, with
    ``n = iterations * min(r − 1, max_factor)``, or zero passes when ``r < min_ratio``.
    """
    A = check_affine(affine)
    spacing = np.linalg.norm(A[:3, :3], axis=0)
    k = int(np.argmax(spacing))
    ratio = float(spacing[k] / spacing.min())
    if ratio < min_ratio:
        return {"slice_axis": None, "slice_iterations": 0}
    n = int(round(iterations * min(ratio - 1.0, max_factor)))
    return {"slice_axis": A[:3, k] / spacing[k], "slice_iterations": n}


def distance_gain(vertices: np.ndarray, groups: np.ndarray, distance: float) -> np.ndarray:
    """Distance-aware damping (Mönch et al. 2011): a per-vertex smoothing gain in [0, 1].

    ``gain = min(1, d / distance)`` where ``d`` is the distance (mm) from the vertex to the nearest
    vertex of another group (another structure); so two structures closer than ``distance``
    keep their gap, far ones smooth fully. Vertices with group < 0 get gain 1 and are ignored as
    neighbours. Nearest vertices are found with a uniform grid hash of cell ``distance`` (numba).

    Parameters
    ----------
    vertices : (N, 3) float, mm
    groups : (N,) int — structure id per vertex (e.g. connected component of the surface)
    distance : float, mm, > 0
    """
    v = check_vertices(vertices)
    g = np.ascontiguousarray(groups, dtype=np.int64).ravel()
    if g.shape[0] != v.shape[0]:
        raise AnatomeshError(f"groups has {g.shape[0]} entries for {v.shape[0]} vertices")
    if not distance > 0:
        raise AnatomeshError(f"damping distance must be > 0 mm, got {distance}")
    if v.shape[0] == 0:
        return np.ones(0)
    cell = float(distance)
    origin = v.min(axis=0) - cell
    dims = (np.floor((v.max(axis=0) - origin) / cell).astype(np.int64) + 2)
    ijk = ((v - origin) / cell).astype(np.int64)
    keys = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.argsort(keys, kind="stable")
    d = _k.nearest_other_group(v, g, cell, origin, dims, keys[order], order)
    return np.clip(d / distance, 0.0, 1.0)


def clamp(pos: np.ndarray, arrays: tuple) -> None:
    """Put float64 (N, 3) ``pos`` back into a constraint, in place; ``arrays`` from
    :meth:`Constraint.arrays` (nothing to do for no box and no cap)."""
    if arrays[0] != 0 or arrays[4] < np.inf:
        _k.constrain_all(pos, *arrays)
