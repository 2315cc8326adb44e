"""The pixels of a DICOM image series: decoders checked first (JPEG, JPEG 2000 ... via pydicom's
pylibjpeg plug-ins), slices decoded into one stack and rescaled to the volume layout by a numba
kernel.

Uncompressed little-endian slices (the common case) are read straight into the stack: the pixel
data element is the file's last one, so its tag and length are checked just before the last
``rows x cols x bytes`` of the file and those bytes are read in place, without parsing the header
a second time; anything else goes through pydicom's decoders."""
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
from .library_messages import reason
from .dicom_values import int_or

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
    native = _native_dtype(headers[0])
    if native is not None:
        stack = np.empty((n_k, rows, cols), native)
    for k, (path, ds) in enumerate(zip(files, headers)):
        if stack is not None and stack.dtype == native and _native_dtype(ds) == native \
                and _read_native(path, stack[k], _RAW_SYNTAXES[transfer_syntax(ds)]):
            report(progress, (k + 1) / n_k, f"reading slice {k + 1}/{n_k}")
            continue
        arr = _decode(path, ds)
        if arr.shape != (rows, cols):
            raise AnatomeshError(f"the pixel array has shape {arr.shape}, expected "
                                 f"({rows}, {cols}): not a greyscale slice like the others; remove it from "
                                 "the series' folder", path)
        if stack is None:
            stack = np.empty((n_k, rows, cols), arr.dtype)
        elif arr.dtype != stack.dtype:
            stack = stack.astype(np.result_type(stack.dtype, arr.dtype))
        stack[k] = arr
        report(progress, (k + 1) / n_k, f"reading slice {k + 1}/{n_k}")
    if native is not None and stack.dtype == native:
        _correct_unused_bits(stack, headers[0])
    return stack


#: transfer syntaxes whose pixel data is the raw little-endian array
_RAW_SYNTAXES = {_uid.ImplicitVRLittleEndian: 8, _uid.ExplicitVRLittleEndian: 12}
_PIXEL_TAG = b"\xe0\x7f\x10\x00"  # (7FE0,0010) Pixel Data, little endian


def _native_dtype(ds):
    """The stored dtype of an uncompressed little-endian greyscale slice, else None."""
    if transfer_syntax(ds) not in _RAW_SYNTAXES or int_or(ds.get("SamplesPerPixel"), 1) != 1:
        return None
    bits = int_or(ds.get("BitsAllocated"), 0)
    if bits not in (8, 16, 32) or int_or(ds.get("BitsStored"), bits) > bits:
        return None
    signed = int_or(ds.get("PixelRepresentation"), 0) == 1
    return np.dtype(f"<{'i' if signed else 'u'}{bits // 8}")


def _read_native(path: Path, out: np.ndarray, head: int) -> bool:
    """Read the slice's raw pixels into ``out`` (C-contiguous) when the Pixel Data element is
    the file's last and holds exactly ``out.nbytes``; False otherwise. ``head`` is the size of
    the element's header: 12 with explicit VR (tag, VR, 2 reserved bytes, length), 8 without."""
    n = out.nbytes
    try:
        with open(path, "rb") as fh:
            start = fh.seek(0, 2) - n - head
            if start < 0:
                return False
            fh.seek(start)
            h = fh.read(head)
            vr_ok = head == 8 or (h[4:6] in (b"OW", b"OB") and h[6:8] == b"\0\0")
            if h[:4] != _PIXEL_TAG or not vr_ok or int.from_bytes(h[-4:], "little") != n:
                return False
            return fh.readinto(memoryview(out).cast("B")) == n
    except OSError:
        return False


def _correct_unused_bits(stack: np.ndarray, ds) -> None:
    """As pydicom does for raw data: ignore the bits above BitsStored (sign-extending signed
    values), in place."""
    allocated = int_or(ds.get("BitsAllocated"), 8 * stack.itemsize)
    stored = int_or(ds.get("BitsStored"), allocated)
    if 0 < stored < allocated:
        shift = allocated - stored
        np.left_shift(stack, shift, out=stack)
        np.right_shift(stack, shift, out=stack)


def _check_decoders(files, headers, source):
    seen = set()
    for path, ds in zip(files, headers):
        ts = transfer_syntax(ds)
        if ts not in seen:
            seen.add(ts)
            require_decoder(ds, path, source)


def require_decoder(ds, path: Path, named=None) -> None:
    """Raise unless pydicom can decode ``ds``'s transfer syntax here: a syntax it cannot decode at
    all names ``path``, a missing plug-in names ``named`` (default ``path``) and the pip package."""
    ts = transfer_syntax(ds)
    try:
        decoder = get_decoder(ts)
    except NotImplementedError:
        raise AnatomeshError(f"the pixel data is stored as {ts.name} ({ts}), which pydicom "
                             "cannot decode; convert the file to uncompressed DICOM first "
                             "(e.g. dcmtk's dcmdjpeg or gdcmconv --raw)", path) from None
    if not decoder.is_available:
        package = _CODEC_PACKAGES.get(ts, "pylibjpeg pylibjpeg-openjpeg pylibjpeg-libjpeg")
        raise AnatomeshError(f"the pixel data is compressed as {ts.name} ({ts}) and no "
                             f"decoder for it is installed; install one with 'pip install "
                             f"{package}' in the Python that runs Anatomesh", named or path)


def _decode(path: Path, ds) -> np.ndarray:
    try:
        if ds.file_meta.get("TransferSyntaxUID"):
            return pixel_array(path)
        full = pydicom.dcmread(path, force=True)  # bare data set without file meta
        full.file_meta.TransferSyntaxUID = transfer_syntax(full)
        return full.pixel_array
    except Exception as err:  # decoders raise many kinds on damaged data
        raise AnatomeshError(f"cannot decode the pixel data ({reason(err)}): the file is "
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
    transpose_rescale(np.ascontiguousarray(stack), slope.astype(kind), intercept.astype(kind), out, 0)
    return out


#: slices decoded at a time when the output is read block by block
BLOCK_SLICES = 16


def read_series(files: List[Path], headers: list, source: Path, progress, slope: np.ndarray,
                intercept: np.ndarray) -> np.ndarray:
    """The sorted slices decoded and rescaled into the (C, R, K) volume layout (see
    :func:`to_volume_layout`).

    When the stored bit range (BitsStored, PixelRepresentation) and integer rescales guarantee
    int16 values — CT's usual case — slices are decoded :data:`BLOCK_SLICES` at a time and
    rescaled straight into the output, so memory holds the volume plus one block; otherwise the
    whole stack of stored values is decoded first and its range decides int16 or float32."""
    n_k = len(files)
    if not _int16_guaranteed(headers, slope, intercept):
        return to_volume_layout(read_pixels(files, headers, source, progress), slope, intercept)
    from ._dicom_kernels import transpose_rescale

    rows, cols = int_or(headers[0].get("Rows"), 0), int_or(headers[0].get("Columns"), 0)
    check_fits_in_memory((cols, rows, n_k), np.int16, "the DICOM series", source, factor=1.1)
    out = np.empty((cols, rows, n_k), np.int16)
    s, b = slope.astype(np.int64), intercept.astype(np.int64)
    for k0 in range(0, n_k, BLOCK_SLICES):
        k1 = min(n_k, k0 + BLOCK_SLICES)
        block = read_pixels(files[k0:k1], headers[k0:k1], source, _slices_of(progress, k0, k1, n_k))
        if not block.dtype.isnative:  # numba reads native byte order only
            block = block.astype(block.dtype.newbyteorder("="))
        transpose_rescale(block, s[k0:k1], b[k0:k1], out, k0)
    return out


def _slices_of(progress, k0: int, k1: int, n_k: int):
    """Progress of one block's slices, reported as slices of the whole series."""
    if progress is None:
        return None
    return lambda f, text="": report(progress, (k0 + f * (k1 - k0)) / n_k,
                                     f"reading slice {k0 + round(f * (k1 - k0))}/{n_k}")


def _int16_guaranteed(headers: list, slope: np.ndarray, intercept: np.ndarray) -> bool:
    """Every storable value of every slice, rescaled, is a whole number within int16."""
    if not all(float(v).is_integer() for v in np.r_[slope, intercept]):
        return False
    for ds, s, b in zip(headers, slope, intercept):
        stored = int_or(ds.get("BitsStored"), int_or(ds.get("BitsAllocated"), 0))
        if not 0 < stored <= 16:
            return False
        signed = int_or(ds.get("PixelRepresentation"), 0) == 1
        lo, hi = (-(1 << (stored - 1)), (1 << (stored - 1)) - 1) if signed else (0, (1 << stored) - 1)
        ends = (lo * s + b, hi * s + b)
        if min(ends) < -32768 or max(ends) > 32767:
            return False
    return True
