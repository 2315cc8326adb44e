"""Packaging: every folder Python can import from the package is listed in pyproject.toml, so
``pip install .`` ships it (a missing ``addon/ui`` breaks ``--format blend`` of an installed
package) and setuptools prints no "Package would be ignored" warning; a release wheel carries
its portable kernels, and the installed package asks numba for them only where they fit."""
from __future__ import annotations

import os
import platform
import subprocess
import sys
import tomllib
import zipfile
from importlib import metadata
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ROOTS = ("core", "app", "addon", "data")


def _importable_folders():
    """Folders below the package roots that Python imports as packages: any with a .py file or
    an __init__.py, and any other folder with files (a namespace package to setuptools)."""
    out = set()
    for root in ROOTS:
        for d in [REPO / root] + [p for p in (REPO / root).rglob("*") if p.is_dir()]:
            if d.name == "__pycache__" or not any(f.is_file() for f in d.iterdir()):
                continue
            out.add("anatomesh." + ".".join(d.relative_to(REPO).parts))
    return out


def test_every_importable_folder_is_a_listed_package():
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    assert _importable_folders() - listed == set()
    assert all((REPO / Path(*p.split(".")[1:])).is_dir() for p in listed)


def test_data_folders_ship_their_files():
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    data = cfg["package-data"]
    assert data["anatomesh.app.web.viewer"] == ["*"] and (REPO / "app" / "web" / "viewer" / "viewer.js").is_file()
    assert data["anatomesh.data.sample"] == ["*"]
    assert data["anatomesh.core.model.styles"] == ["*.toml"] and (REPO / "core" / "model" / "styles" / "default.toml").is_file()


def _probe_package(tmp_path: Path, marker_line: str) -> Path:
    """The package's root ``__init__.py`` alone in ``tmp_path/probe``, with a marker line."""
    package = tmp_path / "probe"
    package.mkdir()
    (package / "__init__.py").write_text((REPO / "__init__.py").read_text())
    (package / "portable_kernels.txt").write_text(marker_line + "\n")
    return package


def _cpu_after_import(tmp_path: Path, first: str = "", **env) -> str:
    code = f"{first}import os, probe; print(os.environ.get('NUMBA_CPU_NAME'))"
    clean = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env={**clean, **env},
                          capture_output=True, text=True, check=True)
    return done.stdout.strip()


def test_shipped_portable_kernels_are_asked_for_only_on_a_match(tmp_path):
    """An install whose marker names this platform, machine, Python and numba asks numba for
    generic-CPU code (so it loads the shipped kernels); any other, or a user's own choice of CPU,
    or numba imported before, leaves numba alone."""
    here = (f"{sys.platform} {platform.machine()} {sys.implementation.cache_tag} "
            f"numba {metadata.version('numba')}")
    _probe_package(tmp_path, here)
    assert _cpu_after_import(tmp_path) == "generic"
    assert _cpu_after_import(tmp_path, NUMBA_CPU_NAME="skylake") == "skylake"
    assert _cpu_after_import(tmp_path, first="import numba; ") == "None"
    (tmp_path / "probe" / "portable_kernels.txt").write_text(here.replace("numba ", "numba 0.0") + "\n")
    assert _cpu_after_import(tmp_path) == "None"


def test_the_wheel_carries_the_kernels_and_marker_it_is_built_with(tmp_path):
    """tools/build_wheel.py's packaging step: numba's index and data files beside the sources and
    the marker end up in the wheel (the kernels' compiling itself: the extension's install test)."""
    sys.path.insert(0, str(REPO / "tools"))
    try:
        import build_wheel
    finally:
        sys.path.pop(0)
    package = build_wheel.stage(tmp_path / "work")
    cache = package / "core" / "smooth" / "__pycache__"
    cache.mkdir(exist_ok=True)
    (cache / "_pass_kernels.kernel-12.py311.nbi").write_bytes(b"index")
    (cache / "_pass_kernels.kernel-12.py311.1.nbc").write_bytes(b"code")
    (cache / "_pass_kernels.cpython-311.pyc").write_bytes(b"bytecode")
    build_wheel.write_marker(package, ["linux x86_64 cpython-311 numba 0.68.1"])
    build_wheel.add_kernels_to_package_data(package)
    wheel = build_wheel.pip_wheel(package, tmp_path / "dist")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {"anatomesh/core/smooth/__pycache__/_pass_kernels.kernel-12.py311.nbi",
            "anatomesh/core/smooth/__pycache__/_pass_kernels.kernel-12.py311.1.nbc",
            "anatomesh/portable_kernels.txt", "anatomesh/core/smooth/_pass_kernels.py"} <= names
    assert not any(n.endswith(".pyc") for n in names)
