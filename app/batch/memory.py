"""How many studies fit on this machine at once: each study's peak memory estimated from its
volume's size (read from the file header only, no voxel is read), the cores and the memory free.

The estimate is ``WORKER_BYTES + BYTES_PER_VOXEL * voxels``: a worker process with the pipeline
loaded, plus what one voxel of the label map costs at the pipeline's peak (the label array, the
extraction's bit planes and the surfaces, smoothed). The constants below cover the measured
peak resident memory of the default recipe on the TotalSegmentator maps, upsampled up to 3x,
with a margin (``benchmarks/bench_batch.py``; figures in docs/MEASURED.md).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional, Tuple

#: resident memory of a worker process with the pipeline loaded (numpy, numba kernels), bytes
WORKER_BYTES = 320 * 2**20
#: peak bytes per voxel of a study's label map with the default recipe (measured <= 57 B)
BYTES_PER_VOXEL = 64
#: the estimate for a study whose size cannot be read from a header
UNKNOWN_BYTES = 2 * 2**30
#: fraction of the free memory the batch plans to use
MEMORY_SHARE = 0.8


def estimate_bytes(path) -> int:
    """Estimated peak memory (bytes) of one study of the input at ``path``."""
    voxels = volume_voxels(Path(path))
    return UNKNOWN_BYTES if voxels is None else WORKER_BYTES + BYTES_PER_VOXEL * voxels


def volume_voxels(path: Path) -> Optional[int]:
    """Voxels of the volume at ``path`` from its header (NIfTI, NRRD, DICOM); for a folder of
    masks the largest mask; None when unknown (missing, unreadable or another kind of file)."""
    try:
        if path.is_dir():
            return _folder_voxels(path)
        name = path.name.lower()
        if name.endswith((".nii", ".nii.gz")):
            import nibabel

            shape = nibabel.load(str(path)).header.get_data_shape()
            return int(_product(shape[:3]))
        if name.endswith((".nrrd", ".nhdr")):
            import nrrd

            return int(_product(nrrd.read_header(str(path))["sizes"]))
        return _dicom_voxels([path])
    except Exception:  # noqa: BLE001 - a header we cannot read: the study fails later, alone
        return None


def _folder_voxels(folder: Path) -> Optional[int]:
    files = [f for f in folder.iterdir() if f.is_file() and not f.name.startswith(".")]
    images = [f for f in files if f.name.lower().endswith((".nii", ".nii.gz", ".nrrd", ".nhdr"))]
    if images:
        sizes = [volume_voxels(f) for f in images]
        return max((s for s in sizes if s is not None), default=None)
    return _dicom_voxels(sorted(f for f in folder.rglob("*") if f.is_file()))


def _dicom_voxels(files) -> Optional[int]:
    import pydicom

    for f in files:
        try:
            ds = pydicom.dcmread(str(f), stop_before_pixels=True)
        except Exception:  # noqa: BLE001 - not DICOM: try the next file
            continue
        if "Rows" in ds and "Columns" in ds:
            frames = int(getattr(ds, "NumberOfFrames", 1) or 1)
            return int(ds.Rows) * int(ds.Columns) * max(frames, len(files))
    return None


def _product(values) -> int:
    out = 1
    for v in values:
        out *= int(v)
    return out


# -- the machine ------------------------------------------------------------------------------
def machine() -> Tuple[int, int]:
    """``(cores, free memory in bytes)`` this process may use (CPU affinity and cgroup limits
    of containers counted)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    quota = _cgroup_cpus()
    if quota:
        cores = max(1, min(cores, quota))
    free = _meminfo_available()
    limit = _cgroup_memory_left()
    if limit is not None:
        free = min(free, limit) if free else limit
    if not free:
        try:
            free = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            free = 4 * 2**30
    return cores, int(free)


def pool_size(estimates, workers: Optional[int] = None, memory: Optional[int] = None) -> Tuple[int, int]:
    """``(worker processes, memory budget in bytes)`` for studies of the given estimated peaks:
    at most ``workers`` (default: the cores), never more than the smallest studies fit in the
    budget (``memory``, default :data:`MEMORY_SHARE` of the free memory), at least one."""
    cores, free = machine()
    budget = int(memory) if memory else int(free * MEMORY_SHARE)
    n = int(workers) if workers else cores
    smallest = min(estimates, default=WORKER_BYTES)
    return max(1, min(n, len(estimates) or 1, budget // max(1, smallest))), budget


def _meminfo_available() -> Optional[int]:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_memory_left() -> Optional[int]:
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit == "max":
            return None
        used = int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
        return max(0, int(limit) - used)
    except (OSError, ValueError):
        return None


def _cgroup_cpus() -> Optional[int]:
    try:
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()[:2]
        return None if quota == "max" else max(1, int(int(quota) / int(period)))
    except (OSError, ValueError):
        return None
