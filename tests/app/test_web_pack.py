"""The web page's data: meshoptimizer encoding round trips, quantisation bounds, shared surfaces
stored once, the page's files and summary."""
import base64
import json
import re
import zlib

import meshopt
import numpy as np
import pytest

from anatomesh.app.web.page import WebModel, page_paths, write_page
from anatomesh.app.web.pack import STEP_MM, Z85, LevelPack, display_vertices, encode_mesh, quantization_for, z85
from anatomesh.core.export.gltf import AXES
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh
from helpers.meshes import icosphere, torus


def _decode(enc, q):
    """The surface back from its parts (meshopt's own decoders): positions mm, triangles, colours."""
    p = enc["parts"]
    pos = meshopt.decode_vertex_buffer(p["p"], enc["v"], 8).view(np.uint16).reshape(-1, 4)
    idx = meshopt.decode_index_buffer(p["i"], 3 * enc["t"], 4).reshape(-1, 3)
    col = meshopt.decode_vertex_buffer(p["c"], enc["v"], 4) if "c" in p else None
    return q.origin + pos[:, :3] * q.step, idx, col


@pytest.mark.parametrize("space", ["RAS", "LPS"])
def test_encoding_round_trip_within_half_a_step(space):
    v, f = torus(40.0, 12.0)
    v = v + [100.0, -30.0, 500.0]
    m = Mesh(v, f, name="torus", space=space)
    q = quantization_for([m])
    enc = encode_mesh(m, q)
    pos, idx, col = _decode(enc, q)
    assert col is None and enc["v"] == len(v) and enc["t"] == len(f)
    want = display_vertices(m)
    assert np.allclose(want, (v.astype(np.float32).astype(np.float64)) @ AXES[space].T)
    # the same triangles (as sets of corner positions; order and numbering change)
    got = {tuple(sorted(map(tuple, np.rint((pos[t] - q.origin) / q.step).astype(int)))) for t in idx}
    ref = {tuple(sorted(map(tuple, np.rint((want[t] - q.origin) / q.step).astype(int)))) for t in f}
    assert got == ref
    nearest = np.abs(pos[:, None, :] - want[None, :, :]).max(axis=2).min(axis=1)  # per axis, mm
    err = nearest
    assert err.max() <= q.step / 2 + 1e-9 and q.step == STEP_MM


def test_colours_and_unused_vertices():
    v, f = icosphere(2, 30.0)
    v = np.vstack([v, [[999.0, 999.0, 999.0]]])  # an unused vertex: dropped, not stored
    c = np.zeros((len(v), 3), np.float32)
    c[:, 0] = (v[:, 2] > 0)  # red top half
    m = Mesh(v, f, vertex_colors=c)
    q = quantization_for([m])
    enc = encode_mesh(m, q)
    pos, idx, col = _decode(enc, q)
    assert enc["v"] == len(v) - 1 and idx.max() == enc["v"] - 1
    assert np.all(col[:, 3] == 255) and set(np.unique(col[:, 0])) == {0, 255}
    top = pos[:, 1] > 0  # display +y is superior (patient z)
    assert np.all(col[top, 0] == 255) and np.all(col[~top, 0] == 0)
    assert q.origin[1] <= -30.0  # the grid covers every vertex, the unused one too


def test_huge_extents_double_the_step():
    v, f = icosphere(1, 5000.0)  # a 10 m wide surface does not fit 16 bits at 1/16 mm
    q = quantization_for([Mesh(v, f)])
    assert q.step > STEP_MM and 10000.0 / q.step < 65535
    assert q.step == STEP_MM * 2 ** round(np.log2(q.step / STEP_MM))


def test_identical_surfaces_are_stored_once():
    v, f = icosphere(2, 10.0)
    a = Mesh(v, f, name="a")
    pack = LevelPack()
    q = quantization_for([a])
    first = pack.add(encode_mesh(a, q))
    again = pack.add(encode_mesh(Mesh(v.copy(), f.copy(), name="renamed"), q))
    other = pack.add(encode_mesh(Mesh(v * 1.01, f), q))
    assert first == again != other and len(pack.records) == 2
    assert pack.triangles == 2 * len(f)
    blob = zlib.decompress(pack.deflated())
    rec = pack.records[first]
    assert blob[rec["p"][0]:rec["p"][0] + rec["p"][1]] == encode_mesh(a, q)["parts"]["p"]


#: RFC 1924's base-85 alphabet, which Python's base64.b85decode reads: the same arithmetic as Z85
B85 = b"0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz!#$%&()*+-;<=>?@^_`{|}~"


def z85_decoded(text: bytes) -> bytes:
    """Z85 text → bytes, by the standard library's base-85 decoder."""
    return base64.b85decode(text.translate(bytes.maketrans(Z85, B85)))


def test_z85_is_zeromq_rfc_32():
    assert z85(bytes([0x86, 0x4F, 0xD2, 0x6F, 0xB5, 0x59, 0xF7, 0x5B])) == b"HelloWorld"  # the RFC's example
    data = np.random.default_rng(3).integers(0, 256, 4001, np.uint8).tobytes() + b"\xff" * 7
    text = z85(data)
    assert len(text) == 5 * 1002 and not set(text) - set(Z85) and b'"' not in text and b"\\" not in text
    assert z85_decoded(text)[:len(data)] == data
    assert z85(b"") == b""


def _scene(folder):
    text = (folder / "scene.js").read_text()
    assert text.startswith("window.ANATOMESH_SCENE = ") and text.endswith(";\n")
    return json.loads(text[len("window.ANATOMESH_SCENE = "):-2])


def test_page_of_two_variants_stores_shared_structures_once(tmp_path):
    """Two resection variants: the same liver and vessel, the tumour only in the first."""
    liver = Mesh(*icosphere(3, 60.0), name="liver", value=5, color=(0.55, 0.27, 0.17))
    vessel = Mesh(*torus(30.0, 4.0), name="portal vein", value=7, color=(0.2, 0.3, 0.8))
    tumour = Mesh(icosphere(2, 8.0)[0] + [20, 0, 0], icosphere(2, 8.0)[1], name="tumour", value=9)
    coarse = [Mesh(*icosphere(1, 60.0), name="liver", value=5), Mesh(*torus(30.0, 4.0, 12, 6), name="portal vein"),
              Mesh(icosphere(0, 8.0)[0] + [20, 0, 0], icosphere(0, 8.0)[1], name="tumour")]
    models = [WebModel("A", [coarse, [liver, vessel, tumour]]), WebModel("B", [coarse[:2], [liver, vessel]])]
    s = write_page(models, tmp_path / "page", title="Variants <A & B>")
    page = tmp_path / "page"
    assert sorted(p.relative_to(page).as_posix() for p in page.rglob("*") if p.is_file()) == \
        ["LICENSES.txt", "data/lod0.js", "data/lod1.js", "index.html", "scene.js", "viewer.js"]
    assert set(page_paths(page, 2)) == {p for p in page.rglob("*") if p.is_file()}
    assert s["stored_surfaces"] == 3 and s["structures"] == 5  # liver and vessel stored once
    assert [lv["file"] for lv in s["levels"]] == ["data/lod1.js", "data/lod0.js"]
    assert s["levels"][1]["triangles"] == liver.n_faces + vessel.n_faces + tumour.n_faces
    assert s["total_bytes"] == sum(p.stat().st_size for p in page.rglob("*") if p.is_file())
    sc = _scene(page)
    a, b = sc["models"]
    assert [x["geometry"] for x in a["structures"][:2]] == [x["geometry"] for x in b["structures"]]
    assert a["structures"][0]["system"] == "organs" and a["structures"][1]["system"] == "vessels"
    assert a["structures"][0]["volume_mm3"] == pytest.approx(4 / 3 * np.pi * 60 ** 3, rel=0.01)
    assert sc["levels"][1]["bytes"] == (page / "data/lod0.js").stat().st_size
    html = (page / "index.html").read_text()
    assert "<title>Variants &lt;A &amp; B&gt;</title>" in html and 'src="data/lod1.js"' in html
    assert not re.search(r"(src|href)=\"(https?:)?//", html)  # nothing from elsewhere
    js = (page / "data/lod0.js").read_bytes()
    m = re.fullmatch(rb'anatomeshLevel\(1,"([^"\\]+)",(\d+)\);\n', js)
    assert m and len(zlib.decompress(z85_decoded(m.group(1))[:int(m.group(2))])) == sum(
        sum(r[k][1] for k in "pic" if k in r) for r in sc["levels"][1]["geometries"].values())


def test_page_refuses_to_overwrite_and_checks_models(tmp_path):
    m = Mesh(*icosphere(1, 5.0), name="ball")
    write_page([WebModel("x", [[m]])], tmp_path)
    with pytest.raises(AnatomeshError, match="already exist"):
        write_page([WebModel("x", [[m]])], tmp_path)
    write_page([WebModel("x", [[m]])], tmp_path, overwrite=True)
    with pytest.raises(AnatomeshError, match="same number of levels"):
        write_page([WebModel("x", [[m]]), WebModel("y", [[m], [m]])], tmp_path / "b")
    with pytest.raises(AnatomeshError, match="no surfaces"):
        write_page([WebModel("x", [[]])], tmp_path / "c")
