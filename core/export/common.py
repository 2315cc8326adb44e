"""Shared by the writers: input checks of the scene writers (3MF, GLB) and atomic file writing."""
from __future__ import annotations

import os
import re
from contextlib import contextmanager
from pathlib import Path
from typing import List, Optional, Sequence

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh


def check_meshes(meshes: Sequence[Mesh], path, fmt: str) -> List[Mesh]:
    """The meshes as a list, or :class:`AnatomeshError` naming ``path`` for an empty list, a
    non-Mesh, surfaces in different (or unknown) spaces, a mesh without faces, non-finite vertices
    or face indices out of range."""
    if isinstance(meshes, Mesh):
        meshes = [meshes]
    meshes = list(meshes or [])
    if not meshes:
        raise AnatomeshError(f"no surfaces to write to {fmt}; extract at least one label or level", path)
    for m in meshes:
        if not isinstance(m, Mesh):
            raise AnatomeshError(f"cannot write {type(m).__name__} to {fmt}: give anatomesh Mesh "
                                 f"objects", path)
        what = f"surface {m.name or '(unnamed)'!r}"
        if m.space not in ("RAS", "LPS") or m.space != meshes[0].space:
            raise AnatomeshError(f"surfaces must all be in one space, RAS or LPS ({what} is in "
                                 f"{m.space!r}, the first in {meshes[0].space!r}); convert them "
                                 f"to one space first", path)
        if m.n_faces == 0:
            raise AnatomeshError(f"{what} has no triangles; leave it out of the {fmt} export", path)
        if not np.isfinite(m.vertices).all():
            raise AnatomeshError(f"{what} has NaN or infinite vertex coordinates; re-run the "
                                 f"smoothing/extraction that produced it", path)
        if m.faces.min() < 0 or m.faces.max() >= m.n_vertices:
            raise AnatomeshError(f"{what} has face indices outside its {m.n_vertices} vertices", path)
    return meshes


@contextmanager
def atomic_write(path):
    """Open ``path + '.part'`` for binary writing and rename it onto ``path`` on success only, so
    an interrupted write never leaves a half-written file under the final name."""
    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fh = open(tmp, "wb")
    except OSError as exc:
        raise AnatomeshError(f"cannot write here ({exc.strerror}); choose another output folder",
                             path) from None
    try:
        with fh:
            yield fh
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)


def file_stem(name: str) -> str:
    """A file-name-safe stem of a surface or scan name (``"Lt Lung"`` → ``"Lt_Lung"``)."""
    s = re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("_")
    return s or "surface"


def unique_stems(names: Sequence[str], tags: Optional[Sequence[str]] = None) -> List[str]:
    """One distinct file stem per name: a repeated stem gets ``_<tag>`` (``tags[i]``, e.g. the
    label value), then underscores until it is free."""
    used, out = set(), []
    for i, name in enumerate(names):
        stem = file_stem(name)
        if stem in used and tags is not None:
            stem = f"{stem}_{file_stem(str(tags[i]))}"
        while stem in used:
            stem += "_"
        used.add(stem)
        out.append(stem)
    return out


def refuse_overwrite(paths: Sequence, overwrite: bool,
                     hint: str = "pass --overwrite to replace them or choose another output folder") -> None:
    """Raise :class:`AnatomeshError` before anything is written when any of ``paths`` exists and
    ``overwrite`` is False (nothing is ever replaced silently)."""
    existing = [Path(p) for p in paths if Path(p).exists()]
    if existing and not overwrite:
        raise AnatomeshError(f"{len(existing)} output file(s) already exist (e.g. {existing[0]}); {hint}")
