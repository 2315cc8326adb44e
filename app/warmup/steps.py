"""The warm-up's steps (:mod:`.compile`): each runs a stage of the flow on tiny made-up inputs, so
that the kernels and argument types that stage's real runs use are compiled and cached.

A step is what one door needs before it can run without compiling: the add-on's import waits for
"reading" and "label surfaces", the smoothing of extracted organs for "label smoothing", a
slider's later runs for "smoothing" (``addon/warmup.py``, ``addon/live.py``). Tests check that
after its steps the sample's extraction and first smoothing compile nothing
(``tests/app/test_warmup.py``).
"""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Dict

import numpy as np

#: what a first session needs first — reading, extraction of label maps and of scans (the
#: add-on's first extraction waits for these), the first smoothing of a label map's surfaces
#: (the add-on's smoothing of extracted organs waits for it), the default smoothing with its
#: report, sliders and isosurfaces, the run's report and files — then the rest
DEFAULT_STEPS = ("reading", "label surfaces", "isosurfaces", "large label maps", "label smoothing",
                 "smoothing", "files and report")
EXTRA_STEPS = ("more data types", "decimation and levels of detail", "print checks and fixes")


def _label_map(dtype, big: int = 0) -> np.ndarray:
    """12x11x9 map: a ball (label 1 or ``big``) beside a box (label 2) it touches, and a voxel
    of label 2 touching the box at a corner (a pinch point and a speck)."""
    i, j, k = np.ogrid[:12, :11, :9]
    data = np.zeros((12, 11, 9), dtype)
    data[(i - 5) ** 2 + (j - 5) ** 2 + (k - 4) ** 2 <= 10] = big or 1
    data[7:11, 3:8, 2:7] = 2
    data[11, 8, 7] = 2
    return data


def _scan(dtype) -> np.ndarray:
    """12x12x10 CT-like scan: a dense ball (~1000 HU) with a softer shell in air (-1000)."""
    i, j, k = np.ogrid[:12, :12, :10]
    r2 = (i - 5.5) ** 2 + (j - 5.5) ** 2 + (k - 4.5) ** 2
    return np.where(r2 <= 9, 1000, np.where(r2 <= 16, 40, -1000)).astype(dtype)


def _save_nifti(data: np.ndarray, path: Path, spacing=(1.0, 1.0, 2.5)) -> str:
    import nibabel as nib

    path.parent.mkdir(parents=True, exist_ok=True)
    img = nib.Nifti1Image(data, np.diag(list(spacing) + [1.0]))
    img.header.set_xyzt_units("mm")
    nib.save(img, str(path))
    return str(path)


def _mesh(folder: Path, source: str, **settings) -> None:
    """One run of the whole flow (:func:`anatomesh.app.flow.run.run`) with these settings."""
    from ..flow.recipe import Recipe
    from ..flow.run import run

    run(Recipe(input=source, out_dir=str(folder / "out"), overwrite=True, **settings))


# -- the steps -------------------------------------------------------------------------------------
def _reading(folder: Path) -> None:
    """Counting values (label detection, input facts): what reading a NIfTI/NRRD file or a mask
    folder compiles (DICOM series: with the scans, :func:`_isosurfaces`)."""
    from ...core.io.values import value_counts

    for dtype in (np.bool_, np.uint8, np.uint16, np.int16, np.int32):
        value_counts(_label_map(dtype))


def _label_surfaces(folder: Path) -> None:
    """A uint8 label map's surfaces extracted and split into shells with their pinch points moved
    apart, as every file and the add-on's objects show them (no file: the lanes start compiling
    without importing and running a reader first), in Fortran order too (as NIfTI readers give
    the voxels: the lattice's columns put back in place)."""
    from ...core.extract.multilabel import label_surfaces
    from ..flow.stages import output_shells

    labels = _label_map(np.uint8)
    output_shells(label_surfaces(labels, affine=np.diag([1.0, 1.0, 2.5, 1.0])))
    label_surfaces(np.asfortranarray(labels))


def _isosurfaces(folder: Path) -> None:
    """The DICOM slice layout kernel (a CT or MR series' pixels; the add-on's import of DICOM
    waits for this step), then an int16 scan read from NIfTI and its isosurface at one level.
    After the label maps' steps: the first extraction of a label map waits less."""
    from ...core.extract.isosurface import isosurfaces
    from ...core.io import load
    from ...core.io.dicom_pixels import to_volume_layout

    for stored in (np.uint16, np.int16):
        stack = np.arange(2 * 3 * 4, dtype=stored).reshape(2, 3, 4)
        to_volume_layout(stack, np.ones(2), np.full(2, -1024.0))  # integer rescale → int16
        to_volume_layout(stack, np.full(2, 0.5), np.zeros(2))      # fractional → float32
    isosurfaces(load(_save_nifti(_scan(np.int16), folder / "i16.nii.gz")), [300.0], cap=True)


def _large_label_maps(folder: Path) -> None:
    """The label extraction's two parallel passes, which maps of more than
    :data:`~anatomesh.core.extract.multilabel.PARALLEL_MIN_VOXELS` voxels run (after the small
    maps' steps)."""
    from ...core.extract.multilabel import label_surfaces

    with _parallel_label_passes():
        label_surfaces(_label_map(np.uint8))


@contextmanager
def _parallel_label_passes():
    """Within the block, label maps of any size run the parallel passes (tiny inputs compile
    what large maps run)."""
    from ...core.extract import multilabel

    threshold = multilabel.PARALLEL_MIN_VOXELS
    multilabel.PARALLEL_MIN_VOXELS = 0
    try:
        yield
    finally:
        multilabel.PARALLEL_MIN_VOXELS = threshold


def _files_and_report(folder: Path) -> None:
    """The rest of a run without smoothing: the report's facts and the STL files."""
    _mesh(folder / "u8", _save_nifti(_label_map(np.uint8), folder / "u8.nii.gz"), smooth="none")
    _mesh(folder / "i16", _save_nifti(_scan(np.int16), folder / "i16.nii.gz"), levels=[300.0],
          smooth="none")


def _more_types(folder: Path) -> None:
    """Label maps with values above 255 (uint16; small and large) and float32 scans at two
    levels."""
    from ...core.extract.multilabel import label_surfaces

    _mesh(folder / "u16", _save_nifti(_label_map(np.uint16, big=300), folder / "u16.nii.gz"))
    with _parallel_label_passes():
        label_surfaces(_label_map(np.uint16, big=300))
    _mesh(folder / "f32", _save_nifti(_scan(np.float32) + 0.5, folder / "f32.nii.gz",
                                      spacing=(1.0, 1.0, 1.0)), levels=[300.0, -400.0])


def _label_smoothing(folder: Path) -> None:
    """What the add-on's first smoothing of a label map's surfaces runs (a smoothing session's
    first run with the default settings, thick and isotropic slices, then the pinch points moved
    apart): extracted organs are smoothed this early, the rest of :func:`_smoothing` compiles
    after."""
    from ...core.extract.multilabel import label_surfaces
    from ...core.smooth.session import SmoothingSession
    from ..flow import stages
    from ..flow.recipe import Recipe

    method, settings = stages.smoothing(Recipe())
    for spacing in ((1.0, 1.0, 2.5), (1.0, 1.0, 1.0)):
        s = label_surfaces(_label_map(np.uint8), affine=np.diag(list(spacing) + [1.0]))
        session = SmoothingSession(s)
        out = session.run(method, **settings)[0]
    stages.output_shells(s.copy_with_vertices(out))  # the smoothed objects' pinch points moved apart
    for dtype in (np.float32, np.float64):  # the component guard on the kept and the working positions
        session.components().volumes(out.astype(dtype))
    _rounds_after_untangling(session, out)  # organs that touch, e.g. the sample's


def _rounds_after_untangling(session, out: np.ndarray) -> None:
    """The unfold and untangle rounds after an untangling that turned faces over, on a face
    turned over by swapping two of its corners."""
    a, b = session.faces[0, :2]
    out[[a, b]] = out[[b, a]]
    session._unfold_untangled(out, session.boxes())


def _smoothing(folder: Path) -> None:
    """The default smoothing (:func:`anatomesh.app.flow.stages.smooth`) of label surfaces (thick
    slices: with the staircase pass; isotropic) and of an isosurface, the cached session the
    live sliders run (:class:`anatomesh.core.smooth.session.SmoothingSession`) with and without
    a maximum deviation, the add-on's relaxing of selected vertices, and the rounds
    that unfold and untangle again after untangling."""
    from ...core.extract.isosurface import isosurfaces
    from ...core.extract.multilabel import label_surfaces
    from ...core.model.surfaceset import SurfaceSet
    from ...core.smooth.constraints import Constraint
    from ...core.smooth.driver import smooth
    from ...core.smooth.session import SmoothingSession
    from ..flow import stages
    from ..flow.recipe import Recipe

    for spacing in ((1.0, 1.0, 2.5), (1.0, 1.0, 1.0)):
        s = label_surfaces(_label_map(np.uint8), affine=np.diag(list(spacing) + [1.0]))
        stages.smooth(s, Recipe())
    iso = isosurfaces(_scan(np.int16), [300.0], cap=True)
    stages.smooth(SurfaceSet.from_meshes(iso, np.eye(4)), Recipe())
    method, settings = stages.smoothing(Recipe())
    live = SmoothingSession(s)
    live.run(method, **settings)
    # a slider's second run (the candidate pairs listed once, then only tested) with the
    # panel's "max deviation" (a cap around each start: other passes)
    live.run(method, **dict(settings, max_deviation=1.0))
    # the add-on's "relax selected" edit tool: Laplacian passes with a gain per vertex
    smooth(s.vertices, s.faces, "laplacian", iterations=2, lam=0.5, fold_guard=True,
           constraint=Constraint(max_deviation=1.0), gain=np.ones(len(s.vertices)))
    # the unfold and untangle rounds after an untangling that turned faces over (bone isosurfaces)
    session = SmoothingSession(SurfaceSet.from_meshes(iso, np.eye(4)))
    _rounds_after_untangling(session, session.run(method, **settings)[0])


def _decimation(folder: Path) -> None:
    labels = _save_nifti(_label_map(np.uint8), folder / "u8.nii.gz")
    _mesh(folder / "lab", labels, decimate=0.5, lod=2, formats=["stl", "3mf", "glb"])
    _mesh(folder / "iso", _save_nifti(_scan(np.int16), folder / "i16.nii.gz"), levels=[300.0],
          target_faces=100, formats=["ply", "obj"])


def _printing(folder: Path) -> None:
    labels = _save_nifti(_label_map(np.uint8), folder / "u8.nii.gz")
    _mesh(folder / "check", labels, check=True)
    _mesh(folder / "fix", labels, thicken=True, clearance=0.2, fuse=[[1, 2]], check=True)


#: each step by name: what it runs (``folder`` a scratch folder of its own)
STEPS: Dict[str, Callable[[Path], None]] = {
    "reading": _reading,
    "label surfaces": _label_surfaces,
    "isosurfaces": _isosurfaces,
    "large label maps": _large_label_maps,
    "label smoothing": _label_smoothing,
    "smoothing": _smoothing,
    "files and report": _files_and_report,
    "more data types": _more_types,
    "decimation and levels of detail": _decimation,
    "print checks and fixes": _printing,
}
