"""Every kind of GLB `anatomesh mesh` writes passes the Khronos glTF Validator (npm
``gltf-validator``, run by ``web/tools/validate-gltf.mjs``) with no error and no warning, and
see-through structures (the default style's lungs, a style file's opacity) are blended with
alpha < 1.

Needs node and ``web/node_modules`` (``npm ci`` in web/, which tools/setup_env.sh runs)."""
import json
import struct
import subprocess

import pytest

from anatomesh.app.cli import main as cli_main
from conftest import REPO, SAMPLE, shared

WEB = REPO / "web"


def _validate(node, paths):
    r = subprocess.run([node, "tools/validate-gltf.mjs", *map(str, paths)], cwd=WEB,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    reports = [json.loads(line) for line in r.stdout.splitlines()]
    assert [rep["file"] for rep in reports] == [str(p) for p in paths]
    return reports


def _materials(path):
    raw = path.read_bytes()
    n = struct.unpack("<I", raw[12:16])[0]
    return {m["name"]: m for m in json.loads(raw[20:20 + n])["materials"]}


def _mesh(tmp_path, name, *argv):
    out = tmp_path / name
    assert cli_main(["mesh", *map(str, argv), "--out", str(out), "--format", "glb"]) == 0
    return sorted(out.glob("*.glb"))


def test_every_glb_we_write_is_valid_gltf(node, tmp_path):
    style = tmp_path / "see_through.toml"
    style.write_text('[structures]\nliver = { opacity = 0.5 }\n')
    ct = shared("totalsegmentator", "example_ct_sm.nii.gz")
    written = {
        "default + lod": _mesh(tmp_path, "lod", SAMPLE / "example_seg.nii.gz", "--lod", "3"),
        "distance colours": _mesh(tmp_path, "dist", SAMPLE / "example_seg.nii.gz", "--distance-to", "liver"),
        "MR, LPS, style": _mesh(tmp_path, "mr", shared("totalsegmentator", "example_seg_mr.nii.gz"),
                                "--style", style),
        "scan levels": _mesh(tmp_path, "levels", ct, "--level", "skin:-300", "--level", "bone:300"),
        "fuzzy shells": _mesh(tmp_path, "fuzzy", ct, "--fuzzy=-400,200,3"),
    }
    assert len(written["default + lod"]) == 4  # the scene and lod0..lod2
    paths = [p for ps in written.values() for p in ps]
    for rep in _validate(node, paths):
        assert (rep["errors"], rep["warnings"]) == (0, 0), (rep["file"], rep["messages"][:5])

    for path in written["default + lod"]:  # the default style's lungs are see-through
        for name, m in _materials(path).items():
            alpha = m["pbrMetallicRoughness"]["baseColorFactor"][3]
            if name.startswith("lung_"):
                assert m.get("alphaMode") == "BLEND" and alpha < 1, (path.name, name)
            else:
                assert "alphaMode" not in m and alpha == 1.0, (path.name, name)
    mr = _materials(written["MR, LPS, style"][0])
    assert mr["liver"]["alphaMode"] == "BLEND" and mr["liver"]["pbrMetallicRoughness"]["baseColorFactor"][3] == 0.5
    assert mr["lung_right"]["alphaMode"] == "BLEND"
    fuzzy = _materials(written["fuzzy shells"][0])
    assert sum(m.get("alphaMode") == "BLEND" for m in fuzzy.values()) >= 2
