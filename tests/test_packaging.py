"""Packaging: every folder Python can import from the package is listed in pyproject.toml, so
``pip install .`` ships it (a missing ``addon/ui`` breaks ``--format blend`` of an installed
package) and setuptools prints no "Package would be ignored" warning."""
from __future__ import annotations

import tomllib
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
