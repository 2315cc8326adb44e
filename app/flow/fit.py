"""Cut to fit, the flow's side: every part too big for the printer's build volume is cut
into pieces that fit (:func:`anatomesh.core.printing.cut.fit_part`), named ``<part>_1``,
``<part>_2``, ...; each part gets one ``fit`` entry in the report's ``fixes`` (build volume, cuts,
pieces with their extents and volumes). Used by ``anatomesh mesh --fit``, ``anatomesh check
--fit --out`` and the Blender Print panel's *Cut to Fit* button."""
from __future__ import annotations

import dataclasses

from typing import Dict, List, Optional, Sequence, Tuple

from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh
from ...core.model.progress import Progress, report

#: the meta key each mesh leaving :func:`fit_parts` carries: the index of the part it came from
PART_INDEX = "fit_part_index"


def fit_arg(text: str) -> List[float]:
    """``--fit X,Y,Z`` (mm) as three floats; raises :class:`AnatomeshError` (one line) otherwise."""
    try:
        size = [float(x) for x in str(text).replace("x", ",").split(",")]
    except ValueError:
        size = []
    if len(size) != 3 or not all(x > 0 and x < float("inf") for x in size):
        raise AnatomeshError(f"--fit takes the printer's build volume as X,Y,Z in mm, e.g. 180,180,180; "
                             f"got {text!r}")
    return size


def check_fit(fit) -> Optional[List[float]]:
    """The recipe's ``fit`` (None or three sizes > 0 mm) as floats; raises for anything else."""
    if fit is None:
        return None
    if not (isinstance(fit, (list, tuple)) and len(fit) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and 0 < x < float("inf") for x in fit)):
        raise AnatomeshError(f"fit_mm (--fit) is the build volume [x, y, z] in mm, each > 0, got {fit!r}")
    return [float(x) for x in fit]


def fit_parts(meshes: Sequence[Mesh], size: Sequence[float], connectors: bool = False,
              profile: str = "fdm", min_wall: Optional[float] = None,
              progress: Optional[Progress] = None) -> Tuple[List[Mesh], List[Dict]]:
    """Every part cut to fit ``size`` (3,) mm (parts that fit stay whole), with pins and pockets
    across the cuts when ``connectors`` (clearance from ``profile``). Returns (meshes, one
    ``{"fix": "fit", "part", ...}`` entry per part); each mesh's ``meta[PART_INDEX]`` is the
    index of its part in ``meshes``."""
    from ...core.printing.cut import fit_part  # speed: loaded only when asked for
    from ...core.printing.profiles import resolve_profile

    prof = resolve_profile(profile, min_wall)
    out, fixes = [], []
    for k, m in enumerate(meshes):
        report(progress, k / max(len(meshes), 1), f"cutting {m.name} to fit")
        pieces, info = fit_part(m, size, connectors=connectors, clearance=prof["connector_clearance"],
                                min_wall=prof["min_wall"])
        meta = {x: y for x, y in m.meta.items() if x != "vertex_ids"}  # indices changed
        out += [dataclasses.replace(p, meta={**meta, PART_INDEX: k}) for p in pieces]
        fixes.append({"fix": "fit", "part": m.name, **info})
    return out, fixes


def rows_for_pieces(rows: List, meshes: Sequence[Mesh]) -> List:
    """Per-part ``rows`` (one per part before cutting) repeated for each piece of ``meshes``."""
    return [rows[m.meta.get(PART_INDEX, k)] for k, m in enumerate(meshes)]


def summary(info: Dict) -> str:
    """One line: ``liver: 2 cuts (x 21.7 mm, y 151.5 mm) -> 3 pieces fit 120x120x120 mm``."""
    size = "x".join(f"{x:g}" for x in info["build_volume_mm"])
    if not info["cuts"]:
        return f"{info['part']} fits {size} mm as it is"
    cuts = ", ".join(f"{c['axis']} {c['position_mm']:.1f} mm" for c in info["cuts"])
    pins = sum(len(j["pins"]) for j in info.get("connectors", []))
    return (f"{info['part']}: {len(info['cuts'])} cut(s) ({cuts}) -> {len(info['pieces'])} pieces fit "
            f"{size} mm" + (f", {pins} pin(s)" if "connectors" in info else ""))
