"""Headless Chromium from Debian's packages (``/usr/bin/chromium``), driven with Playwright for
Python: open a generated page from ``file://``, wait for its pictures, read its pixels.

Nothing downloads a browser: Playwright only drives the system's binary. The flags keep it
offline and quiet (the test machines have no network), the profile is a fresh temporary one.
"""
from __future__ import annotations

import base64
import os
import shutil
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = os.environ.get("ANATOMESH_CHROMIUM", "/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def chromium_or_skip() -> str:
    """The browser's path; fails in CI (tools/setup_env.sh installs it), skips elsewhere."""
    if Path(CHROMIUM).exists() or shutil.which(CHROMIUM):
        return CHROMIUM
    msg = f"{CHROMIUM} missing: apt-get install chromium (tools/setup_env.sh does as root)"
    if os.environ.get("CI"):
        pytest.fail(msg)
    pytest.skip(msg)


@contextmanager
def browser():
    """A headless Chromium (Playwright ``Browser``), closed at the end."""
    from playwright.sync_api import sync_playwright

    exe = chromium_or_skip()
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe, args=FLAGS)
        try:
            yield b
        finally:
            b.close()


class Page:
    """A generated page opened from ``file://`` with its console, errors and requests recorded."""

    def __init__(self, b, folder: Path, size=(900, 560)):
        self.folder = Path(folder).resolve()
        self.page = b.new_page(viewport={"width": size[0], "height": size[1]})
        self.console, self.requests = [], []
        self.page.on("console", lambda m: self.console.append((m.type, m.text)))
        self.page.on("pageerror", lambda e: self.console.append(("pageerror", str(e))))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.goto((self.folder / "index.html").as_uri())
        self.page.wait_for_function("window.anatomesh && window.anatomesh.done === true", timeout=90000)

    def js(self, expr: str, arg=None):
        return self.page.evaluate(expr, arg)

    def pixels(self) -> np.ndarray:
        """The canvas as drawn now: (H, W, 3) uint8, top row first."""
        d = self.js("anatomesh.pixels()")
        a = np.frombuffer(base64.b64decode(d["data"]), np.uint8).reshape(d["height"], d["width"], 4)
        return a[::-1, :, :3].copy()

    def errors(self):
        return [(t, m) for t, m in self.console if t in ("error", "pageerror")]

    def open_group(self, name: str) -> None:
        """Open the tree group holding structure ``name`` (its inputs become clickable)."""
        self.js("n => document.querySelector(`input[data-structure=\"${n}\"]`).closest('details').open = true", name)

    def set_range(self, selector: str, value: float) -> None:
        self.page.eval_on_selector(selector, "(e, v) => { e.value = v; e.dispatchEvent(new Event('input')); }", value)


def srgb_to_linear(c) -> np.ndarray:
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lit_residual(seen_rgb8, albedo) -> float:
    """How far a lit colour (uint8 sRGB, mean of a region) is from ``albedo`` (sRGB 0..1) lit by
    white light: the relative residual of ``seen = k * albedo + s`` (linear light, k, s >= 0:
    diffuse and specular/ambient white), fitted by least squares."""
    y = srgb_to_linear(np.asarray(seen_rgb8, np.float64) / 255.0)
    a = srgb_to_linear(albedo[:3])
    best = np.inf
    for k, s in _fits(a, y):
        best = min(best, float(np.linalg.norm(k * a + s - y)))
    return best / float(np.linalg.norm(y))


def _fits(a, y):
    A = np.c_[a, np.ones(3)]
    k, s = np.linalg.lstsq(A, y, rcond=None)[0]
    yield max(k, 0.0), max(s, 0.0)
    yield max(float(a @ y / (a @ a)), 0.0), 0.0  # s = 0
    yield 0.0, max(float(y.mean()), 0.0)  # k = 0


def chroma(rgb) -> np.ndarray:
    """Chromaticity (r, g, b) / (r + g + b) of colours (..., 3), brightness removed."""
    c = np.asarray(rgb, np.float64)
    return c / np.maximum(c.sum(-1, keepdims=True), 1e-9)


def hue_saturation(rgb):
    """Hue (degrees 0..360) and saturation (0..1) of uint8 colours (..., 3)."""
    c = np.asarray(rgb, np.float64) / 255.0
    mx, mn = c.max(-1), c.min(-1)
    d = np.where(mx > mn, mx - mn, 1.0)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    h = np.where(mx == r, (g - b) / d % 6, np.where(mx == g, (b - r) / d + 2, (r - g) / d + 4)) * 60.0
    s = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-9), 0.0)
    return np.where(mx > mn, h, 0.0), s


def scene_of(folder: Path) -> dict:
    """The scene record (scene.js) of the page written into ``folder``."""
    import json

    text = (Path(folder) / "scene.js").read_text()
    return json.loads(text[text.index("{"):text.rindex("}") + 1])
