"""Build Anatomesh's wheel with its numba kernels compiled for a portable CPU, so that a user's
first command loads them instead of compiling them (minutes of one core).

numba keys a cached kernel by the source file's content (sha256), the Python, the machine triple
and the CPU it was compiled for; compiled with ``NUMBA_CPU_NAME=generic`` the CPU part is
"generic" with no extra features, which every x86-64 (or arm64) machine of the same platform
runs. This script:

1. copies the checkout's tracked files into ``<work>/stage/anatomesh``;
2. runs the warm-up's default flow there with ``NUMBA_CPU_NAME=generic`` (the same module
   names and source bytes as the installed package), numba writing its cache beside the sources,
   with this Python or with each ``--pythons`` version in a fresh venv holding the package's
   dependencies as a user's would;
3. writes ``portable_kernels.txt`` (platform, machine, Python, numba version of each build),
   which tells the installed package to ask numba for these kernels (root ``__init__.py``), and
   adds the caches to the wheel's package data;
4. ``pip wheel`` of the stage.

Where numba, Python or the platform differ from a build's, the package leaves numba alone and it
compiles on first use as without them. Generic-CPU kernels run the whole ``anatomesh mesh``
command as fast as kernels compiled for the host (``benchmarks/bench_generic_cpu.py``), so nothing
is compiled again for the host. ::

    python tools/build_wheel.py [--out dist] [--pythons 3.10,3.11,3.12,3.13] [--no-kernels]
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import List, Optional, Sequence

REPO = Path(__file__).resolve().parents[1]
#: written beside the package's ``__init__.py`` when the wheel ships portable kernels
MARKER = "portable_kernels.txt"
#: what the stage's pyproject adds to the package data: numba's index and data files
CACHE_FILES = '"*" = ["__pycache__/*.nbi", "__pycache__/*.nbc"]'


def stage(work: Path) -> Path:
    """The checkout's tracked files (git ls-files) copied into ``work/stage/anatomesh``."""
    dest = work / "stage" / "anatomesh"
    if dest.exists():
        shutil.rmtree(dest)
    names = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
    for name in filter(None, names.decode().split("\0")):
        source = REPO / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)
    return dest


def compile_portable_kernels(package: Path, python: str = sys.executable, name: str = "anatomesh",
                             steps: Optional[str] = None) -> str:
    """Run the warm-up's default flow (or its ``steps``, comma-separated) with ``python`` (an
    interpreter with Anatomesh's dependencies), the package in ``package`` imported as ``name``
    (as it will be installed: ``bl_ext.user_default.anatomesh`` in Blender) and numba targeting
    a generic CPU; numba writes the caches beside the sources. Returns the marker line of this
    build: ``<platform> <machine> <python cache tag> numba <version>``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(NUMBA_CPU_NAME="generic", PYTHONPATH=str(package.parent), PYTHONDONTWRITEBYTECODE="1")
    which = ["--steps", steps] if steps else ["--default-only"]
    as_name = [] if name == "anatomesh" else ["--as", name, str(package.parent)]
    subprocess.run([python, "-m", "anatomesh.app.warmup", "--quiet", *which, *as_name],
                   cwd=package.parent, env=env, check=True)
    facts = ("import platform, sys; from importlib.metadata import version; "
             "print(sys.platform, platform.machine(), sys.implementation.cache_tag, 'numba', version('numba'))")
    return subprocess.run([python, "-c", facts], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def build_python(version: str, plain_wheel: Path, work: Path) -> str:
    """A venv of ``python<version>`` (on the PATH) in ``work`` with the plain wheel and its
    dependencies installed, as a user's would be; returns its interpreter."""
    found = shutil.which(f"python{version}")
    if found is None:
        sys.exit(f"error: python{version} not found on the PATH")
    venv = work / f"venv-{version}"
    quietly([found, "-m", "venv", str(venv)])
    python = str(venv / "bin" / "python")
    quietly([python, "-m", "pip", "install", "-q", "--upgrade", "pip"])
    quietly([python, "-m", "pip", "install", "-q", str(plain_wheel)])
    return python


def quietly(command: List[str]) -> None:
    """Run ``command``, its output shown only when it fails (then this script stops)."""
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(command)} failed:\n{done.stdout[-3000:]}{done.stderr[-3000:]}")


def write_marker(package: Path, lines: List[str]) -> None:
    """The marker the installed package reads (root ``__init__.py``): one line per build."""
    (package / MARKER).write_text("".join(line + "\n" for line in lines))


def add_kernels_to_package_data(package: Path) -> None:
    """The stage's pyproject carries the marker and numba's caches into the wheel."""
    pyproject = package / "pyproject.toml"
    text = pyproject.read_text()
    head = "[tool.setuptools.package-data]\n"
    assert head in text, "pyproject.toml lost its [tool.setuptools.package-data] table"
    text = text.replace(head, f"{head}{CACHE_FILES}\n")
    text = text.replace('anatomesh = ["blender_manifest.toml"]', f'anatomesh = ["blender_manifest.toml", "{MARKER}"]')
    pyproject.write_text(text)


def pip_wheel(package: Path, out: Path) -> Path:
    """``pip wheel`` of the staged package into ``out`` (the build backend's output shown only
    when it fails); returns the wheel."""
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("anatomesh-*.whl"):
        old.unlink()
    quietly([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(package)])
    return next(out.glob("anatomesh-*.whl"))


def build(out: Path, pythons: Sequence[str] = (), work: Optional[Path] = None) -> Path:
    """The wheel in ``out`` (returned), with portable kernels for this Python (when ``pythons``
    is empty) or for each ``python<version>`` of ``pythons``; ``pythons=None``: a plain wheel."""
    with tempfile.TemporaryDirectory(prefix="anatomesh_wheel_") as tmp:
        work = Path(work or tmp)
        package = stage(work)
        if pythons is None:
            return pip_wheel(package, out)
        plain = pip_wheel(package, work / "plain") if pythons else None
        interpreters = [build_python(v, plain, work) for v in pythons] or [sys.executable]
        write_marker(package, [compile_portable_kernels(package, python) for python in interpreters])
        add_kernels_to_package_data(package)
        count = len(list(package.rglob("__pycache__/*.nbi")))
        print(f"portable kernels: {count} index files for " + "; ".join((package / MARKER).read_text().splitlines()))
        return pip_wheel(package, out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(REPO / "dist"), help="folder for the wheel (default: dist/)")
    p.add_argument("--pythons", default="",
                   help="comma list of Python versions (python3.X on the PATH) to compile kernels for, "
                        "each in a fresh venv (default: this Python, with its packages)")
    p.add_argument("--no-kernels", action="store_true", help="a plain wheel: kernels compile on first use")
    args = p.parse_args(argv)
    pythons = None if args.no_kernels else [v.strip() for v in args.pythons.split(",") if v.strip()]
    wheel = build(Path(args.out), pythons)
    print(f"{wheel} ({wheel.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
