"""Install as a user would, and time the first commands.

For each Python found (``python3.10`` .. ``python3.13`` on the PATH, or ``--pythons``): build the
wheel once (``pip wheel``), install it into a fresh venv (``pip install anatomesh-*.whl``, its
dependencies from the index), then time, with empty numba caches:

* ``anatomesh --version``;
* the first ``anatomesh mesh`` of the bundled sample (41-label map, STL): the whole command, and
  the longest time the command printed nothing (stdout and stderr read line by line);
* the same command again (kernels loaded from the cache numba wrote next to the installed sources).

Prints one row per Python; the issue's targets are a first command within 20 s and no silence over
5 s. Needs the network index pip uses (or its mirror); several minutes per Python on 2 cores::

    python benchmarks/bench_install.py [--pythons 3.11,3.13] [--keep DIR]
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "data" / "sample" / "example_seg.nii.gz"


def build_wheel(folder: Path) -> Path:
    """``pip wheel`` of the checkout (no dependencies) into ``folder``."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(folder), str(REPO)],
                   check=True)
    return next(folder.glob("anatomesh-*.whl"))


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
    process = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--pythons", default="3.10,3.11,3.12,3.13", help="comma list of versions (python3.X on the PATH)")
    p.add_argument("--keep", help="keep the venvs and outputs in this folder")
    args = p.parse_args(argv)
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="anatomesh_install_"))
    work.mkdir(parents=True, exist_ok=True)
    wheel = build_wheel(work / "dist")
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
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
