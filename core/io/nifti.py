"""NIfTI-1/-2 (``.nii``, ``.nii.gz``) → :class:`~anatomesh.core.model.volume.Volume`, with nibabel.

Geometry is nibabel's: ``img.affine`` (the sform when its code is set, else the qform, else a
fallback from the voxel sizes alone — then a warning says the orientation is unknown). The
space is RAS (NIfTI's world space). The affine is always in mm: spacing stored in microns or
metres (``xyzt_units``) is converted; unknown units are taken as mm, as every viewer does.

Voxel values: ``scl_slope``/``scl_inter`` are applied. An integer image without scaling keeps
its dtype (int16 CT stays int16); a scaled or floating-point scan becomes float32; a label map
becomes uint8/uint16/int32 (the smallest that holds its largest value). NaN/inf voxels of a scan
are set to the minimum finite value with a warning; in a label map they are an error.

4D images need ``volume_index`` (0-based; CLI ``--volume N``) unless the 4th axis has length 1;
5D and higher (vector or tensor fields) are rejected.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.volume import Volume, check_fits_in_memory
from ._reader_common import finish_volume
from .library_messages import notes_of_library, reason

#: NIfTI spatial units → factor to mm
_TO_MM = {"mm": 1.0, "micron": 1e-3, "meter": 1e3}


@notes_of_library
def read_nifti(path, volume_index: Optional[int] = None, labels=None,
               label_map: Optional[bool] = None) -> Volume:
    """Read a ``.nii``/``.nii.gz`` file.

    Parameters
    ----------
    path : path
        The NIfTI file.
    volume_index : int, optional
        For a 4D image, which volume to read (0-based).
    labels : path, optional
        A label table (see :func:`anatomesh.core.io.label_tables.read_label_table`); makes the image a
        label map. Without it, a sidecar table next to the file is used when the image is a label map.
    label_map : bool, optional
        Force (True) or forbid (False) a label map; by default decided by
        :func:`~anatomesh.core.io.label_tables.looks_like_label_map` or the NIfTI intent ``label``.

    Returns
    -------
    Volume
        ``data`` shape (I, J, K); ``affine`` voxel → mm in RAS; ``meta`` with ``format``,
        ``source``, ``description``, ``spatial_units``, ``sform_code``, ``qform_code``,
        ``dtype_on_disk`` (+ ``scl_slope``/``scl_inter`` when scaled, ``volume_index`` for 4D).

    Raises
    ------
    AnatomeshError
        Not a NIfTI file, truncated or corrupt data, 4D without ``volume_index``, 5D+, a label map
        with NaN voxels, or too large for the available memory.
    """
    nib = _nibabel()
    p = Path(path)
    img = _open(p, nib)
    hdr = img.header
    shape = tuple(int(s) for s in img.shape)
    shape3, index = _volume_shape(shape, volume_index, p)
    warnings: List[str] = []

    proxy = img.dataobj
    slope = float(getattr(proxy, "slope", 1.0))
    inter = float(getattr(proxy, "inter", 0.0))
    scaled = not (slope == 1.0 and inter == 0.0)
    disk = np.dtype(hdr.get_data_dtype())
    out = np.dtype(np.float32) if (scaled or disk.kind == "f") else disk
    # the raw voxels and the converted copy coexist; a scaled 4D volume passes through float64
    factor = 1.0 if out == disk else (disk.itemsize + out.itemsize + (8 if index is not None else 0)) / out.itemsize
    check_fits_in_memory(shape3, out, "NIfTI volume", p, factor=factor)
    affine, units = _affine_mm(img, hdr, p, warnings)  # bad geometry fails before the long read

    data = _read_voxels(proxy, index, shape3, p, scaled)
    if data.ndim == 2:
        data = data[:, :, None]
    meta = {
        "format": "NIfTI-2" if isinstance(hdr, nib.Nifti2Header) else "NIfTI-1",
        "source": str(p),
        "description": _text(hdr.get("descrip")),
        "spatial_units": units,
        "sform_code": int(hdr["sform_code"]),
        "qform_code": int(hdr["qform_code"]),
        "dtype_on_disk": disk.name,
        "shape_on_disk": shape,
    }
    if scaled:
        meta.update(scl_slope=slope, scl_inter=inter)
    if index is not None:
        meta["volume_index"] = index
    try:
        intent = hdr.get_intent()[0]
    except Exception:  # unknown intent code: not a label map hint
        intent = ""
    return finish_volume(data, affine, "RAS", meta, p, warnings, labels=labels,
                         label_map=label_map, hint_label=(intent == "label"))


def _nibabel():
    """``nibabel``, imported without pydicom when pydicom is not loaded yet and we are not inside
    Blender: ``nibabel.nifti1`` imports pydicom only for the rare DICOM header extension, which
    would slow the start of every NIfTI command (a later ``import pydicom`` works as usual)."""
    if "nibabel" in sys.modules or "pydicom" in sys.modules or "bpy" in sys.modules:
        import nibabel
        return nibabel
    sys.modules["pydicom"] = None  # nibabel's optional_package sees it as not installed
    try:
        import nibabel
    finally:
        del sys.modules["pydicom"]
    return nibabel


def _open(p: Path, nib):
    try:
        img = nib.load(str(p), mmap=False)
    except FileNotFoundError:
        raise AnatomeshError("no such file; check the path", p) from None
    except Exception as err:  # nibabel raises ImageFileError, HeaderDataError, OSError, EOFError...
        raise AnatomeshError(f"not a readable NIfTI file ({reason(err)}); check that it is a "
                             "complete .nii/.nii.gz", p) from None
    if not isinstance(img, (nib.Nifti1Image, nib.Nifti2Image, nib.Nifti1Pair, nib.Nifti2Pair)):
        raise AnatomeshError(f"not a NIfTI image (nibabel read it as {type(img).__name__}); give a "
                             ".nii/.nii.gz NIfTI file", p)
    return img


def _volume_shape(shape: Tuple[int, ...], volume_index: Optional[int], p: Path):
    """The 3D shape to read and the 4D index (None for a 3D image)."""
    dims = list(shape)
    while len(dims) > 4 and dims[-1] == 1:  # trailing singleton axes (e.g. X,Y,Z,1,1)
        dims.pop()
    if len(dims) < 2:
        raise AnatomeshError(f"the image has shape {shape}; a volume needs at least 2 axes: give a 3D image", p)
    if any(d == 0 for d in dims):
        raise AnatomeshError(f"the image has shape {shape}: it holds no voxels; export it again", p)
    if len(dims) > 4:
        raise AnatomeshError(f"the image is {len(dims)}D, shape {shape} (a vector or tensor field?); "
                             "only 3D volumes and 4D series are supported", p)
    if len(dims) == 4:
        n = dims[3]
        if volume_index is None:
            if n == 1:
                return tuple(dims[:3]), 0
            raise AnatomeshError(
                f"the image is 4D, shape {shape}, with {n} volumes; choose one with "
                f"volume_index (CLI --volume N, N from 0 to {n - 1})", p)
        if not 0 <= int(volume_index) < n:
            raise AnatomeshError(f"volume index {volume_index} is out of range: the image has shape "
                                 f"{shape}, {n} volumes: choose one from 0 to {n - 1}", p)
        return tuple(dims[:3]), int(volume_index)
    if volume_index not in (None, 0):
        raise AnatomeshError(f"volume index {volume_index} given but the image is {len(dims)}D, "
                             f"shape {shape}, with a single volume: leave the volume index out", p)
    return tuple(dims) + ((1,) if len(dims) == 2 else ()), None


def _read_voxels(proxy, index: Optional[int], shape3, p: Path, scaled: bool) -> np.ndarray:
    """Voxels of the whole 3D image, or of volume ``index`` of a 4D one, scaling applied (float32)."""
    try:
        if index is None:
            raw = proxy.get_unscaled() if hasattr(proxy, "get_unscaled") else proxy
            data = np.asarray(raw)
            if scaled:  # scale in float32 (nibabel would make float64: twice the memory)
                slope, inter = float(proxy.slope), float(proxy.inter)
                data = data.astype(np.float32)
                if slope != 1.0:
                    data *= np.float32(slope)
                if inter != 0.0:
                    data += np.float32(inter)
        else:  # nibabel reads just this volume and applies the scaling (float64 when scaled)
            sl = (slice(None),) * 3 + (index,) + (0,) * (len(proxy.shape) - 4)
            data = np.asarray(proxy[sl])
            if scaled:
                data = data.astype(np.float32)
    except MemoryError:
        raise AnatomeshError(f"not enough memory to read a volume of shape {tuple(shape3)}; close other "
                             "programs or use a machine with more memory", p) from None
    except Exception as err:  # EOFError, zlib.error, OSError, ValueError from a truncated file
        raise AnatomeshError(f"could not read the voxel data ({reason(err)}): the file is "
                             "truncated or corrupt; export or download it again", p) from None
    return data


def _affine_mm(img, hdr, p: Path, warnings: List[str]):
    affine = np.array(img.affine, dtype=np.float64)
    if int(hdr["sform_code"]) == 0 and int(hdr["qform_code"]) == 0:
        warnings.append("the file has neither sform nor qform: orientation and origin are unknown; "
                        "using voxel sizes only (nibabel's fallback)")
    unit = hdr.get_xyzt_units()[0] if hasattr(hdr, "get_xyzt_units") else "unknown"
    if unit in _TO_MM and unit != "mm":
        affine[:3, :] *= _TO_MM[unit]
        warnings.append(f"spacing stored in {unit}s; converted to mm")
    units = unit if unit in _TO_MM else "mm (unspecified in the file)"
    if not np.all(np.isfinite(affine)):
        raise AnatomeshError("the affine (sform/qform) holds NaN or infinite numbers; fix the header", p)
    if abs(np.linalg.det(affine[:3, :3])) < 1e-12:
        raise AnatomeshError(f"the affine is singular (voxel sizes {tuple(np.round(img.header.get_zooms()[:3], 6))}); "
                             "fix the header's pixdim/sform", p)
    return affine, units


def _text(raw) -> str:
    if raw is None:
        return ""
    try:
        b = raw.tobytes() if hasattr(raw, "tobytes") else bytes(raw)
    except (TypeError, ValueError):
        return str(raw)
    return b.split(b"\x00", 1)[0].decode("latin-1").strip()

