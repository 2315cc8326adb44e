"""Steps the NIfTI and NRRD readers share: scalar clean-up and assembling the Volume."""
from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from ..model.errors import AnatomeshError
from ..model.volume import Volume
from .label_tables import resolve_label_map


def native(data: np.ndarray) -> np.ndarray:
    """``data`` in the machine's byte order (numba kernels and ``bincount`` want native dtypes)."""
    if data.dtype.byteorder not in ("=", "|") and not data.dtype.isnative:
        return data.astype(data.dtype.newbyteorder("="))
    return data


def clean_scalar(data: np.ndarray, path, warnings: List[str]) -> np.ndarray:
    """A scan's voxels ready for meshing: float64 → float32, NaN/inf → the minimum finite value.

    Non-finite voxels (NaN, ±inf) would poison interpolation in marching cubes; they are set to
    the smallest finite value of the image (i.e. "outside" for any threshold above it), and a
    warning gives their count.
    """
    if data.dtype.kind != "f":
        return data
    if data.dtype != np.float32:
        data = data.astype(np.float32)
    finite = np.isfinite(data)
    bad = int(data.size - np.count_nonzero(finite))
    if bad:
        if bad == data.size:
            raise AnatomeshError("every voxel is NaN or infinite, so the file holds no image; export it again", path)
        fill = float(data[finite].min())
        if not data.flags.writeable:
            data = data.copy()
        data[~finite] = fill
        warnings.append(f"{bad} voxels were NaN or infinite; they were set to the minimum finite "
                        f"value {fill:g}")
    return data


def finish_volume(data: np.ndarray, affine: np.ndarray, space: str, meta: Dict, path,
                  warnings: List[str], *, labels=None, label_map: Optional[bool] = None,
                  hint_label: bool = False, names=None, names_source: str = "") -> Volume:
    """Decide label map or scan, clean up accordingly and build the :class:`Volume`."""
    data = native(data)
    data, table, more, extra = resolve_label_map(
        data, Path(path), labels=labels, label_map=label_map, hint_label=hint_label,
        names=names, names_source=names_source)
    warnings = list(warnings) + more
    if table is None:
        data = clean_scalar(data, path, warnings)
    meta = dict(meta)
    meta.update(extra)
    return Volume(data, affine, space, meta, table, warnings)
