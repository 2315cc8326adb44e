"""A folder (or list) of binary masks, one structure per file → label-map layers.

TotalSegmentator writes one ``<structure>.nii.gz`` per structure; 3D Slicer exports segments the
same way (NIfTI or NRRD). Each file is read with the NIfTI/NRRD reader; then

* the structure's name is the file name without its suffix (``aorta_true_lumen.nii.gz`` →
  ``aorta_true_lumen``), its colour the anatomical palette's
  (:func:`anatomesh.core.model.labels.label_table_for`);
* each file's values decide what it is (:func:`classify`), and every choice other than a plain 0/1
  mask is said in ``meta["notes"]`` with the file's name:

  - 0/1 (or empty): a mask;
  - 0/255 (8-bit exports): a mask, inside = value > 0;
  - fractions within 0..1 (a probability map): a mask, inside = value >= 0.5;
  - negative values, fractions beyond 1, or more distinct whole values than a label map holds
    (a CT or MR, e.g. ``ct.nii.gz``): the image, not meshed, but its grid can be chosen; at most one;
  - other whole values (a label map, or a piece of one holding 0 and one other value): refused,
    naming the file;

* masks on other grids are brought onto one grid by their affines (nearest neighbour, exact when
  the grids share a lattice): by default the finest grid among the masks (smallest voxel),
  else the one named by ``grid`` (a mask name, or ``"image"``); the common grid covers every
  structure. What was moved or resampled is listed in ``meta["resampled"]``;
* empty masks are skipped with a warning.

Overlapping masks become separate layers (:mod:`anatomesh.core.model.segmentation`).
"""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from ..model.errors import AnatomeshError
from ..model.labels import LabelInfo, label_table_for
from ..model.progress import Progress, report
from ..model.segmentation import Mask, Segmentation, crop_mask, segmentation_from_masks
from ..model.volume import Volume
from .label_tables import MAX_AUTO_LABELS, distinct_values, is_integer_valued

MASK_SUFFIXES = (".nii.gz", ".nii", ".seg.nrrd", ".nrrd", ".nhdr")
GRID_IMAGE = "image"


def mask_files(path_or_paths) -> Optional[List[Path]]:
    """The NIfTI/NRRD files of a folder (top level, not hidden) or list, when that is what it
    holds (a list: every entry such a file); None otherwise (e.g. a DICOM folder)."""
    if isinstance(path_or_paths, (list, tuple)):
        files = [Path(p) for p in path_or_paths]
        ok = files and all(p.is_file() and p.name.lower().endswith(MASK_SUFFIXES) for p in files)
        return files if ok else None
    p = Path(path_or_paths)
    if not p.is_dir():
        return None
    entries = [q for q in p.iterdir() if not q.name.startswith(".")]
    files = sorted(q for q in entries if q.is_file() and q.name.lower().endswith(MASK_SUFFIXES))
    if not files or any(q.is_file() and _is_dicom(q) for q in entries):
        return None  # a DICOM folder (perhaps with a reference mask beside it)
    return files


def _is_dicom(q: Path) -> bool:
    if q.suffix.lower() in (".dcm", ".dicom", ".ima"):
        return True
    try:
        with open(q, "rb") as fh:
            head = fh.read(132)
    except OSError:
        return False
    return head[128:132] == b"DICM"


def structure_name(path: Path) -> str:
    """The structure a mask file names: its file name without the suffix."""
    name = path.name
    for s in MASK_SUFFIXES:
        if name.lower().endswith(s):
            return name[: -len(s)]
    return name


def read_masks(files: Sequence[Path], grid: Optional[str] = None, space: Optional[str] = None,
               progress: Optional[Progress] = None) -> Union[Volume, Segmentation]:
    """Read binary masks (+ at most one image) into one label map, or layers when they overlap.

    Parameters
    ----------
    files : NIfTI/NRRD paths (see :func:`mask_files`)
    grid : None (finest mask grid), ``"image"`` or a structure name: the grid to mesh on.
    space : "RAS"/"LPS" of the result (default: the first file's).

    Returns
    -------
    Volume or Segmentation
        label values 1..n in file order (empty masks skipped); ``meta``: ``format`` "masks",
        ``source`` (folder), ``structures``, ``image`` (path of the image file or None),
        ``grid`` (what the grid is), ``resampled`` (list of ``{name, how, from_shape,
        from_spacing}``).
    """
    files = [Path(f) for f in files]
    source = files[0].parent if len(files) > 1 or files[0].parent.is_dir() else files[0]
    masks, image, space, warnings, notes = _sort_files(files, space, source, progress)
    if not masks:
        raise AnatomeshError("no binary masks found (only an image); give a folder of one "
                             "0/1 mask per structure", source)
    target, shape, grid_note = _target_grid(masks, image, grid, source)
    table = label_table_for(range(1, len(masks) + 1), {k + 1: n for k, (n, _) in enumerate(masks)})
    placed, resampled = [], []
    for k, (name, vol) in enumerate(masks):
        m, how = _place(vol, table[k + 1], target, shape)
        if how:
            resampled.append({"name": name, "how": how, "from_shape": list(vol.shape),
                              "from_spacing": [round(s, 6) for s in vol.spacing]})
        if m is None:
            warnings.append(f"mask {name!r} is empty (no voxel set): skipped")
            continue
        placed.append(m)
    report(progress, 0.95, "sorting structures into layers")
    meta = {"format": "masks", "source": str(source), "structures": len(placed),
            "image": str(files[0].parent / image.meta["source_name"]) if image is not None else None,
            "grid": grid_note, "resampled": resampled, "modality": "segmentation",
            "notes": notes + [f"{r['name']} ({'x'.join(map(str, r['from_shape']))} voxels): {r['how']} onto "
                              f"{grid_note}" for r in resampled]}
    out = segmentation_from_masks(placed, shape, target, space, meta, warnings)
    report(progress, 1.0, "masks read")
    return out


def _sort_files(files: List[Path], space: Optional[str], source: Path, progress):
    """Read and classify every file: ``(masks [(name, bool Volume)], image Volume or None, space,
    warnings, notes)``; the image's ``meta["source_name"]`` is its file name."""
    masks, image, warnings, notes = [], None, [], []
    for n, f in enumerate(files):
        vol = _read(f)
        space = space or vol.space
        vol = vol.in_space(space) if vol.space != space else vol
        kind, inside, note = classify(vol, f)
        notes += [note] if note else []
        warnings += [w if f.name in w else f"{f.name}: {w}" for w in vol.warnings]
        if kind == "image":
            if image is not None:
                raise AnatomeshError(f"two images among the masks ({image.meta['source_name']}, {f.name}); a "
                                     "mask folder holds one binary mask per structure and at most one "
                                     "scan: move one out", source)
            vol.meta["source_name"] = f.name
            image = vol
        else:
            masks.append((structure_name(f), Volume(inside, vol.affine, vol.space, vol.meta, None, [])))
        report(progress, 0.8 * (n + 1) / len(files), f"reading {f.name}")
    return masks, image, space, warnings, notes


def _read(f: Path) -> Volume:
    if f.name.lower().endswith((".nii", ".nii.gz")):
        from .nifti import read_nifti
        return read_nifti(f, label_map=False)
    from .nrrd import read_nrrd
    return read_nrrd(f, label_map=False)


#: fraction from which a voxel of a probability map (values within 0..1) is inside
PROBABILITY_THRESHOLD = 0.5
#: the "inside" value of 8-bit masks (0/255 exports), read as 1
BYTE_MASK = 255


def classify(vol: Volume, f: Path) -> Tuple[str, Optional[np.ndarray], str]:
    """What a file of a mask folder is: ``("mask", inside, note)`` with ``inside`` bool (I, J, K),
    or ``("image", None, note)``; ``note`` ("" for a plain 0/1 mask) names the file and the rule.
    Raises for a label map of several structures (see the module docstring)."""
    d = vol.data
    if d.size == 0:
        return "mask", np.zeros(d.shape, bool), ""
    lo, hi = float(d.min()), float(d.max())
    whole = is_integer_valued(d)
    values = distinct_values(d, limit=MAX_AUTO_LABELS) if whole and lo >= 0 else None
    if lo < 0 or (not whole and hi > 1) or (whole and values is None):
        return "image", None, (f"{f.name} was taken as the image, not a mask (values {lo:g}..{hi:g}: a scan); "
                               "it is not meshed, --grid image meshes the masks on its grid")
    if not whole:
        return "mask", d >= PROBABILITY_THRESHOLD, (
            f"{f.name} holds fractions within 0..1 (a probability map): voxels at or above "
            f"{PROBABILITY_THRESHOLD:g} were taken as inside")
    nonzero = values[values != 0]
    if len(nonzero) == 0 or (len(nonzero) == 1 and nonzero[0] == 1):
        return "mask", d != 0, ""
    if len(nonzero) == 1 and nonzero[0] == BYTE_MASK:
        return "mask", d != 0, (f"{f.name} holds the values 0 and {BYTE_MASK}: voxels of value {BYTE_MASK} "
                                "(> 0) were taken as inside")
    shown = ", ".join(f"{v:g}" for v in nonzero[:6]) + (", ..." if len(nonzero) > 6 else "")
    what = (f"{len(nonzero)} different nonzero values ({shown}): a label map (or a low-bit scan), not the mask "
            "of one structure" if len(nonzero) > 1 else
            f"only the values 0 and {shown} (one label of a label map, not a 0/1 mask)")
    raise AnatomeshError(f"holds {what}; each mask must hold only 0 and 1 (or 0 and {BYTE_MASK}): split a label "
                         "map into one 0/1 mask per structure, load it on its own, or move it out of the mask "
                         "folder", f)


def _target_grid(masks, image, grid, source) -> Tuple[np.ndarray, Tuple[int, int, int], str]:
    """(affine, shape, description) of the common grid."""
    grids = [(n, v) for n, v in masks]
    if grid is None or str(grid).strip() == "":
        name, ref = min(grids, key=lambda nv: (round(nv[1].voxel_volume_mm3(), 9), 0))
        why = f"the finest mask grid ({name})"
    elif str(grid).strip().lower() == GRID_IMAGE:
        if image is None:
            raise AnatomeshError("--grid image: there is no image (scan) among the masks; give a "
                                 "structure name or leave --grid out", source)
        ref, why = image, f"the image ({image.meta['source_name']})"
    else:
        hits = [v for n, v in grids if n.lower() == str(grid).strip().lower()]
        if not hits:
            raise AnatomeshError(f"--grid {grid!r} names no mask here; give one of "
                                 f"{', '.join(n for n, _ in grids[:8])}{' ...' if len(grids) > 8 else ''} "
                                 "or 'image'", source)
        ref, why = hits[0], f"the grid of {grid}"
    A = ref.affine
    if all(_same(v.affine, A) and v.shape == ref.shape for _, v in grids):
        return A, ref.shape, why
    inv = np.linalg.inv(A)
    lo = np.zeros(3)
    hi = np.asarray(ref.shape, float) - 1
    for _, v in grids:
        corners = _box_corners(v)
        if corners is None:
            continue
        idx = (inv @ v.affine @ corners)[:3]
        lo = np.minimum(lo, np.floor(idx.min(axis=1) + 1e-6))
        hi = np.maximum(hi, np.ceil(idx.max(axis=1) - 1e-6))
    shift = lo.astype(np.int64)
    target = A.copy()
    target[:3, 3] = A[:3, 3] + A[:3, :3] @ shift
    shape = tuple(int(s) for s in (hi - lo + 1).astype(np.int64))
    return target, shape, why + (", extended to cover every structure" if shape != ref.shape else "")


def _box_corners(v: Volume) -> Optional[np.ndarray]:
    """(4, 8) homogeneous index corners of the nonzero box of ``v`` (voxel centres), or None."""
    nz = [np.flatnonzero(np.any(v.data, axis=tuple(a for a in range(3) if a != ax))) for ax in range(3)]
    if any(len(n) == 0 for n in nz):
        return None
    c = np.array([[a, b, c, 1.0] for a in (nz[0][0], nz[0][-1]) for b in (nz[1][0], nz[1][-1])
                  for c in (nz[2][0], nz[2][-1])]).T
    return c


def _same(a, b, atol=1e-4) -> bool:
    return bool(np.allclose(a, b, atol=atol))


def _place(vol: Volume, info: LabelInfo, target: np.ndarray, shape) -> Tuple[Optional[Mask], str]:
    """The mask of ``vol`` on the target grid and how it got there ("" when already on it)."""
    A = vol.affine
    rel = np.linalg.inv(target) @ A  # source index → target index
    lin, off = rel[:3, :3], rel[:3, 3]
    if np.allclose(lin, np.eye(3), atol=1e-4) and np.allclose(off, np.round(off), atol=1e-3):
        shift = np.round(off).astype(np.int64)
        m = crop_mask(info, vol.data != 0, tuple(int(s) for s in shift))
        how = "" if not shift.any() and vol.shape == tuple(shape) else \
            f"same lattice, shifted by {tuple(int(s) for s in shift)} voxels"
        return m, how
    return _resample(vol, info, target, shape), "resampled (nearest neighbour, by affine)"


def _resample(vol: Volume, info: LabelInfo, target: np.ndarray, shape) -> Optional[Mask]:
    """Nearest-neighbour resampling of a binary mask onto the target grid, over its box only."""
    from scipy import ndimage

    corners = _box_corners(vol)
    if corners is None:
        return None
    src = np.asarray(vol.data != 0, np.uint8)
    idx = np.linalg.inv(target) @ vol.affine @ np.concatenate(
        [corners + np.array([[s] for s in (-0.5, -0.5, -0.5, 0)]),
         corners + np.array([[s] for s in (0.5, 0.5, 0.5, 0)])], axis=1)
    lo = np.clip(np.floor(idx[:3].min(axis=1)).astype(np.int64), 0, None)
    hi = np.minimum(np.ceil(idx[:3].max(axis=1)).astype(np.int64) + 1, np.asarray(shape))
    m = np.linalg.inv(vol.affine) @ target  # target index → source index
    out = ndimage.affine_transform(src, m[:3, :3], offset=m[:3, :3] @ lo + m[:3, 3],
                                   output_shape=tuple(int(x) for x in hi - lo), order=0, mode="constant")
    return crop_mask(info, out, tuple(int(x) for x in lo))


__all__ = ["mask_files", "read_masks", "structure_name", "GRID_IMAGE"]
