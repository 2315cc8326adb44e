"""Cut faces: the triangles of a surface that lie on the scan's field-of-view boundary.

A structure that leaves the scanned volume is closed by a flat cap where the volume ends (a
label map's shell runs along the outer voxel faces, index -0.5 or n - 0.5; a capped isosurface
between the last voxel centre and the zero padding beyond it). Those faces show no anatomy: they
are where the scan cut the structure. A face is a cut face when all three corners lie at or beyond
the outermost voxel centres along one index axis (index <= 0, or >= n - 1) and its normal is
within 30 degrees of that axis (in index space). Smoothing keeps each vertex in its voxel cell
and decimation keeps planar caps planar, so the test also holds for the finished surfaces.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

#: a cut face's normal is within this angle of the index axis it is cut along
MAX_TILT_DEG = 30.0


def cut_faces(vertices: np.ndarray, faces: np.ndarray, affine: np.ndarray,
              shape: Sequence[int], tolerance: float = 1e-3) -> np.ndarray:
    """Which faces lie on the field-of-view boundary of the volume (see module docstring).

    Parameters
    ----------
    vertices : (N, 3) float, mm, in the space ``affine`` maps into
    faces : (M, 3) int
    affine : (4, 4) voxel index → mm (at voxel centres)
    shape : the volume's (i, j, k) size in voxels
    tolerance : voxels by which a corner may sit inside the outermost voxel centres

    Returns
    -------
    (M,) bool
    """
    v = np.asarray(vertices, np.float64).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if not len(f):
        return np.zeros(0, bool)
    inv = np.linalg.inv(np.asarray(affine, np.float64))
    ijk = v @ inv[:3, :3].T + inv[:3, 3]
    tri = ijk[f]  # (M, 3 corners, 3 axes)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    aligned = np.abs(normal) >= np.cos(np.radians(MAX_TILT_DEG)) * length[:, None]
    low = np.all(tri <= tolerance, axis=1)
    high = np.all(tri >= np.asarray(shape, np.float64) - 1.0 - tolerance, axis=1)
    return np.any((low | high) & aligned & (length[:, None] > 0), axis=1)
