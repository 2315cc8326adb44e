"""The :class:`Volume`: a voxel array with exact geometry, and its label table.

Every reader returns a Volume; nothing downstream reads a file.

Conventions
-----------
* ``data[i, j, k]`` is the voxel with index (i, j, k); ``affine @ (i, j, k, 1)`` is the position of
  that voxel's *centre* in millimetres in the space named by ``space``.
* ``space`` names the patient coordinate system: ``"RAS"`` (NIfTI, most Blender users): +x toward
  the patient's Right, +y Anterior, +z Superior; ``"LPS"`` (DICOM, ITK, 3D Slicer's files): +x toward
  the patient's Left, +y Posterior, +z Superior. Converting negates the first two rows of the affine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from .errors import AnatomeshError
from .labels import LabelInfo

SPACES = ("RAS", "LPS")
_AXIS_LETTERS = {"RAS": ("L", "R", "P", "A", "I", "S"), "LPS": ("R", "L", "A", "P", "I", "S")}


@dataclass
class Volume:
    """A 3D scan or label map with its geometry.

    Attributes
    ----------
    data : np.ndarray, shape (I, J, K)
        Voxel values (any real dtype; label maps are integer). Scaling (e.g. CT rescale to HU)
        is already applied.
    affine : np.ndarray, shape (4, 4), float64
        Voxel index (i, j, k, 1) → position in mm in ``space``.
    space : str
        ``"RAS"`` or ``"LPS"``: the patient coordinate system the affine maps into.
    meta : dict
        Free-form facts: ``format``, ``modality``, ``units`` (e.g. "HU"), ``series_description``,
        ``series_uid``, ``source`` (path) ...
    labels : dict[int, LabelInfo] or None
        Label table when the volume is a label map (value → name, colour); None for scalar scans.
    warnings : list[str]
        Problems found while reading that did not stop it (non-uniform spacing, skipped files ...).
    """

    data: np.ndarray
    affine: np.ndarray
    space: str = "RAS"
    meta: Dict = field(default_factory=dict)
    labels: Optional[Dict[int, LabelInfo]] = None
    warnings: List[str] = field(default_factory=list)

    def __post_init__(self):
        self.affine = np.asarray(self.affine, dtype=np.float64)
        if self.affine.shape != (4, 4):
            raise ValueError(f"affine must be 4x4, got {self.affine.shape}")
        if self.space not in SPACES:
            raise ValueError(f"space must be one of {SPACES}, got {self.space!r}")
        if self.data.ndim != 3:
            raise ValueError(f"volume data must be 3D, got shape {self.data.shape}")

    # -- geometry -------------------------------------------------------------------------
    @property
    def shape(self) -> Tuple[int, int, int]:
        return tuple(int(s) for s in self.data.shape)

    @property
    def spacing(self) -> Tuple[float, float, float]:
        """Voxel size in mm along i, j, k (norms of the affine's columns)."""
        return tuple(float(v) for v in np.linalg.norm(self.affine[:3, :3], axis=0))

    @property
    def is_label_map(self) -> bool:
        return self.labels is not None

    def orientation(self) -> str:
        """Three letters: the patient direction each index axis (i, j, k) points to, e.g. 'LPS'."""
        return orientation_codes(self.affine, self.space)

    def in_space(self, space: str) -> "Volume":
        """The same volume with its affine expressed in ``space`` (data shared, not copied)."""
        return Volume(self.data, convert_affine(self.affine, self.space, space), space,
                      dict(self.meta), self.labels, list(self.warnings))

    def voxel_volume_mm3(self) -> float:
        return float(abs(np.linalg.det(self.affine[:3, :3])))

    def release_voxels(self) -> None:
        """Let go of the voxel array (one-shot runs, memory: the surfaces are extracted and the
        input facts taken): ``data`` becomes a read-only zero-stride view of the same shape and
        dtype holding zeros, so the geometry (shape, affine, spacing) still answers."""
        self.data = np.broadcast_to(np.zeros((), self.data.dtype), self.data.shape)


def convert_affine(affine: np.ndarray, from_space: str, to_space: str) -> np.ndarray:
    """Re-express a voxel→mm affine in another space (RAS ↔ LPS negates x and y)."""
    for s in (from_space, to_space):
        if s not in SPACES:
            raise ValueError(f"unknown space {s!r}; use one of {SPACES}")
    out = np.array(affine, dtype=np.float64)
    if from_space != to_space:
        out[:2, :] *= -1.0
    return out


def space_flip(from_space: str, to_space: str) -> np.ndarray:
    """The 4x4 matrix taking points from one space to the other (identity or diag(-1,-1,1,1))."""
    return convert_affine(np.eye(4), from_space, to_space)


def orientation_codes(affine: np.ndarray, space: str) -> str:
    """The patient direction of each voxel axis, as 3 letters (nibabel's aff2axcodes, any space)."""
    letters = _AXIS_LETTERS[space]
    m = np.asarray(affine, dtype=np.float64)[:3, :3]
    codes = []
    used = set()
    for col in range(3):
        v = m[:, col]
        order = np.argsort(-np.abs(v))
        axis = next(int(a) for a in order if int(a) not in used)
        used.add(axis)
        codes.append(letters[2 * axis + (1 if v[axis] > 0 else 0)])
    return "".join(codes)


def check_fits_in_memory(shape, dtype, what: str, path=None, factor: float = 1.0) -> None:
    """Fail early, with the size needed, if an array of ``shape``/``dtype`` cannot be held.

    ``factor`` accounts for temporary copies the reader makes (e.g. 2.0 when decoding into a
    second buffer). Uses the available physical memory (``/proc/meminfo`` MemAvailable).
    """
    need = float(np.prod([int(s) for s in shape], dtype=np.float64)) * np.dtype(dtype).itemsize * factor
    avail = available_memory_bytes()
    if avail is not None and need > avail:
        raise AnatomeshError(
            f"{what} of shape {tuple(int(s) for s in shape)} ({np.dtype(dtype).name}) needs "
            f"{_gib(need)} of memory but only {_gib(avail)} is available; crop or downsample the "
            "scan first, or free memory", path)


def available_memory_bytes() -> Optional[float]:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:  # macOS / Windows fall back to total physical memory
        import os
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def _gib(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def affine_from_geometry(origin, directions, spacing) -> np.ndarray:
    """Build a 4x4 affine from an origin (3,), unit direction columns (3, 3) and spacing (3,)."""
    a = np.eye(4)
    a[:3, :3] = np.asarray(directions, dtype=np.float64) * np.asarray(spacing, dtype=np.float64)[None, :]
    a[:3, 3] = np.asarray(origin, dtype=np.float64)
    return a


def is_finite_number(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)
