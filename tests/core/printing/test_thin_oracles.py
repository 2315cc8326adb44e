"""The thin-feature rule checked against independent measurements:

* rays in the inward normal cone (a shape-diameter estimate, Shapira, Shamir & Cohen-Or 2008,
  "Consistent mesh partitioning and skeletonisation using the shape diameter function"), cast
  here by brute force in numpy (Möller & Trumbore 1997), not by our spatial grid: the median
  cone-ray length on the sheet and the rod is their true thickness, as our figures say;
* PrusaSlicer's slicing (classic perimeters, no thin-wall detection, 0.45 mm extrusions): the
  G-code layers show what survives. A rim that passes keeps its material to within the tolerance
  (plus half an extrusion) of the edge; a knife edge that fails loses more; the failing sheet and
  rod get a single outline and no inner perimeter or infill, while the body gets both.
"""
import re
import shutil
import subprocess

import numpy as np
import pytest
from helpers.print_shapes import body_with_fin_and_rod, lens, standing_lens

from anatomesh.core.export.mesh_files import write_stl
from anatomesh.core.model.mesh import Mesh, vertex_normals
from anatomesh.core.printing import checks as pc

PRUSA = shutil.which("prusa-slicer")
need_prusa = pytest.mark.skipif(PRUSA is None, reason="prusa-slicer (Debian package) is not installed")
#: PrusaSlicer's default extrusion width for a 0.4 mm nozzle is about this, mm
EXTRUSION_MM = 0.45


def cone_ray_thickness(v, f, points, inward, half_angle_deg=30.0, rays=24, seed=0):
    """Median first-hit distance (P,) of ``rays`` rays per point in the inward cone: brute
    force over all triangles (Möller & Trumbore 1997)."""
    rng = np.random.default_rng(seed)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2 = b - a, c - a
    out = np.empty(len(points))
    cos_max = np.cos(np.radians(half_angle_deg))
    for i, (p, u) in enumerate(zip(points, inward)):
        z = rng.uniform(cos_max, 1.0, rays)
        phi = rng.uniform(0, 2 * np.pi, rays)
        t1 = np.cross(u, [1.0, 0, 0] if abs(u[0]) < 0.9 else [0, 1.0, 0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(u, t1)
        d = (np.sqrt(1 - z * z)[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
             + z[:, None] * u)
        pv = np.cross(d[:, None, :], e2[None])
        det = np.einsum("fk,rfk->rf", e1, pv)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = p - a
        uu = np.einsum("fk,rfk->rf", tv, pv) * inv
        qv = np.cross(tv, e1)
        vv = np.einsum("rk,fk->rf", d, qv) * inv
        tt = np.einsum("fk,fk->f", e2, qv)[None] * inv
        hit = ok & (uu >= 0) & (vv >= 0) & (uu + vv <= 1) & (tt > 1e-6)
        out[i] = np.median(np.where(hit, tt, np.inf).min(axis=1))
    return out


@pytest.fixture(scope="module")
def phantom():
    v, f = body_with_fin_and_rod(sheet=0.5, rod=0.6)
    part = pc.check_parts([Mesh(v, f, name="phantom")], "fdm")["parts"][0]
    return v, f, {r["kind"]: r for r in part["thin_regions"]}


def test_cone_rays_measure_the_same_sheet_and_rod(phantom):
    v, f, kinds = phantom
    n = vertex_normals(v, f)
    rng = np.random.default_rng(1)
    fin = np.flatnonzero((np.abs(v[:, 0] - 5) < 0.3) & (v[:, 2] > 8) & (v[:, 2] < 12)
                         & (np.abs(v[:, 1] - 5) < 3))
    rod = np.flatnonzero((v[:, 0] > 12) & (v[:, 0] < 20) & (np.hypot(v[:, 1] - 5, v[:, 2] - 3) < 0.4))
    for idx, true, kind in ((fin, 0.5, "sheet"), (rod, 0.6, "rod")):
        pick = rng.choice(idx, 40, replace=False)
        sdf = np.median(cone_ray_thickness(v, f, v[pick], -n[pick]))
        # cone rays lean, so they run a little longer than the thickness (1/cos of their angle)
        assert sdf == pytest.approx(true, abs=0.1)
        assert kinds[kind]["thickness_mm"] == pytest.approx(sdf, abs=0.1)


def _slice(tmp_path, v, f, name):
    stl = tmp_path / f"{name}.stl"
    write_stl(Mesh(v, f, name=name), stl)
    gcode = tmp_path / f"{name}.gcode"
    run = subprocess.run([PRUSA, "--export-gcode", "--dont-arrange", "--perimeter-generator", "classic",
                          "--no-thin-walls", "--layer-height", "0.2", "-o", str(gcode), str(stl)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    return _extrusions(gcode)


def _extrusions(path):
    """[(x0, y0, x1, y1, z, kind)] of the extruding moves of a G-code file."""
    x = y = z = e = 0.0
    rel, kind, out = False, "", []
    for line in open(path):
        if line.startswith(";TYPE:"):
            kind = line[6:].strip()
        elif line.startswith(("M82", "M83")):
            rel = line.startswith("M83")
        elif line.startswith("G92"):
            m = re.search(r"E([-\d.]+)", line)
            e = float(m.group(1)) if m else e
        elif line.startswith("G1"):
            d = dict(re.findall(r"([XYZE])([-\d.]+)", line.split(";")[0]))
            nx, ny = float(d.get("X", x)), float(d.get("Y", y))
            z = float(d.get("Z", z))
            if "E" in d:
                de = float(d["E"]) - (0.0 if rel else e)
                e = e + de if rel else float(d["E"])
                if de > 0 and (nx, ny) != (x, y):
                    out.append((x, y, nx, ny, z, kind))
            x, y = nx, ny
    return out


@need_prusa
@pytest.mark.parametrize("half_angle,passes", [(45.0, True), (20.0, False)])
def test_prusaslicer_keeps_a_passing_rim_and_cuts_back_a_failing_edge(tmp_path, half_angle, passes):
    v, f = lens(10.0, half_angle)
    part = pc.check_parts([Mesh(v, f, name="lens")], "fdm")["parts"][0]
    assert part["passed"] == passes
    # stand the lens on its rim (rim in a vertical plane) on a base: the layer through its centre
    # cuts the wedge across, where a slicer loses what is narrower than its line
    v, f = standing_lens(10.0, half_angle)
    moves = _slice(tmp_path, v + [100.0, 100.0, 0.0], f, "lens")
    layer = min({m[4] for m in moves}, key=lambda z: abs(z - 11.0))
    reach = max(abs(m[k] - 100.0) for m in moves if m[4] == layer for k in (0, 2))
    lost = 10.0 - reach - EXTRUSION_MM / 2  # from the line's edge to the tip of the wedge
    tol = pc.resolve_profile("fdm")["min_feature"]
    assert (lost <= tol) == passes, lost


@need_prusa
def test_prusaslicer_prints_the_failing_sheet_and_rod_as_one_outline(tmp_path, phantom):
    v, f, _ = phantom
    moves = _slice(tmp_path, v + [50.0, 50.0, 0.0], f, "phantom")
    fin = {m[5] for m in moves if 7 < m[4] < 13}
    assert fin == {"External perimeter"}  # no inner perimeter, no infill: one line thick
    stick = {m[5] for m in moves if abs(m[4] - 3.0) < 0.25 and min(m[0], m[2]) > 61}
    assert stick and stick <= {"External perimeter", "Overhang perimeter"}  # the rod hangs free
    body = {m[5] for m in moves if abs(m[4] - 3.0) < 0.25 and max(m[0], m[2]) < 59}
    assert "Perimeter" in body and any("infill" in k.lower() for k in body)
