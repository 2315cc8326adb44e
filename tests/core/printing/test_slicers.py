"""Independent validation: Debian's ``admesh`` and ``prusa-slicer`` read what ``anatomesh mesh``
writes as solid, with nothing to repair (tools installed by tools/setup_env.sh; these tests
skip, with the reason, only where they are not installed).

Parsers are checked on broken boxes first (a hole, a flipped face), so a silent parser cannot
make the real-data checks pass."""
import json
import re
import shutil
import subprocess

import pytest
from conftest import SAMPLE
from helpers.meshes import box

from anatomesh.app.cli import main as cli_main
from anatomesh.core.export.threemf import write_3mf
from anatomesh.core.io.mesh_files import read_mesh
from anatomesh.core.export.mesh_files import write_stl
from anatomesh.core.model.mesh import Mesh

ADMESH = shutil.which("admesh")
PRUSA = shutil.which("prusa-slicer")
need_admesh = pytest.mark.skipif(ADMESH is None, reason="admesh not installed (tools/setup_env.sh "
                                 "installs it as root: apt-get install admesh)")
need_prusa = pytest.mark.skipif(PRUSA is None, reason="prusa-slicer not installed (tools/setup_env.sh "
                                "installs it as root: apt-get install prusa-slicer)")

#: small organs of the bundled sample: thin adrenal glands, two touching vertebrae (a shared
#: seam, each written as its own closed shell), the gallbladder and a rib
LABELS = "4,8,9,30,31,98"
#: admesh counters that are non-zero when it had to repair something
ADMESH_REPAIRS = ("Degenerate facets", "Edges fixed", "Facets removed", "Facets added",
                  "Facets reversed", "Backwards edges", "Normals fixed", "Total disconnected facets")
#: keys `prusa-slicer --info` prints only when it repaired the mesh or found it open
PRUSA_REPAIRS = ("open_edges", "degenerate_facets", "edges_fixed", "facets_removed",
                 "facets_added", "facets_reversed", "backwards_edges")


def admesh_stats(path) -> dict:
    # admesh prints the 80-byte header as a C string, often with stray bytes after it
    out = subprocess.run([ADMESH, str(path)], capture_output=True, text=True, errors="replace",
                         timeout=120, check=True).stdout
    stats = {}
    for key in ADMESH_REPAIRS + ("Number of parts",):
        m = re.search(rf"^{re.escape(key)}\s*:\s*(\d+)", out, re.M)
        assert m, f"admesh output has no '{key}' line:\n{out}"
        stats[key] = int(m.group(1))
    return stats


def prusa_info(path) -> dict:
    res = subprocess.run([PRUSA, "--info", str(path)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    info = dict(re.findall(r"^(\w+) = (.*)$", res.stdout, re.M))
    assert "number_of_facets" in info, res.stdout
    return info


@pytest.fixture(scope="module")
def broken(tmp_path_factory):
    d = tmp_path_factory.mktemp("broken")
    v, f = box((0, 0, 0), (8, 8, 8), 4)
    flipped = f.copy()
    flipped[5] = flipped[5][::-1]
    write_stl(Mesh(v, f[2:], name="hole"), d / "hole.stl")
    write_stl(Mesh(v, flipped, name="flip"), d / "flip.stl")
    write_stl(Mesh(v, f, name="ok"), d / "ok.stl")
    return d


@pytest.fixture(scope="module")
def meshed(tmp_path_factory):
    out = tmp_path_factory.mktemp("meshed")
    assert cli_main(["mesh", str(SAMPLE / "example_seg.nii.gz"), "--labels", LABELS,
                     "--out", str(out / "m")]) == 0
    rep = json.loads((out / "m" / "report.json").read_text())
    files = [out / "m" / s["files"]["stl"] for s in rep["surfaces"]]
    assert len(files) == len(LABELS.split(","))
    return files


@need_admesh
def test_admesh_parser_sees_repairs_on_broken_boxes(broken):
    hole, flip, ok = (admesh_stats(broken / f"{n}.stl") for n in ("hole", "flip", "ok"))
    assert hole["Total disconnected facets"] > 0 and hole["Facets added"] > 0
    assert flip["Facets reversed"] == 1
    assert all(ok[k] == 0 for k in ADMESH_REPAIRS)


@need_prusa
def test_prusa_parser_sees_repairs_on_broken_boxes(broken):
    hole, flip, ok = (prusa_info(broken / f"{n}.stl") for n in ("hole", "flip", "ok"))
    assert hole["manifold"] == "no" and int(hole["open_edges"]) > 0
    assert int(flip["facets_reversed"]) == 1
    assert ok["manifold"] == "yes" and not set(PRUSA_REPAIRS) & set(ok)


@need_admesh
def test_every_stl_of_anatomesh_mesh_passes_admesh_without_repairs(meshed):
    for path in meshed:
        stats = admesh_stats(path)
        assert {k: stats[k] for k in ADMESH_REPAIRS} == dict.fromkeys(ADMESH_REPAIRS, 0), path.name
        assert stats["Number of parts"] >= 1


@need_prusa
def test_prusa_slicer_reads_every_stl_as_manifold_without_repairs(meshed):
    for path in meshed:
        info = prusa_info(path)
        assert info["manifold"] == "yes", (path.name, info)
        assert not set(PRUSA_REPAIRS) & set(info), (path.name, info)
        assert float(info["volume"]) > 0


@need_prusa
def test_prusa_slicer_slices_our_stl_to_gcode(meshed, tmp_path):
    src = next(p for p in meshed if "vertebrae_L1" in p.name)
    gcode = tmp_path / "out.gcode"
    res = subprocess.run([PRUSA, "--export-gcode", "--scale", "0.5", str(src), "--output", str(gcode)],
                         capture_output=True, text=True, timeout=300)
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-2000:]
    assert gcode.is_file() and gcode.stat().st_size > 10000
    assert not re.search(r"\berror\b|repair|manifold", text, re.I), text[-2000:]
    body = gcode.read_text(errors="replace")
    assert re.search(r"^G1 .*E", body, re.M)  # extrusion moves were generated


@need_prusa
def test_prusa_slicer_slices_our_3mf(meshed, tmp_path):
    meshes = [read_mesh(p) for p in meshed[:3]]
    path = tmp_path / "parts.3mf"
    write_3mf(meshes, path)
    res = subprocess.run([PRUSA, "--info", str(path)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "manifold = yes" in res.stdout and not re.search("|".join(PRUSA_REPAIRS), res.stdout)
    gcode = tmp_path / "parts.gcode"
    res = subprocess.run([PRUSA, "--export-gcode", "--scale", "0.5", str(path), "--output", str(gcode)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and gcode.is_file(), (res.stdout + res.stderr)[-2000:]
    assert not re.search(r"\berror\b|repair", res.stdout + res.stderr, re.I)
