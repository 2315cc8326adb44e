"""The files of a run: where each goes, refusing to overwrite any, and writing them.

Formats (``recipe.formats``), all in mm in the recipe's space: ``stl``, ``ply``, ``obj``, ``3mf``
one file per surface; ``dicom`` one DICOM Encapsulated STL object (``<name>.dcm``) per surface,
in the study and frame of reference of a DICOM source (LPS mm, whatever ``space`` says); ``3mf`` also one combined print-ready ``<stem>.3mf`` (one object per part,
colours); ``glb`` one ``<stem>.glb`` with every surface; ``blend`` a Blender file built by the
add-on exactly as its Extract button would, ``png`` a Cycles render of that scene (both need
Blender: the add-on provides the writer, see :func:`blender_writer`). ``<stem>`` is a slug of
the scan's name. ``lod`` > 1 also writes ``<stem>_lod0.glb`` .. ``_lod{n-1}.glb``.
"""
from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional

from ...core.export.mesh_files import write_mesh
from ...core.export.common import file_stem, refuse_overwrite, unique_stems
from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh
from ...core.model.progress import Progress, report
from ...core.model.surfaceset import SurfaceSet
from ...core.model.volume import Volume
from .recipe import (BLENDER_FORMATS, DICOM_FORMAT, RECIPE_FILE, SCENE_ONLY_FORMATS, SURFACE_FORMATS,
                     WEB_FORMAT, Recipe)
from .stages import clean, output_shells

#: entry-point group through which the add-on offers its ``.blend``/PNG writer (pyproject.toml)
BLENDER_ENTRY_POINTS = "anatomesh.blender"
_BLENDER_WRITER: List[Callable] = []
#: file suffix of a format when it is not the format's name
FILE_SUFFIX = {DICOM_FORMAT: "dcm"}
#: the turntable's folder of frames (and, with ".mp4", its video) in the output folder
TURNTABLE = "turntable"


@dataclass
class Plan:
    """Every path a run writes, decided (and checked for overwriting) before anything is written."""

    surfaces: List[Dict[str, Path]]          # per surface: format -> path
    scene: Dict[str, Path]                   # combined 3mf, glb, blend, png
    lods: List[Path]                         # GLB levels of detail, finest first
    report: Path
    recipe: Path
    stem: str = "scan"
    extra: List[Path] = field(default_factory=list)
    dicom_reference: Optional[Dict] = None  # format "dicom": study/frame of reference of the source

    def all_paths(self) -> List[Path]:
        return ([p for fs in self.surfaces for p in fs.values()] + list(self.scene.values())
                + self.lods + [self.report, self.recipe] + self.extra)


def refuse_existing(recipe: Recipe) -> None:
    """Before anything is read: raise :class:`AnatomeshError` when the run's report or recipe file
    exists and ``recipe.overwrite`` is not set (every run writes both, so a folder holding an
    earlier run's results is refused at once; :func:`plan` checks every other file)."""
    report_path = _report_path(recipe)
    refuse_overwrite([report_path, report_path.parent / RECIPE_FILE], recipe.overwrite)


def _report_path(recipe: Recipe) -> Path:
    return Path(recipe.report) if recipe.report else Path(recipe.out_dir) / "report.json"


def plan(meshes: List[Mesh], volume: Volume, recipe: Recipe) -> Plan:
    """The paths of every output of ``recipe`` for ``meshes``; raises :class:`AnatomeshError`
    when one exists and ``recipe.overwrite`` is not set (nothing is written then)."""
    out_dir = Path(recipe.out_dir)
    report_path = _report_path(recipe)
    stem = scan_stem(volume, recipe)
    stems = unique_stems([m.name for m in meshes], [m.value for m in meshes])
    per_surface = [{fmt: out_dir / f"{s}.{FILE_SUFFIX.get(fmt, fmt)}" for fmt in recipe.formats
                    if fmt in SURFACE_FORMATS} for s in stems]
    taken = {p for fs in per_surface for p in fs.values()}
    name = stem if all(out_dir / f"{stem}.{f}" not in taken for f in ("3mf", "glb")) else f"{stem}_all"
    scene = {fmt: out_dir / f"{name}.{fmt}" for fmt in ("3mf",) + SCENE_ONLY_FORMATS
             if fmt in recipe.formats}
    if "png" in scene and list(recipe.views) != ["anterior"]:  # several views: one PNG each
        del scene["png"]
        scene.update({f"png_{v}": out_dir / f"{name}_{v}.png" for v in recipe.views})
    lods = [out_dir / f"{stem}_lod{i}.glb" for i in range(recipe.lod if recipe.lod > 1 else 0)]
    p = Plan(per_surface, scene, lods, report_path, report_path.parent / RECIPE_FILE, stem)
    if recipe.turntable:  # the frames' folder and the video
        scene.update(turntable=out_dir / TURNTABLE, mp4=out_dir / f"{TURNTABLE}.mp4")
        p.extra += [out_dir / TURNTABLE / f"frame_{i:04d}.png" for i in range(1, recipe.turntable + 1)]
    if WEB_FORMAT in recipe.formats:  # the page's folder
        from ..web.page import page_paths

        p.extra += page_paths(web_dir(recipe), recipe.web_levels)
    if DICOM_FORMAT in recipe.formats:  # segmentations: the study the objects join
        from ...core.export.dicom_stl import dicom_reference

        p.dicom_reference = dicom_reference(volume)
    refuse_overwrite(p.all_paths(), recipe.overwrite)
    return p


def scan_stem(volume: Volume, recipe: Recipe) -> str:
    """A file-name slug of the scan's name (``example_seg.nii.gz`` → ``example_seg``)."""
    src = volume.meta.get("source") or recipe.input
    if isinstance(src, (list, tuple)):
        src = Path(str(src[0])).parent if len(src) > 1 else src[0]
    base = Path(str(src).rstrip("/\\")).name or "scan"
    for suffix in (".nii.gz", ".nii", ".seg.nrrd", ".nrrd", ".nhdr", ".dcm"):
        if base.lower().endswith(suffix) and len(base) > len(suffix):
            base = base[: -len(suffix)]
            break
    return file_stem(base)


def write_surfaces(meshes: List[Mesh], p: Plan, title: str, progress: Optional[Progress] = None) -> None:
    """Every per-surface file, then the combined 3MF and the GLB (not blend/png)."""
    from ...core import export  # speed: the 3MF/GLB writers load when asked for

    for i, (m, fs) in enumerate(zip(meshes, p.surfaces)):
        for fmt, path in fs.items():
            if fmt == DICOM_FORMAT:
                from ...core.export.dicom_stl import write_encapsulated_stl  # pydicom: when asked for

                write_encapsulated_stl(m, path, p.dicom_reference or {}, instance=i + 1)
            elif fmt in export.SCENE_FORMAT_NAMES:
                export.SCENE_FORMATS[fmt]([m], path, title=m.name)
            else:
                write_mesh(m, path, fmt)
        report(progress, (i + 1) / max(1, len(meshes)) * 0.8, f"wrote {m.name}")
    for fmt in ("3mf", "glb"):
        if fmt in p.scene:
            export.SCENE_FORMATS[fmt](meshes, p.scene[fmt], title=title)
    report(progress, 1.0, "files written")


def write_lods(surfaces: SurfaceSet, recipe: Recipe, p: Plan,
               progress: Optional[Progress] = None) -> List[Dict]:
    """Levels of detail of the final surfaces as GLB files, ``p.lods[0]`` the finest.

    One progressive decimation run over the whole set (seams shared at every level;
    :func:`anatomesh.core.decimate.progressive.progressive`, Hoppe 1996), levels at face ratios
    1, 1/2, 1/4, ...; returns per file ``{file, faces, hausdorff_mm, mean_mm}`` (the worst
    shell's distances to level 0)."""
    if not p.lods or not surfaces.n_faces:
        return []
    from ...core.decimate.progressive import progressive  # speed: loaded only for --lod
    from ...core.export import SCENE_FORMATS

    ratios = [0.5 ** i for i in range(len(p.lods) - 1, 0, -1)]  # coarsest first, 1.0 implied
    pm = progressive(surfaces, face_ratios=ratios, progress=progress)
    base = p.report.parent.resolve()
    out = []
    for i, path in enumerate(p.lods):
        k = pm.n_levels - 1 - min(i, pm.n_levels - 1)
        meshes, _ = output_shells(pm.level(k))
        for m in meshes:
            clean(m, recipe)
        worst = {"hausdorff_mm": 0.0, "mean_mm": 0.0}
        for sh in pm.measure(k).values():
            worst = {key: max(worst[key], float(sh[key])) for key in worst}
        SCENE_FORMATS["glb"](meshes, path, title=f"{p.stem} lod{i}")
        out.append({"file": relative(path, base), "faces": int(sum(m.n_faces for m in meshes)),
                    **{key: round(v, 4) for key, v in worst.items()}})
    return out


def web_dir(recipe: Recipe) -> Path:
    """The folder of the "web" output: ``<out>/web`` (open ``index.html`` there)."""
    return Path(recipe.out_dir) / "web"


def needs_blender(recipe: Recipe) -> bool:
    """True when the run writes something only Blender makes (blend, png, a turntable)."""
    return any(f in BLENDER_FORMATS for f in recipe.formats) or bool(recipe.turntable)


def pictures(p: Plan) -> Dict[str, Path]:
    """The still pictures of a plan by view (``png`` alone: the default view)."""
    if "png" in p.scene:
        return {"anterior": p.scene["png"]}
    return {k[4:]: v for k, v in p.scene.items() if k.startswith("png_")}


def register_blender_writer(writer: Callable) -> None:
    """Called by the add-on when Blender registers it: ``writer(result, blend_path, *,
    render_png, samples, size)`` builds the scene of a run and saves it."""
    _BLENDER_WRITER[:] = [writer]


def blender_writer() -> Callable:
    """The ``.blend``/PNG writer: the one the running add-on registered, else the add-on's entry
    point (``anatomesh.blender``), which needs Blender's Python module (``bpy``)."""
    if _BLENDER_WRITER:
        return _BLENDER_WRITER[0]
    eps = [ep for ep in importlib.metadata.entry_points(group=BLENDER_ENTRY_POINTS)
           if ep.name == "write_blend"]
    try:
        writer = eps[0].load() if eps else None
    except ImportError as exc:
        writer, why = None, str(exc)
    else:
        why = "the add-on is not installed with this package"
    if writer is None:
        raise AnatomeshError(f"the blend/png outputs need Blender: install its Python module "
                             f"(pip install bpy==5.0.1) or run inside Blender ({why})")
    return writer


def relative(p: Path, base: Path) -> str:
    """``p`` relative to ``base`` when inside it, else absolute (report paths)."""
    try:
        return str(Path(p).resolve().relative_to(base))
    except ValueError:
        return str(Path(p).resolve())

