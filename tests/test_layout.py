"""Package rules: core never imports bpy; the root package imports without Blender."""
import subprocess
import sys


def test_core_never_imports_bpy():
    code = ("import sys, anatomesh, anatomesh.core, anatomesh.core.cli, anatomesh.core.pipeline, "
            "anatomesh.core.extract; assert 'bpy' not in sys.modules, 'bpy imported'; "
            "assert 'anatomesh.addon' not in sys.modules; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
