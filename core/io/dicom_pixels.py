"""The pixels of a DICOM image series: decoders checked first (JPEG, JPEG 2000 ... via pydicom's
pylibjpeg plug-ins), slices decoded into one stack and rescaled to the volume layout by a numba
kernel."""
from __future__ import annotations

from pathlib import Path
from typing import List

import numpy as np
import pydicom
from pydicom import uid as _uid
from pydicom.pixels import get_decoder, pixel_array

from ..model.errors import AnatomeshError
from ..model.progress import report
from ..model.volume import check_fits_in_memory
from .dicom_values import int_or, short_error

# transfer syntax → the pip package(s) whose pydicom plug-in decodes it


_CODEC_PACKAGES = {
    _uid.JPEGBaseline8Bit: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGExtended12Bit: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLossless: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLosslessSV1: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLSLossless: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEGLSNearLossless: "pylibjpeg pylibjpeg-libjpeg",
    _uid.JPEG2000Lossless: "pylibjpeg pylibjpeg-openjpeg",
    _uid.JPEG2000: "pylibjpeg pylibjpeg-openjpeg",
    _uid.HTJ2KLossless: "pylibjpeg pylibjpeg-openjpeg",
    _uid.HTJ2KLosslessRPCL: "pylibjpeg pylibjpeg-openjpeg",
    _uid.HTJ2K: "pylibjpeg pylibjpeg-openjpeg",
    _uid.RLELossless: "pylibjpeg pylibjpeg-rle",
}


def read_pixels(files: List[Path], headers: list, source: Path, progress) -> np.ndarray:
    """Decode the sorted slices into a (K, rows, cols) stack of stored values."""
    _check_decoders(files, headers, source)
    n_k = len(files)
    rows, cols = int_or(headers[0].get("Rows"), 0), int_or(headers[0].get("Columns"), 0)
    itemsize = max(1, int_or(headers[0].get("BitsAllocated"), 16) // 8)
    # the stack of stored values plus the (at most float32) output
    check_fits_in_memory((cols, rows, n_k), np.float32, "the DICOM series", source,
                         factor=(itemsize + 4) / 4)
    stack = None
    for k, (path, ds) in enumerate(zip(files, headers)):
        arr = _decode(path, ds)
        if arr.shape != (rows, cols):
            raise AnatomeshError(f"the pixel array has shape {arr.shape}, expected "
                                 f"({rows}, {cols}): not a greyscale slice like the others", path)
        if stack is None:
            stack = np.empty((n_k, rows, cols), arr.dtype)
        elif arr.dtype != stack.dtype:
            stack = stack.astype(np.result_type(stack.dtype, arr.dtype))
        stack[k] = arr
        report(progress, (k + 1) / n_k, f"reading slice {k + 1}/{n_k}")
    return stack


def _check_decoders(files, headers, source):
    seen = set()
    for path, ds in zip(files, headers):
        ts = transfer_syntax(ds)
        if ts in seen:
            continue
        seen.add(ts)
        try:
            decoder = get_decoder(ts)
        except NotImplementedError:
            raise AnatomeshError(f"the pixel data is stored as {ts.name} ({ts}), which pydicom "
                                 "cannot decode; convert the series to uncompressed DICOM first "
                                 "(e.g. dcmtk's dcmdjpeg or gdcmconv --raw)", path) from None
        if not decoder.is_available:
            package = _CODEC_PACKAGES.get(ts, "pylibjpeg pylibjpeg-openjpeg pylibjpeg-libjpeg")
            raise AnatomeshError(f"the pixel data is compressed as {ts.name} ({ts}) and no "
                                 f"decoder for it is installed; install one with 'pip install "
                                 f"{package}' in the Python that runs Anatomesh", source)


def _decode(path: Path, ds) -> np.ndarray:
    try:
        if ds.file_meta.get("TransferSyntaxUID"):
            return pixel_array(path)
        full = pydicom.dcmread(path, force=True)  # bare data set without file meta
        full.file_meta.TransferSyntaxUID = transfer_syntax(full)
        return full.pixel_array
    except Exception as err:  # decoders raise many kinds on damaged data
        raise AnatomeshError(f"cannot decode the pixel data ({short_error(err)}): the file is "
                             "truncated or damaged; copy it again", path) from None


def transfer_syntax(ds) -> _uid.UID:
    value = ds.file_meta.get("TransferSyntaxUID") if getattr(ds, "file_meta", None) else None
    if value:
        return _uid.UID(str(value))
    implicit, little = getattr(ds, "original_encoding", (True, True))
    if implicit:
        return _uid.ImplicitVRLittleEndian
    return _uid.ExplicitVRLittleEndian if little else _uid.ExplicitVRBigEndian


def to_volume_layout(stack: np.ndarray, slope: np.ndarray, intercept: np.ndarray) -> np.ndarray:
    """(K, R, C) stored values → C-contiguous (C, R, K) rescaled, int16 when exact, else float32."""
    from ._dicom_kernels import transpose_rescale

    n_k, rows, cols = stack.shape
    integer = stack.dtype.kind in "iu" and all(float(v).is_integer()
                                               for v in np.r_[slope, intercept])
    if integer:
        lo = stack.min(axis=(1, 2)).astype(np.float64)
        hi = stack.max(axis=(1, 2)).astype(np.float64)
        ends = np.r_[lo * slope + intercept, hi * slope + intercept]
        integer = ends.min() >= -32768 and ends.max() <= 32767
    out = np.empty((cols, rows, n_k), np.int16 if integer else np.float32)
    if not stack.dtype.isnative:  # numba reads native byte order only
        stack = stack.astype(stack.dtype.newbyteorder("="))
    kind = np.int64 if integer else np.float64
    transpose_rescale(np.ascontiguousarray(stack), slope.astype(kind), intercept.astype(kind), out)
    return out
