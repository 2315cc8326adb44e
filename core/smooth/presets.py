"""The named smoothing settings (:data:`PRESETS`, :data:`DEFAULT`) and the filter names
(:data:`METHODS`).

The default ``"organ"`` is Taubin's λ|μ filter (Taubin 1995, "A signal processing approach to fair
surface design") with λ = 0.5, μ = −0.53 and 20 iterations — the range Bade, Haase & Preim 2006
("Comparison of fundamental mesh smoothing algorithms for medical surface models") recommend for
compact and flat organs — with every vertex kept in its voxel cell (Gibson 1998, "Constrained
elastic surface nets"), junction curves of 3+ labels smoothed along the curve only, folds undone,
volumes restored and crossing faces untangled.
"""
from __future__ import annotations

from typing import Dict, Tuple

from .checks import check_factor, check_iterations, check_taubin
from ..model.errors import AnatomeshError

#: The named default for label maps and organ isosurfaces.
DEFAULT = "organ"

#: Named settings. ``constraint="cell"`` means: the voxel-cell box of a label surface (the
#: vertex's lattice cell) or, for a surface without a lattice, a box of ± half a voxel per voxel
#: axis around the start.
PRESETS: Dict[str, dict] = {
    # smooth organs: volume change within 0.2 % on compact organs (TotalSegmentator maps), every
    # vertex inside its voxel cell, seams shared, no folds, no crossing faces
    "organ": dict(method="taubin", iterations=20, lam=0.5, mu=-0.53, constraint="cell",
                  preserve_volume=True),
    # stronger: more iterations, same bound (flat or large structures, thick slices)
    "strong": dict(method="taubin", iterations=50, lam=0.6, mu=-0.63, constraint="cell"),
    # light touch: removes the voxel steps' shading artefacts only
    "light": dict(method="taubin", iterations=8, lam=0.5, mu=-0.53, constraint="cell"),
    # no bound at all: classic Taubin (for comparison with other tools)
    "taubin": dict(method="taubin", iterations=20, lam=0.5, mu=-0.53, constraint=None),
    "none": dict(method="none"),
}

#: The filters by name (see :mod:`anatomesh.core.smooth.filters`).
METHODS = ("laplacian", "taubin", "hc", "mean_curvature", "normal_mean", "normal_median", "none")


def resolve(method: str = DEFAULT, **params) -> Tuple[str, dict]:
    """Expand a preset name into ``(filter method, parameters)``; explicit params win. A λ given
    without μ to a Taubin preset gets the μ that keeps the preset's pass-band frequency
    (:func:`taubin_mu`), so a stronger λ stays a valid, non-shrinking λ|μ pair."""
    if method in PRESETS:
        p = dict(PRESETS[method])
        name = p.pop("method")
        if params.get("lam") is not None and params.get("mu") is None and "mu" in p:
            p["mu"] = taubin_mu(params["lam"], 1.0 / p["lam"] + 1.0 / p["mu"])
        p.update({k: v for k, v in params.items() if not (k == "mu" and v is None)})
        return name, p
    if method in METHODS:
        return method, dict(params)
    raise AnatomeshError(f"unknown smoothing method {method!r}; choose one of "
                         f"{sorted(set(PRESETS) | set(METHODS))}")


def check_settings(method: str = DEFAULT, **params) -> Tuple[str, dict]:
    """:func:`resolve` and the checks the filters make of their settings, without a mesh (a run
    refuses bad settings before it reads its input): the method, whole ``iterations`` >= 0, λ in
    (0, 1] and, for Taubin, −1 <= μ < −λ. Returns what :func:`resolve` returns."""
    name, p = resolve(method, **params)
    if p.get("iterations") is not None:
        check_iterations(p["iterations"])
    if p.get("lam") is not None:
        check_factor("lam", p["lam"], 0.0, 1.0)
        if name == "taubin" and p.get("mu") is not None:
            check_taubin(p["lam"], p["mu"])
    return name, p


def taubin_mu(lam: float, k_pb: float) -> float:
    """μ for ``lam`` with Taubin's pass-band frequency ``k_pb = 1/λ + 1/μ`` (Taubin 1995; the
    presets' 0.11), kept in [−1, −λ): the shrinking λ step and the inflating μ step balance at the
    same frequency whatever the strength."""
    lam = float(lam)
    if not 0.0 < lam < 1.0:
        return -1.0  # the filter's own check names the bad λ
    mu = 1.0 / (k_pb - 1.0 / lam) if k_pb < 1.0 / lam else -1.0
    return max(-1.0, min(mu, -lam - 1e-3))
