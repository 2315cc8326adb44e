"""The README's pictures of the 3D page: a capped cut, a saved view and a measurement.

Meshes the 61-label TotalSegmentator map with the example saved views, opens the page from
``file://`` in Debian's headless Chromium (the tests' browser helper) and writes
``docs/images/web_cut_caps.png``, ``web_shared_view.png`` and ``web_measure.png``::

    .venv/bin/python tools/web_screenshots.py [--out docs/images]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from conftest import shared  # noqa: E402  (the tests' data paths and browser helper)
from helpers.browser import Page, browser  # noqa: E402

from anatomesh.app.flow.recipe import Recipe  # noqa: E402
from anatomesh.app.flow.run import run  # noqa: E402


def write_page(folder: Path) -> Path:
    """The page of the 61-label map with ``examples/web_views.toml``; its folder."""
    seg = shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")
    names = shared("totalsegmentator", "label_names_total_and_total_mr.json")
    run(Recipe(input=str(seg), label_table=str(names), out_dir=str(folder), formats=["web"],
               web_views=str(REPO / "examples" / "web_views.toml"), overwrite=True))
    return folder / "web"


def go(p: Page, fragment: str) -> None:
    p.js("f => { location.hash = f; }", fragment)
    p.js("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    p.page.wait_for_timeout(300)


def click_on(p: Page, name: str, fx: float, fy: float) -> None:
    """Click at the fractions (fx, fy) of structure ``name``'s box on the canvas."""
    box = p.js(f"anatomesh.screenBox({name!r})")
    left, top = p.js("(r => [r.left, r.top])(document.getElementById('view').getBoundingClientRect())")
    p.page.mouse.click(left + box["x0"] + fx * (box["x1"] - box["x0"]),
                       top + box["y0"] + fy * (box["y1"] - box["y0"]))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "images")
    out = ap.parse_args(argv).out
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp, browser() as b:
        p = Page(b, write_page(Path(tmp)), size=(1100, 640))
        go(p, "clip=coronal:0.55:outline")
        p.page.screenshot(path=str(out / "web_cut_caps.png"))
        p.page.click("text=lungs over the liver")
        p.page.wait_for_timeout(800)
        p.page.screenshot(path=str(out / "web_shared_view.png"))
        p.page.click("#reset")
        go(p, "")
        p.page.check("#measure")
        click_on(p, "liver", 0.25, 0.55)
        click_on(p, "liver", 0.75, 0.35)
        p.page.wait_for_timeout(800)
        p.page.screenshot(path=str(out / "web_measure.png"))
        print(p.page.inner_text("#measure-out"))
        if p.errors():
            raise SystemExit(f"page errors: {p.errors()}")
    print(f"screenshots in {out}")


if __name__ == "__main__":
    main()
