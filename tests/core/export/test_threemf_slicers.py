"""Multi-material 3MF: every part its own filament. The written XML is checked against the 3MF
core specification's rules (ids, references, indices, namespaces, content types) and the slicers'
metadata parts; PrusaSlicer (Debian package) reads the filaments back (its own 3MF export keeps
them) and slices the parts with one tool per filament."""
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
from helpers.meshes import icosphere

from anatomesh.core.export.threemf import NS_CORE, read_3mf, write_3mf
from anatomesh.core.export.threemf_slicers import BAMBU_CONFIG, NS_MATERIAL, PRUSA_CONFIG
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh

PRUSA = shutil.which("prusa-slicer")
C = "{%s}" % NS_CORE
UNITS = {"micron", "millimeter", "centimeter", "inch", "foot", "meter"}
OBJECT_TYPES = {"model", "support", "solidsupport", "surface", "other"}
COLOUR = re.compile(r"^#[0-9A-Fa-f]{6}([0-9A-Fa-f]{2})?$")


def core_rule_errors(zf: zipfile.ZipFile) -> list:
    """Violations of the 3MF core specification 1.3 rules a consumer enforces (empty: none)."""
    errs = []
    types = ET.fromstring(zf.read("[Content_Types].xml"))
    exts = {d.get("Extension").lower() for d in types if d.tag.endswith("Default")}
    for name in zf.namelist():
        if not name.endswith("/") and name != "[Content_Types].xml" and name.rsplit(".", 1)[-1].lower() not in exts:
            errs.append(f"part {name} has no content type")
    raw = zf.read("3D/3dmodel.model").decode()
    declared = dict(re.findall(r'xmlns:(\w+)="([^"]+)"', raw))
    root = ET.fromstring(raw)
    if root.tag != C + "model" or root.get("unit", "millimeter") not in UNITS:
        errs.append("root is not a core <model> with a valid unit")
    for ext in root.get("requiredextensions", "").split():
        if ext not in declared:
            errs.append(f"required extension {ext} not declared")
    names = [m.get("name") for m in root.findall(C + "metadata")]
    if len(names) != len(set(names)):
        errs.append("duplicate model metadata names")
    for n in names:
        if ":" in n and n.split(":")[0] not in declared:
            errs.append(f"metadata {n}: undeclared prefix")
    res = root.find(C + "resources")
    ids, counts = {}, {}
    for el in res:
        rid = int(el.get("id"))
        if rid <= 0 or rid in ids:
            errs.append(f"resource id {rid} not positive or not unique")
        ids[rid] = el
        kids = list(el)
        counts[rid] = len(kids)
        for k in kids:
            col = k.get("displaycolor") or k.get("color")
            if col is not None and not COLOUR.match(col):
                errs.append(f"bad colour {col}")
    for el in res.findall(C + "object"):
        if el.get("type", "model") not in OBJECT_TYPES:
            errs.append("bad object type")
        if el.get("pid") is not None:
            pid, pindex = int(el.get("pid")), int(el.get("pindex", 0))
            if pid not in ids or not 0 <= pindex < counts[pid]:
                errs.append(f"object {el.get('id')}: pid/pindex {pid}/{pindex} points nowhere")
        mesh = el.find(C + "mesh")
        nv = len(mesh.find(C + "vertices"))
        tri = np.array([[int(t.get(k)) for k in ("v1", "v2", "v3")] for t in mesh.find(C + "triangles")])
        if nv < 3 or tri.min() < 0 or tri.max() >= nv:
            errs.append(f"object {el.get('id')}: triangle indices outside its {nv} vertices")
        if np.any((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])):
            errs.append(f"object {el.get('id')}: a triangle repeats a vertex")
    for item in root.find(C + "build"):
        oid = int(item.get("objectid"))
        if oid not in ids or ids[oid].tag != C + "object":
            errs.append(f"build item points to {oid}, not an object")
    return errs


@pytest.fixture
def three(tmp_path):
    v, f = icosphere(3, 8.0)
    colours = [(1, 0, 0), (0, 1, 0), (1, 0, 0), (0, 0, 1)]  # two parts share red
    meshes = [Mesh(v + [k * 20, 0, 10], f, name=f"part {k} <&>", color=c, value=k + 1)
              for k, c in enumerate(colours)]
    return meshes, write_3mf(meshes, tmp_path / "parts.3mf")


def test_xml_keeps_the_core_rules_and_names_a_filament_per_colour(three):
    meshes, path = three
    with zipfile.ZipFile(path) as zf:
        assert core_rule_errors(zf) == []
        model = ET.fromstring(zf.read("3D/3dmodel.model"))
        prusa = ET.fromstring(zf.read(PRUSA_CONFIG))
        bambu = ET.fromstring(zf.read(BAMBU_CONFIG))
    objects = model.find(C + "resources").findall(C + "object")
    ids = [o.get("id") for o in objects]
    group = model.find(C + "resources").find("{%s}colorgroup" % NS_MATERIAL)
    assert [c.get("color") for c in group] == ["#FF0000", "#00FF00", "#FF0000", "#0000FF"]
    want = ["1", "2", "1", "3"]
    got = [(o.get("id"), {m.get("key"): m.get("value") for m in o.findall("metadata")}) for o in prusa]
    assert [g[0] for g in got] == ids and [g[1]["extruder"] for g in got] == want
    assert [g[1]["name"] for g in got] == [m.name for m in meshes]
    for o, m in zip(prusa, meshes):
        vol = o.find("volume")
        assert (vol.get("firstid"), vol.get("lastid")) == ("0", str(m.n_faces - 1))
    bo = bambu.findall("object")
    assert [o.get("id") for o in bo] == ids
    assert [{m.get("key"): m.get("value") for m in o.find("part").findall("metadata")}["extruder"]
            for o in bo] == want
    assert len(bambu.find("plate").findall("model_instance")) == 4
    back = read_3mf(path)  # the reader still reads the parts as written
    assert [b.name for b in back] == [m.name for m in meshes] and [b.value for b in back] == [1, 2, 3, 4]
    np.testing.assert_array_equal(back[3].faces, meshes[3].faces)


def test_explicit_filaments_and_bad_ones(tmp_path):
    v, f = icosphere(2, 5.0)
    ms = [Mesh(v, f, name="a"), Mesh(v + 20, f, name="b")]
    p = write_3mf(ms, tmp_path / "x.3mf", filaments=[4, 2])
    with zipfile.ZipFile(p) as zf:
        assert re.findall(r'key="extruder" value="(\d)"', zf.read(PRUSA_CONFIG).decode()) == ["4", "2"]
    with pytest.raises(AnatomeshError, match="filament"):
        write_3mf(ms, tmp_path / "y.3mf", filaments=[1])
    with pytest.raises(AnatomeshError, match="filament"):
        write_3mf(ms, tmp_path / "y.3mf", filaments=[0, 1])


@pytest.mark.skipif(PRUSA is None, reason="prusa-slicer (Debian package prusa-slicer) is not installed")
def test_prusaslicer_keeps_the_filaments_and_slices_one_tool_per_filament(three, tmp_path):
    meshes, path = three
    info = subprocess.run([PRUSA, "--info", str(path)], capture_output=True, text=True, timeout=300)
    assert info.returncode == 0 and "manifold = no" not in info.stdout, info.stdout[-2000:]
    # PrusaSlicer's own 3MF export of what it loaded keeps each object's extruder
    again = tmp_path / "again.3mf"
    run = subprocess.run([PRUSA, "--export-3mf", "-o", str(again), str(path)], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    with zipfile.ZipFile(again) as zf:
        conf = zf.read(PRUSA_CONFIG).decode()
    assert re.findall(r'key="extruder" value="(\d)"', conf) == ["1", "2", "1", "3"]
    gcode = tmp_path / "parts.gcode"
    run = subprocess.run([PRUSA, "--export-gcode", "-o", str(gcode), "--nozzle-diameter", "0.4,0.4,0.4",
                          "--wipe-tower", "--use-relative-e-distances", str(path)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    tools = set(re.findall(r"^T(\d)\s*$", gcode.read_text(errors="replace"), re.M))
    assert tools == {"0", "1", "2"}
