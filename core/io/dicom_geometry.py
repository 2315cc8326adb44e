"""The geometry of a DICOM image series: slice order and spacing from ImagePositionPatient along
the slice normal (never from SliceThickness/SpacingBetweenSlices), the in-plane axes and the
voxel → LPS mm affine; missing, duplicate and tilted slices found and reported (DICOM PS3.3
C.7.6.2, Image Plane Module)."""
from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Dict, List

import numpy as np

from ..model.errors import AnatomeshError
from .dicom_values import float_or, floats, int_or, rel_path, text_of

GAP_FACTOR = 1.5            # a step above this times the median step is a gap (missing slices)
UNIFORM_TOLERANCE = 0.01    # relative spread of the slice steps tolerated without a warning
DUPLICATE_MM = 0.01         # two slices closer than this along the normal share a position
ORIENTATION_TOLERANCE = 1e-4  # direction-cosine difference tolerated between slices
TILT_TOLERANCE_DEG = 0.01   # shear below this is rounding; the affine is then orthogonal
LINE_TOLERANCE_PX = 0.1     # in-plane scatter of slice origins tolerated, in pixels


def series_geometry(files: List[Path], headers: list, source: Path):
    """Sort the slices and build the affine. Returns (order, affine, median step mm, warnings)."""
    _check_alike(files, headers, source)
    row, col, dx, dy, warnings = _in_plane_axes(files, headers, source)
    normal = np.cross(row, col)
    normal /= np.linalg.norm(normal)
    if len(files) < 2:
        raise AnatomeshError("the series has a single slice; a volume needs at least 2: give the folder "
                             "that holds the whole series", files[0])
    pos = np.array([floats(d, "ImagePositionPatient", 3, p) for p, d in zip(files, headers)])
    t = pos @ normal  # position along the normal
    order = np.argsort(t, kind="stable")
    t, pos = t[order], pos[order]
    step, more = _slice_step(t, order, files, headers, source)
    vector, tilt = _slice_vector(pos, t, step, normal, min(dx, dy), order, files, headers, source)
    affine = np.eye(4)
    affine[:3, 0] = row * dx
    affine[:3, 1] = col * dy
    affine[:3, 2] = vector
    affine[:3, 3] = pos[0]
    return order, affine, step, warnings + more + tilt


def _check_alike(files, headers, source):
    """Raise unless all slices have one image size and are greyscale."""
    sizes = [(int_or(d.get("Rows"), 0), int_or(d.get("Columns"), 0)) for d in headers]
    _same(files, sizes, "image sizes", lambda v: f"{v[1]}x{v[0]}", source)
    samples = [int_or(d.get("SamplesPerPixel"), 1) for d in headers]
    _same(files, samples, "samples per pixel", str, source)
    if samples[0] != 1:
        raise AnatomeshError("colour (RGB) images cannot form a scalar volume; export the "
                             "series as greyscale", files[0])


def _in_plane_axes(files, headers, source):
    """Unit row and column directions, column and row spacing (mm), warnings."""
    iop = np.array([floats(d, "ImageOrientationPatient", 6, p) for p, d in zip(files, headers)])
    _same_numbers(files, iop, ORIENTATION_TOLERANCE, "orientations", source)
    spacing = np.array([floats(d, "PixelSpacing", 2, p) for p, d in zip(files, headers)])
    _same_numbers(files, spacing, 1e-4 * spacing.max(), "pixel spacings", source)
    dy, dx = spacing[0]  # PixelSpacing = (between rows, between columns)
    if dx <= 0 or dy <= 0:
        raise AnatomeshError(f"PixelSpacing {spacing[0].tolist()} is not positive: the header is "
                             "damaged; export the series again", files[0])
    row, col = iop[0, :3], iop[0, 3:]
    if min(np.linalg.norm(row), np.linalg.norm(col)) < 1e-6:
        raise AnatomeshError("ImageOrientationPatient has a zero vector: the header is damaged; "
                             "export the series again", files[0])
    row, col = row / np.linalg.norm(row), col / np.linalg.norm(col)
    angle = math.degrees(math.acos(max(-1.0, min(1.0, float(row @ col)))))
    warnings = []
    if abs(angle - 90.0) > 0.06:
        warnings.append(f"the image row and column directions are {angle:.2f}° apart, not 90°; "
                        "the affine keeps them as given")
    return row, col, float(dx), float(dy), warnings


def _slice_step(t, order, files, headers, source):
    """Median step along the normal (mm) after the duplicate and gap checks; warnings."""
    steps = np.diff(t)
    _check_duplicates(steps, t, order, files, headers, source)
    step = float(np.median(steps))
    _check_gaps(steps, step, t, order, files, source)
    if steps.max() - steps.min() <= UNIFORM_TOLERANCE * step:
        return step, []
    drift = np.abs(t - (t[0] + step * np.arange(len(t)))).max()
    return step, [f"slice spacing is not uniform: steps from {steps.min():.4g} to "
                  f"{steps.max():.4g} mm; the volume uses the median {step:.4g} mm, so slices "
                  f"may be placed up to {drift:.3g} mm off"]


def _slice_vector(pos, t, step, normal, pixel, order, files, headers, source):
    """The affine's third column: ``normal * step``, or sheared along the slice origins (tilt)."""
    travel = (pos[-1] - pos[0]) / (t[-1] - t[0])  # origin displacement per mm along the normal
    off = np.linalg.norm(pos - pos[0] - np.outer(t - t[0], travel), axis=1)
    if off.max() > LINE_TOLERANCE_PX * pixel:
        bad = int(np.argmax(off))
        raise AnatomeshError(f"the slice origins do not lie on one line: "
                             f"{rel_path(files[order[bad]], source)} is {off[bad]:.3g} mm off; the "
                             "files may belong to different acquisitions; pass the files of one",
                             source)
    tilt = math.degrees(math.atan(float(np.linalg.norm(travel - normal * (travel @ normal)))))
    if tilt <= TILT_TOLERANCE_DEG:
        return normal * step, []
    gantry = float_or(headers[order[0]], "GantryDetectorTilt", 0.0)
    named = f", GantryDetectorTilt {gantry:g}°" if gantry else ""
    return travel * step, [f"the slices are sheared by {tilt:.2f}° (gantry tilt{named}); the "
                           "affine reproduces the sheared grid exactly, but tools that assume "
                           "square voxels may need a resampled copy"]


def _same_numbers(files, values: np.ndarray, tol: float, what: str, source):
    """Raise when rows of ``values`` differ from the first by more than ``tol``."""
    if np.all(np.abs(values - values[0]) <= tol):
        return
    keys = [tuple(np.round(v, 4).tolist()) for v in values]
    _same(files, keys, what, lambda v: "[" + ", ".join(f"{x:g}" for x in v) + "]", source)


def _same(files, keys: list, what: str, fmt, source):
    """Raise when ``keys`` (one per slice) differ, listing each group with an example file."""
    if len(set(keys)) == 1:
        return
    groups: Dict[object, List[Path]] = defaultdict(list)
    for k, p in zip(keys, files):
        groups[k].append(p)
    parts = ", ".join(f"{len(ps)} with {fmt(k)} (e.g. {rel_path(ps[0], source)})"
                      for k, ps in sorted(groups.items(), key=lambda kv: -len(kv[1])))
    raise AnatomeshError(f"mixed {what} within one series: {parts}; a volume needs one; pass "
                         "only the files that belong together", source)


def _check_duplicates(steps, t, order, files, headers, source):
    dup = np.flatnonzero(steps < DUPLICATE_MM)
    if not len(dup):
        return
    a, b = order[dup[0]], order[dup[0] + 1]
    more = f" ({len(dup) - 1} more such pair(s))" if len(dup) > 1 else ""
    same = text_of(headers[a], "SOPInstanceUID") and \
        text_of(headers[a], "SOPInstanceUID") == text_of(headers[b], "SOPInstanceUID")
    why = "the same image twice (same SOPInstanceUID)" if same else \
        "a duplicated file, or several acquisitions or time points in one series"
    raise AnatomeshError(f"duplicate slice positions: {rel_path(files[a], source)} and "
                         f"{rel_path(files[b], source)} are both at {t[dup[0]]:.4g} mm along the "
                         f"slice normal{more}: {why}; remove the duplicates "
                         "or pass the files of one acquisition", source)


def _check_gaps(steps, step, t, order, files, source):
    gaps = np.flatnonzero(steps > GAP_FACTOR * step)
    if not len(gaps):
        return
    g = gaps[0]
    missing = max(1, int(round(steps[g] / step)) - 1)
    more = f"; {len(gaps) - 1} more gap(s)" if len(gaps) > 1 else ""
    raise AnatomeshError(f"missing slice(s): the position jumps by {steps[g]:.4g} mm between "
                         f"{rel_path(files[order[g]], source)} ({t[g]:.4g} mm) and "
                         f"{rel_path(files[order[g + 1]], source)} ({t[g + 1]:.4g} mm) where the usual "
                         f"step is {step:.4g} mm, about {missing} slice(s) missing{more}; copy "
                         "the complete series again", source)
