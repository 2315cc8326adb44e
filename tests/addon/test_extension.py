"""The extension package: the manifest validates, and the built zip installs into a fresh Blender."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import tomllib
import zipfile
from pathlib import Path

from packaging.requirements import Requirement

from conftest import REPO, shared  # tests/conftest.py

sys.path.insert(0, str(REPO / "tools"))
import build_extension  # noqa: E402

sys.path.pop(0)


def test_manifest_validates():
    ext = build_extension.find_blender_ext()
    out = subprocess.run([sys.executable, str(ext), "validate", str(REPO)], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    text = (REPO / "blender_manifest.toml").read_text()
    wheels = build_extension.manifest_wheels(text)
    assert wheels and not any("numpy" in w for w in wheels)  # Blender ships numpy
    for plat in ("win_amd64", "manylinux", "macosx"):
        assert any(plat in w and "numba" in w for w in wheels), plat
        # DICOM SEG reading (highdicom) and its compiled dependencies, on every platform
        assert any(plat in w and "pillow" in w for w in wheels), plat
        assert any(plat in w and "pyjpegls" in w for w in wheels), plat
    assert any(w.endswith(".whl") and "highdicom" in w for w in wheels)
    # every runtime dependency of the package that Blender's Python 3.11 needs, but numpy
    # (Blender's own), is bundled: a wheel per platform, or one for all
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    blender_python = {"python_version": "3.11", "python_full_version": "3.11.9"}
    for dep in map(Requirement, deps):
        if dep.name == "numpy" or (dep.marker is not None and not dep.marker.evaluate(blender_python)):
            continue
        name = dep.name.lower().replace("-", "_")
        mine = [w for w in wheels if Path(w).name.lower().startswith(name + "-")]
        assert any(w.endswith("-none-any.whl") for w in mine) or all(
            any(plat in w for w in mine) for plat in ("win_amd64", "manylinux", "macosx")), dep
    stripped = tomllib.loads(build_extension.strip_wheels(text))
    assert "wheels" not in stripped and "platforms" not in stripped and stripped["id"] == "anatomesh"
    assert stripped["blender_version_min"] == "4.2.0" and stripped["permissions"]["files"]


def test_no_wheels_zip_installs_and_its_kernels_load(tmp_path):
    """Build with tools/build_extension.py --no-wheels (numba's kernels compiled for a generic CPU
    inside: the steps a label map's extraction and first smoothing wait for); install it with
    Blender's own installer in a fresh Blender (subprocess, no numba cache of ours): the first
    extraction of the sample loads every kernel, compiling none."""
    seg = str(shared("totalsegmentator", "example_seg.nii.gz"))
    table = str(shared("totalsegmentator", "label_names_total_and_total_mr.json"))
    steps = "reading,label surfaces,large label maps,label smoothing"
    (zip_path,) = build_extension.build(tmp_path / "dist", wheels=False, kernel_steps=steps, work=tmp_path / "work")
    names = zipfile.ZipFile(zip_path).namelist()
    assert "blender_manifest.toml" in names and "addon/operators/scan.py" in names and "core/model/mesh.py" in names and "app/flow/run.py" in names
    assert not any(n.startswith(("tests/", "benchmarks/", "tools/", "data/", "examples/", ".")) for n in names)
    assert not any(n.endswith(".pyc") for n in names)
    assert "portable_kernels.txt" in names and sum(n.endswith(".nbi") for n in names) > 50
    script = textwrap.dedent(f"""
        import os
        os.environ["BLENDER_USER_RESOURCES"] = {str(tmp_path / "user")!r}
        import bpy, addon_utils
        assert bpy.ops.extensions.package_install_files(
            filepath={str(zip_path)!r}, repo="user_default", enable_on_install=True) == {{"FINISHED"}}
        mod = "bl_ext.user_default.anatomesh"
        assert addon_utils.check(mod) == (True, True), addon_utils.check(mod)
        from bl_ext.user_default.anatomesh.app.warmup.compile import counting_compiles
        bpy.ops.wm.read_homefile(use_empty=True)
        with counting_compiles() as compiled:
            r = bpy.ops.anatomesh.import_scan(filepath={seg!r}, label_table={table!r}, extract=True)
        s = bpy.context.scene.anatomesh
        coll = bpy.data.collections[s.last_collection]
        print("RESULT", sorted(r), len(s.labels), s.labels[0].name, len(coll.all_objects),
              os.environ.get("NUMBA_CPU_NAME"), "COMPILED", compiled)
    """)
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}  # as a user's Blender
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600, env=env)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "RESULT ['FINISHED'] 41 spleen 41 generic COMPILED []" in out.stdout, out.stdout[-2000:]


def test_example_script_runs_headless(tmp_path):
    """examples/blender_import_labels.py as `python script.py options` (bpy module), no render."""
    out = subprocess.run([sys.executable, str(REPO / "examples" / "blender_import_labels.py"), "--out",
                          str(tmp_path), "--iterations", "2", "--no-render"],
                         capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "41 surfaces in 'example_seg'" in out.stdout
    assert (tmp_path / "example_seg.blend").stat().st_size > 100_000


def test_example_runs_as_blender_runs_it(tmp_path):
    """examples/pipeline_to_blend.py the way `blender -b -P script.py -- options` runs it: bpy
    already imported, Blender's own arguments before "--", the script run as __main__."""
    script = REPO / "examples" / "pipeline_to_blend.py"
    launcher = textwrap.dedent(f"""
        import runpy, sys
        import bpy
        sys.argv = ["blender", "-b", "-P", {str(script)!r}, "--", "--out", {str(tmp_path)!r},
                    "--labels", "liver,spleen", "--samples", "1"]
        runpy.run_path({str(script)!r}, run_name="__main__")
    """)
    out = subprocess.run([sys.executable, "-c", launcher], capture_output=True, text=True,
                         timeout=600, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "2 surfaces" in out.stdout
    names = {p.name for p in tmp_path.iterdir()}
    assert {"liver.stl", "spleen.stl", "example_seg.glb", "example_seg.blend", "example_seg.png"} <= names
