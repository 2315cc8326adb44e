"""Where the frames of a DICOM SEG go: their geometry read exactly from the file, the grid built
from it (``native``) or taken from the referenced image series (``image``), and each frame's voxel
on that grid.

Geometry (DICOM PS3.3 C.7.6.16, Multi-frame Functional Groups): each frame's ImagePositionPatient
(Plane Position), the ImageOrientationPatient (Plane Orientation) and the Pixel Measures
(PixelSpacing, SliceThickness, SpacingBetweenSlices), per frame or shared, taken as the file writes
them (never rounded).

The native grid: the frames' in-plane axes and pixel spacing; along the slice normal, a lattice
through every frame plane whose step is

1. SpacingBetweenSlices when the file gives it (the frame planes must lie on its multiples);
2. else SliceThickness, when it is smaller than the smallest distance between frame planes and
   they lie on its multiples (frames that do not touch: the planes between them are empty planes
   of a sparse SEG, left out as the standard allows);
3. else the distance between frame planes, fitted by least squares over all of them.

A plane without a frame is an empty plane, never a longer step. Frame planes that lie on no such
lattice are refused.

Placing frames (both grids): a frame goes to the voxel nearest its position when it lies within
:data:`ON_GRID_TOLERANCE` of a voxel (a fraction of the voxel along each axis: of the slice step
along the normal, of the pixel spacing in-plane); frames further off are refused with the offset
in voxels and mm. Offsets above :data:`NOTE_FROM` voxel are reported in a note.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from .dicom_values import float_or, floats, text_of
from .plane_lattice import fitted_lattice, lattice_offsets

#: how far (fraction of the voxel along each axis) a frame may sit from a grid voxel and still be placed on it
ON_GRID_TOLERANCE = 0.1
#: frame offsets above this (fraction of the voxel) are reported in a note; below it they are rounding
NOTE_FROM = 0.005
#: relative difference of pixel spacings, and difference of direction cosines, taken as equal
SAME_GEOMETRY = 1e-4


@dataclass
class FrameGeometry:
    """The geometry of a SEG's frames, as the file gives it.

    ``positions`` (F, 3) float64: each frame's first pixel centre, LPS mm; ``row``, ``col`` (3,)
    unit vectors (along a frame row, down a frame column); ``spacing`` (dx, dy) mm (between
    columns, between rows); ``thickness`` and ``between`` (SliceThickness, |SpacingBetweenSlices|)
    mm or None; ``numbers`` (F,) int segment number of each frame (None for a label-map SEG);
    ``frame_shape`` (rows, cols)."""

    positions: np.ndarray
    row: np.ndarray
    col: np.ndarray
    spacing: Tuple[float, float]
    thickness: Optional[float]
    between: Optional[float]
    numbers: Optional[np.ndarray]
    frame_shape: Tuple[int, int]

    @property
    def normal(self) -> np.ndarray:
        n = np.cross(self.row, self.col)
        return n / np.linalg.norm(n)


def frame_geometry(ds, path: Path, frame_shape: Tuple[int, int]) -> FrameGeometry:
    """Read :class:`FrameGeometry` from a SEG data set; frames with different orientations or
    pixel spacings are refused (one grid cannot hold them)."""
    shared = ds.get("SharedFunctionalGroupsSequence", [None])[0]
    per = ds.get("PerFrameFunctionalGroupsSequence", [])
    if not per:
        raise AnatomeshError("the SEG has no per-frame functional groups, so its frames cannot be "
                             "placed in space; export the segmentation again", path)
    iops = np.array([floats(_item(g, shared, "PlaneOrientationSequence", path), "ImageOrientationPatient",
                            6, path) for g in per])
    measures = [_item(g, shared, "PixelMeasuresSequence", path) for g in per]
    spacings = np.array([floats(m, "PixelSpacing", 2, path) for m in measures])
    _same_for_all(iops, SAME_GEOMETRY, "orientations (ImageOrientationPatient)", path)
    _same_for_all(spacings, SAME_GEOMETRY * spacings.max(), "pixel spacings", path)
    positions = np.array([floats(_item(g, shared, "PlanePositionSequence", path), "ImagePositionPatient",
                                 3, path) for g in per])
    row, col = iops[0, :3], iops[0, 3:]
    if min(np.linalg.norm(row), np.linalg.norm(col)) < 1e-6 or spacings[0].min() <= 0:
        raise AnatomeshError(f"the SEG's ImageOrientationPatient {iops[0].tolist()} or PixelSpacing "
                             f"{spacings[0].tolist()} is degenerate; export the segmentation again", path)
    thickness = float_or(measures[0], "SliceThickness", None)
    between = float_or(measures[0], "SpacingBetweenSlices", None)
    numbers = None
    if text_of(ds, "SegmentationType").upper() != "LABELMAP":
        numbers = np.array([int(_item(g, shared, "SegmentIdentificationSequence", path).ReferencedSegmentNumber)
                            for g in per])
    return FrameGeometry(positions, row / np.linalg.norm(row), col / np.linalg.norm(col),
                         (float(spacings[0, 1]), float(spacings[0, 0])),
                         thickness if thickness and thickness > 0 else None,
                         abs(between) if between else None, numbers, frame_shape)


def _item(group, shared, name: str, path):
    for g in (group, shared):
        if g is not None and name in g and len(g[name].value):
            return g[name][0]
    raise AnatomeshError(f"the SEG lacks {name}, so its frames cannot be placed in space; export "
                         "the segmentation again", path)


def _same_for_all(values: np.ndarray, tol: float, what: str, path) -> None:
    bad = np.flatnonzero(np.abs(values - values[0]).max(axis=1) > tol)
    if len(bad):
        raise AnatomeshError(f"the SEG's frames have different {what} (frame 1: {values[0].tolist()}, "
                             f"frame {bad[0] + 1}: {values[bad[0]].tolist()}); one grid cannot hold them: "
                             "export the segmentation on one image series", path)


# -- the native grid ------------------------------------------------------------------------------
def native_grid(geo: FrameGeometry, path) -> Tuple[np.ndarray, Tuple[int, int, int], str, List[str]]:
    """The SEG's own grid (see the module docstring): affine (4, 4) voxel (column, row, plane) →
    LPS mm, shape, a description and notes on how the step was chosen."""
    planes = _planes(geo.positions @ geo.normal, geo)
    step, why, notes = _native_step(planes, geo, path)
    affine = np.eye(4)
    affine[:3, 0], affine[:3, 1] = geo.row * geo.spacing[0], geo.col * geo.spacing[1]
    affine[:3, 2], affine[:3, 3] = geo.normal * step, geo.positions[0]
    idx = _indices(affine, geo.positions)
    affine[:3, 3] += affine[:3, :3] @ (idx - np.round(idx)).mean(axis=0)  # centre the offsets
    near = np.round(_indices(affine, geo.positions)).astype(np.int64)
    lo, hi = near.min(axis=0), near.max(axis=0)
    affine[:3, 3] += affine[:3, :3] @ lo
    rows, cols = geo.frame_shape
    shape = (int(hi[0] - lo[0]) + cols, int(hi[1] - lo[1]) + rows, int(hi[2] - lo[2]) + 1)
    text = (f"the SEG's own frame positions ({len(planes)} plane{'s' * (len(planes) != 1)}, step "
            f"{step:.6g} mm from {why}), {'x'.join(map(str, shape))} voxels")
    return affine, shape, text, notes


def _planes(t: np.ndarray, geo: FrameGeometry) -> np.ndarray:
    """Distinct frame planes along the normal (mm, ascending): positions closer than half the
    smallest slice distance the file gives (SpacingBetweenSlices, else the smaller of the
    SliceThickness and the pixel spacing) are one plane, e.g. the frames of several segments."""
    scale = geo.between or min([geo.thickness or np.inf, *geo.spacing])
    s = np.sort(t)
    starts = np.r_[0, np.flatnonzero(np.diff(s) > 0.5 * scale) + 1]
    return np.array([s[a:b].mean() for a, b in zip(starts, np.r_[starts[1:], len(s)])])


def _native_step(planes: np.ndarray, geo: FrameGeometry, path) -> Tuple[float, str, List[str]]:
    """(step mm, where it came from, notes); refuses frame planes that lie on no lattice."""
    if len(planes) == 1:
        if geo.between or geo.thickness:
            return (geo.between, "SpacingBetweenSlices", []) if geo.between else \
                (geo.thickness, "SliceThickness", [])
        return min(geo.spacing), "the pixel spacing (one plane, no slice thickness)", []
    smallest = float(np.diff(planes).min())
    if geo.between:
        candidates = [(geo.between, "SpacingBetweenSlices")]
    else:
        candidates = [(fitted_lattice(planes, smallest)[0], "the frame positions")]
        if geo.thickness and geo.thickness < smallest * (1 - ON_GRID_TOLERANCE):
            candidates.insert(0, (geo.thickness, "SliceThickness"))
    for step, why in candidates:
        if lattice_offsets(planes, step).max() <= ON_GRID_TOLERANCE:
            return step, why, _step_notes(step, why, planes, geo)
    step, why = candidates[-1]
    off = lattice_offsets(planes, step)
    bad = int(np.argmax(off))
    raise AnatomeshError(
        f"the SEG's frame planes are not evenly spaced: the plane at {planes[bad]:.4f} mm lies {off[bad]:.2f} "
        f"voxel ({off[bad] * step:.3f} mm) off the {step:.6g} mm lattice ({why}) through the others, more "
        f"than the tolerance of {ON_GRID_TOLERANCE:g} voxel, so its frames fit no grid of its own; put the "
        "image series it was made from beside it to mesh it on that series' grid", path)


def _step_notes(step: float, why: str, planes: np.ndarray, geo: FrameGeometry) -> List[str]:
    notes = []
    empty = int(round((planes[-1] - planes[0]) / step)) + 1 - len(planes)
    if empty:
        notes.append(f"the SEG has frames on {len(planes)} planes of a {step:.6g} mm lattice (step from "
                     f"{why}); the {empty} plane(s) between them without a frame are empty planes")
    if why == "SliceThickness":
        notes.append(f"the SEG gives no SpacingBetweenSlices; its frames ({geo.thickness:g} mm thick) lie "
                     f"{np.diff(planes).min():.6g} mm or more apart, so the slice step was taken as the "
                     "SliceThickness and the planes between them as empty")
    return notes


def _mm(value: Optional[float]) -> str:
    return f"{value:g} mm" if value else "not given"


# -- placing frames -------------------------------------------------------------------------------
def _indices(affine: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """(F, 3) fractional voxel indices of ``positions`` (F, 3) mm on ``affine``."""
    return np.linalg.solve(affine[:3, :3], (positions - affine[:3, 3]).T).T


def same_in_plane_lattice(geo: FrameGeometry, affine: np.ndarray) -> bool:
    """Whether the frames' pixel axes and spacing equal the grid's first two axes."""
    a = affine[:3, :2]
    b = np.stack([geo.row * geo.spacing[0], geo.col * geo.spacing[1]], axis=1)
    return bool(np.abs(a - b).max() <= SAME_GEOMETRY * max(1.0, float(np.abs(b).max())))


def place_frames(geo: FrameGeometry, affine: np.ndarray, shape, path,
                 grid: str) -> Tuple[np.ndarray, List[str]]:
    """Grid index (F, 3) int64 of each frame's first pixel, and notes; raises when a frame lies
    more than :data:`ON_GRID_TOLERANCE` voxel off the grid (``grid`` names it in the message) or
    reaches outside it. The caller adds what to do to the message."""
    idx = _indices(affine, geo.positions)
    near = np.round(idx)
    frac = idx - near
    off = np.abs(frac).max(axis=1)
    mm = np.linalg.norm(affine[:3, :3] @ frac.T, axis=0)
    f = int(np.argmax(off))
    if off[f] > ON_GRID_TOLERANCE:
        axis = "along the slice normal" if np.argmax(np.abs(frac[f])) == 2 else "in its plane"
        raise AnatomeshError(f"frame {f + 1} lies {off[f]:.2f} voxel ({mm[f]:.3f} mm) off {grid} {axis}, "
                             f"more than the tolerance of {ON_GRID_TOLERANCE:g} voxel", path)
    notes = []
    if off[f] > NOTE_FROM:
        moved = int(np.count_nonzero(off > NOTE_FROM))
        notes.append(f"{moved} of {len(off)} SEG frames lie up to {off[f]:.3f} voxel ({mm.max():.3f} mm) off "
                     f"{grid} (tolerance {ON_GRID_TOLERANCE:g} voxel): each was placed on its nearest voxel")
    near = near.astype(np.int64)
    rows, cols = geo.frame_shape
    bad = (near < 0).any(axis=1) | (near[:, 0] + cols > shape[0]) | (near[:, 1] + rows > shape[1]) | \
        (near[:, 2] >= shape[2])
    if np.any(bad):
        f = int(np.flatnonzero(bad)[0])
        raise AnatomeshError(f"frame {f + 1} reaches outside {grid}", path)
    return near, notes


__all__ = ["FrameGeometry", "frame_geometry", "native_grid", "place_frames", "same_in_plane_lattice",
           "ON_GRID_TOLERANCE", "NOTE_FROM"]
