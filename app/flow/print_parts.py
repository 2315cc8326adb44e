"""The printable-part tools of a run, after the surfaces are final and before they are written:
connectors between touching parts (:func:`anatomesh.core.printing.connectors.add_connectors`),
then hollowing with drain holes (:func:`anatomesh.core.printing.hollow.hollow`), then cutting
to fit the build volume (:mod:`.fit`). Each tool adds
entries to the report's ``fixes`` (what it did: volumes, counts, places)."""
from __future__ import annotations

from typing import Dict, List, Optional, Tuple

from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh
from ...core.model.progress import Progress, report
from ...core.printing.connectors import add_connectors
from ...core.printing.hollow import hollow
from ...core.printing.profiles import resolve_profile
from .fit import fit_parts  # cut to fit


def apply_tools(meshes: List[Mesh], recipe, progress: Optional[Progress] = None) -> Tuple[List[Mesh], List[Dict]]:
    """``meshes`` with the recipe's tools applied (``hollow`` wall in mm, ``drain_holes``,
    ``drain_diameter`` mm or the profile's); returns (meshes, fixes entries)."""
    fixes: List[Dict] = []
    meshes = list(meshes)
    prof = resolve_profile(recipe.profile, recipe.min_wall)
    for pair in recipe.connectors:
        ia, ib = (_find(meshes, x) for x in pair)
        meshes[ia], meshes[ib], info = add_connectors(meshes[ia], meshes[ib], prof["connector_clearance"],
                                                      min_wall=prof["min_wall"])
        fixes.append({"fix": "connectors", **info})
    if recipe.hollow is None:
        return _fit(meshes, fixes, recipe, progress)  # cut to fit
    out = []
    for k, m in enumerate(meshes):
        report(progress, k / max(len(meshes), 1), f"hollowing {m.name}")
        hm, info = hollow_part(m, recipe.hollow, recipe.drain_holes, recipe.drain_diameter, recipe.profile)
        out.append(hm)
        fixes.append({"fix": "hollow", "part": m.name, **info})
    return _fit(out, fixes, recipe, progress)  # cut to fit


def _fit(meshes: List[Mesh], fixes: List[Dict], recipe, progress) -> Tuple[List[Mesh], List[Dict]]:
    """The parts cut to fit the recipe's build volume ``fit`` (when set), last."""
    if not recipe.fit:
        return meshes, fixes
    meshes, more = fit_parts(meshes, recipe.fit, recipe.fit_connectors, recipe.profile, recipe.min_wall, progress)
    return meshes, fixes + more


def hollow_part(mesh: Mesh, wall: float, holes: int = 2, diameter: Optional[float] = None,
                profile: str = "resin") -> Tuple[Mesh, Dict]:
    """One part hollowed (:func:`~anatomesh.core.printing.hollow.hollow`), the drain diameter
    from ``profile`` when not given."""
    d = diameter if diameter is not None else resolve_profile(profile)["drain_diameter"]
    return hollow(mesh, wall, holes=holes, hole_diameter=d)


def _find(meshes: List[Mesh], key) -> int:
    """The index of the part named ``key`` (or with that label value)."""
    for k, m in enumerate(meshes):
        if str(m.name) == str(key) or (m.value is not None and str(m.value) == str(key)):
            return k
    raise AnatomeshError(f"--connectors: no part {key!r}; parts are {', '.join(m.name for m in meshes[:12])}")
