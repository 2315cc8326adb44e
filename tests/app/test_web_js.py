"""The viewer's JavaScript: its unit tests (node's test runner), the committed bundle is the build
of the lockfile, and pages written by Python decode in JavaScript to the same surfaces.

Needs node and ``web/node_modules`` (``npm ci`` in web/, which tools/setup_env.sh runs)."""
import json
import subprocess

import numpy as np
import pytest

from anatomesh.app.web.page import VIEWER_DIR, VIEWER_FILES, WebModel, write_page
from anatomesh.app.web.pack import display_vertices
from anatomesh.core.model.mesh import Mesh, surface_area
from conftest import REPO
from helpers.meshes import icosphere, torus

WEB = REPO / "web"


def _run(node, *args, cwd=WEB):
    return subprocess.run([node, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_viewer_unit_tests_pass(node):
    r = _run(node, "--test", "test/")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "# fail 0" in r.stdout and "# pass 0" not in r.stdout


def test_committed_bundle_is_the_build_of_the_lockfile(node, tmp_path):
    r = _run(node, "build.mjs", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    for name in VIEWER_FILES:
        assert (tmp_path / name).read_bytes() == (VIEWER_DIR / name).read_bytes(), \
            f"app/web/viewer/{name} is stale: run `npm ci && npm run build` in web/ and commit it"
    lock = json.loads((WEB / "package-lock.json").read_text())["packages"]
    head = (VIEWER_DIR / "viewer.js").read_text(encoding="utf-8").splitlines()[0]
    for lib in ("three", "meshoptimizer"):
        assert f"{lib} {lock[f'node_modules/{lib}']['version']}" in head
    lic = (VIEWER_DIR / "LICENSES.txt").read_text()
    assert "three.js" in lic and "meshoptimizer" in lic and "fflate" in lic
    assert lic.count("Permission is hereby granted") == 3


def test_a_python_page_decodes_in_javascript_to_the_same_surfaces(node, tmp_path):
    v, f = icosphere(3, 25.0)
    ball = Mesh(v + [0, 40, 10], f, name="ball", space="LPS",
                vertex_colors=np.c_[(v[:, 2] > 0), np.zeros((len(v), 2))].astype(np.float32))
    ring = Mesh(*torus(30.0, 6.0), name="ring", space="LPS")
    coarse = [Mesh(icosphere(1, 25.0)[0] + [0, 40, 10], icosphere(1, 25.0)[1], name="ball", space="LPS"),
              Mesh(*torus(30.0, 6.0, 16, 8), name="ring", space="LPS")]
    write_page([WebModel("m", [coarse, [ball, ring]])], tmp_path)
    r = _run(node, WEB / "tools" / "decode-page.mjs", tmp_path)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    scene = json.loads((tmp_path / "scene.js").read_text().split("= ", 1)[1].rstrip(";\n"))
    step = scene["quantization"]["step"]
    for k, level in enumerate([coarse, [ball, ring]]):
        for s, m in zip(scene["models"][0]["structures"], level):
            g = got[k][s["geometry"][k]]
            d = display_vertices(m)
            assert (g["v"], g["t"]) == (m.n_vertices, m.n_faces)
            assert np.allclose(g["min"], d.min(0), atol=step / 2 + 1e-6)
            assert np.allclose(g["max"], d.max(0), atol=step / 2 + 1e-6)
            origin = np.asarray(scene["quantization"]["origin"])
            quantised = origin + np.rint((d - origin) / step) * step  # what the page stores
            assert g["area"] == pytest.approx(surface_area(quantised, m.faces), rel=1e-6)
            assert g["colors"] == (m.n_vertices if m.vertex_colors is not None else 0)
