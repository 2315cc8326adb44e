"""Install as a user would, and time the first commands.

For each Python found (``python3.10`` .. ``python3.13`` on the PATH, or ``--pythons``): build the
wheel once as a release is built (``tools/build_wheel.py``: portable kernels for each of these
Pythons; ``--plain``: a plain ``pip wheel``, kernels compiled on first use), install it into a
fresh venv (``pip install anatomesh-*.whl``, its dependencies from the index), then time, with no
numba cache but the wheel's:

* ``anatomesh --version``;
* the first ``anatomesh mesh`` of the bundled sample (41-label map, STL): the whole command, and
  the longest time the command printed nothing (stdout and stderr read line by line);
* the same command again.

Then Blender: the extension zip of this platform (``tools/build_extension.py``, wheels bundled,
portable kernels unless ``--plain``) installed with Blender's own installer
(``bpy.ops.extensions.package_install_files``) into a fresh user folder, the background warm-up
started as enabling it does, the sample imported with extraction: when its objects are there and
when they are smoothed.

Prints one row per Python and a line for Blender; the targets are a first command within 20 s,
no silence over 5 s, and smoothed surfaces in Blender within 10 s. Needs the network index pip
uses (or its mirror); several minutes per Python on 2 cores::

    python benchmarks/bench_install.py [--pythons 3.11,3.13] [--plain] [--no-blender] [--keep DIR]
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import build_extension  # noqa: E402
import build_wheel  # noqa: E402

sys.path.pop(0)
SAMPLE = REPO / "data" / "sample" / "example_seg.nii.gz"


def fresh_venv(python: str, folder: Path, wheel: Path) -> Path:
    """A new venv of ``python`` with the wheel installed; returns its ``bin`` folder."""
    subprocess.run([python, "-m", "venv", str(folder)], check=True)
    pip = [str(folder / "bin" / "python"), "-m", "pip", "install", "-q"]
    subprocess.run(pip + ["--upgrade", "pip"], check=True)
    subprocess.run(pip + [str(wheel)], check=True)
    return folder / "bin"


def timed(command, cwd: Path):
    """``(seconds, longest silence in seconds, return code, last line)`` of a command, its
    stdout and stderr read line by line as they come."""
    t0 = time.perf_counter()
    stamps, lines = [t0], []
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}  # as a new user's
    process = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True)

    def read():
        for line in process.stdout:
            stamps.append(time.perf_counter())
            lines.append(line.rstrip("\n"))

    reader = threading.Thread(target=read)
    reader.start()
    code = process.wait()
    reader.join()
    t1 = time.perf_counter()
    stamps.append(t1)
    silence = max(b - a for a, b in zip(stamps, stamps[1:]))
    return t1 - t0, silence, code, lines[-1] if lines else ""


def one_python(python: str, wheel: Path, work: Path) -> dict:
    """Install and time the first commands with ``python``."""
    version = subprocess.run([python, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    t0 = time.perf_counter()
    try:
        bin_dir = fresh_venv(python, work / f"venv-{version}", wheel)
    except subprocess.CalledProcessError as exc:
        return {"python": version, "install": f"failed ({exc.returncode})"}
    row = {"python": version, "install_s": round(time.perf_counter() - t0, 1)}
    numpy = subprocess.run([str(bin_dir / "python"), "-c", "import numpy; print(numpy.__version__)"],
                           capture_output=True, text=True).stdout.strip()
    row["numpy"] = numpy
    _, _, code, last = timed([str(bin_dir / "anatomesh"), "--version"], work)
    row["version"] = last if code == 0 else f"failed: {last}"
    for key in ("first", "second"):
        out = work / f"out-{version}-{key}"
        s, silence, code, last = timed([str(bin_dir / "anatomesh"), "mesh", str(SAMPLE), "--out", str(out),
                                        "--overwrite"], work)
        row[f"{key}_mesh_s"], row[f"{key}_silence_s"] = round(s, 1), round(silence, 1)
        if code != 0:
            row[f"{key}_error"] = last
    return row


_BLENDER_FIRST_EXTRACT = """
import os, sys, time
os.environ["BLENDER_USER_RESOURCES"] = {user!r}
import bpy
t0 = time.perf_counter()
assert bpy.ops.extensions.package_install_files(filepath={zip!r}, repo="user_default",
                                                 enable_on_install=True) == {{"FINISHED"}}
installed = time.perf_counter() - t0
from bl_ext.user_default.anatomesh.addon.operators import warmup
from bl_ext.user_default.anatomesh.addon.scene import bridge
from bl_ext.user_default.anatomesh.app.warmup.compile import counting_compiles
sys.path.insert(0, {benchmarks!r})
from bench_first_run import wait_for_warmup
t1 = time.perf_counter()
warmup.start(force=True)  # what enabling the extension does in a Blender with a window
with counting_compiles() as compiled:
    assert bpy.ops.anatomesh.import_scan(filepath={sample!r}, extract=True) == {{"FINISHED"}}
    marks = wait_for_warmup(bpy.context.scene, warmup, bridge, t1)
print("BLENDER", round(installed, 1), marks["objects"][1], round(marks["objects"][0], 1),
      round(marks["smoothed"], 1), round(time.perf_counter() - t1, 1), len(compiled), flush=True)
"""


def blender_first_extract(work: Path, kernels: bool) -> str:
    """Build the extension zip (``tools/build_extension.py``: the wheels bundled, portable
    kernels unless ``kernels`` is False), install it with Blender's own installer into a fresh
    user folder (the ``bpy`` module, a new process, no numba cache but the zip's), enable it,
    import the sample with extraction: one line of times."""
    zips = build_extension.build(work / "extension-dist", kernels=kernels, work=work / "extension")
    (zip_path,) = [z for z in zips if build_extension._BUILDER_PLATFORM in z.name]
    script = _BLENDER_FIRST_EXTRACT.format(user=str(work / "blender-user"), zip=str(zip_path),
                                          benchmarks=str(REPO / "benchmarks"), sample=str(SAMPLE))
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    line = next((x for x in out.stdout.splitlines() if x.startswith("BLENDER ")), None)
    if line is None:
        return f"Blender: failed ({out.returncode}): {out.stderr[-500:]}"
    installed, objects, at, smoothed, everything, compiled = line.split()[1:]
    return (f"Blender ({zip_path.name}, {zip_path.stat().st_size / 2**20:.0f} MiB): installed and enabled in "
            f"{installed} s; first Extract of the sample: {objects} objects after {at} s, smoothed after "
            f"{smoothed} s (target 10 s); the background warm-up done after {everything} s; kernels "
            f"compiled in Blender's own process: {compiled}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--pythons", default="3.10,3.11,3.12,3.13", help="comma list of versions (python3.X on the PATH)")
    p.add_argument("--plain", action="store_true", help="a plain wheel, no portable kernels")
    p.add_argument("--keep", help="keep the venvs and outputs in this folder")
    p.add_argument("--no-blender", dest="blender", action="store_false", help="skip the extension")
    args = p.parse_args(argv)
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="anatomesh_install_"))
    work.mkdir(parents=True, exist_ok=True)
    versions = [v.strip() for v in args.pythons.split(",") if shutil.which(f"python{v.strip()}")]
    t0 = time.perf_counter()
    wheel = build_wheel.build(work / "dist", None if args.plain else versions, work=work / "build")
    print(f"wheel built in {time.perf_counter() - t0:.0f} s")
    print(f"wheel: {wheel.name} ({wheel.stat().st_size / 1e6:.1f} MB)")
    print(f"{'python':>6} {'numpy':>8} {'install s':>9} {'version':>22} {'1st mesh s':>10} {'silence s':>9} "
          f"{'2nd mesh s':>10}")
    for v in args.pythons.split(","):
        python = shutil.which(f"python{v.strip()}")
        if python is None:
            print(f"{v:>6} not found")
            continue
        r = one_python(python, wheel, work)
        if "install_s" not in r:
            print(f"{r['python']:>6} install {r['install']}")
            continue
        print(f"{r['python']:>6} {r['numpy']:>8} {r['install_s']:>9} {r['version'][:22]:>22} "
              f"{r['first_mesh_s']:>10} {r['first_silence_s']:>9} {r['second_mesh_s']:>10}"
              + (f"  error: {r.get('first_error') or r.get('second_error')}"
                 if "first_error" in r or "second_error" in r else ""), flush=True)
    if args.blender:
        print(blender_first_extract(work, kernels=not args.plain), flush=True)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
