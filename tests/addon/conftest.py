"""Blender (bpy module) fixtures: a throw-away user folder and the add-on enabled from the checkout.

``BLENDER_USER_RESOURCES`` must point at a temporary folder *before* ``bpy`` is imported, so the
tests never read or write the developer's own Blender preferences. ``bpy`` is imported here, early,
before anything can import pymeshlab (their bundled libraries clash when pymeshlab comes first).

The add-on is enabled the way Blender enables an extension, without building a zip: a user
extension repository whose folder holds a link named ``anatomesh`` to this checkout, then
``addon_utils.enable("bl_ext.<repo>.anatomesh")``.
"""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
REPO_MODULE = "anatomesh_dev"
ADDON_MODULE = f"bl_ext.{REPO_MODULE}.anatomesh"

if "bpy" not in sys.modules:
    _USER = tempfile.mkdtemp(prefix="anatomesh_blender_user_")
    os.environ["BLENDER_USER_RESOURCES"] = _USER

# numba keys its on-disk cache by source file, but a cached kernel remembers the *module name* it
# was compiled under. Here the same files are imported twice, as ``anatomesh.core...`` (the
# editable install) and as ``bl_ext.anatomesh_dev.anatomesh.core...`` (the add-on through the
# link); sharing core/**/__pycache__ would make each load the other's kernels and fail with
# "No module named 'bl_ext...'". A cache folder of our own, keyed by the (unresolved) path,
# keeps them apart and persists between runs (build/ is git-ignored).
os.environ.setdefault("NUMBA_CACHE_DIR", str(REPO / "build" / "numba-cache-blender-tests"))
if "numba" in sys.modules:
    from numba.core import config as _numba_config

    _numba_config.reload_config()

try:
    import bpy
except ImportError:  # the test extras install bpy; without it these tests cannot run at all
    bpy = None
    collect_ignore_glob = ["test_*.py"]


def pytest_report_header(config):
    if bpy is None:
        return "tests/addon: SKIPPED, the bpy module is missing (pip install bpy==5.0.1)"
    return f"tests/addon: bpy {bpy.app.version_string}, Blender user folder {os.environ.get('BLENDER_USER_RESOURCES', '(default)')}"


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/addon/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.blender)


def enable_from_checkout(repo_dir: Path, source: Path = REPO) -> str:
    """Register ``repo_dir`` as a user extension repo holding a link to ``source``; enable it."""
    import addon_utils

    repo_dir.mkdir(parents=True, exist_ok=True)
    link = repo_dir / "anatomesh"
    if link.is_symlink() and link.resolve() != source.resolve():
        link.unlink()  # a link left by another checkout
    if not link.exists():
        link.symlink_to(source, target_is_directory=True)
    repos = bpy.context.preferences.extensions.repos
    if not any(r.module == REPO_MODULE for r in repos):
        repos.new(name="Anatomesh (checkout)", module=REPO_MODULE, custom_directory=str(repo_dir),
                  source="USER")
    mod = addon_utils.enable(ADDON_MODULE, default_set=True, handle_error=_raise)
    if mod is None:
        raise RuntimeError(f"could not enable {ADDON_MODULE}")
    return ADDON_MODULE


def _raise(exc):
    raise exc


@pytest.fixture(scope="session")
def addon():
    """The enabled add-on's module (``bl_ext.anatomesh_dev.anatomesh``).

    The repository folder is a fixed path under build/ so numba's cache (keyed by the path the
    kernels are imported from) is reused between test runs.
    """
    name = enable_from_checkout(REPO / "build" / "blender-test-extensions" / REPO_MODULE)
    yield sys.modules[name]
    import addon_utils

    addon_utils.disable(name, default_set=True)


@pytest.fixture
def empty_scene(addon):
    """A new empty file (the add-on stays enabled)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    return bpy.context.scene
