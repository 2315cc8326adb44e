"""Fixtures of the page and file tests: node with the web folder's packages, one Chromium."""
from __future__ import annotations

import shutil

import pytest

from conftest import REPO
from helpers.browser import Page, browser

WEB = REPO / "web"


@pytest.fixture(scope="module")
def node():
    """The node executable, with web/node_modules installed (three, meshoptimizer, gltf-validator)."""
    exe = shutil.which("node")
    if exe is None:
        pytest.fail("node is missing: install Node.js 18+ (tools/setup_env.sh does on Debian)")
    for package in ("three", "gltf-validator"):
        if not (WEB / "node_modules" / package / "package.json").exists():
            pytest.fail(f"web/node_modules/{package} is missing: run `npm ci` in web/ (tools/setup_env.sh does)")
    return exe


@pytest.fixture(scope="module")
def chromium():
    """One headless Chromium for a test module."""
    with browser() as b:
        yield b


@pytest.fixture
def page(chromium, sample_run):
    """The page of the module's ``sample_run`` (result, page folder) open in the browser."""
    p = Page(chromium, sample_run[1])
    yield p
    p.page.close()
