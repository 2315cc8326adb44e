"""The generated page in a real browser (Debian's headless Chromium, from file://): first
picture, no errors, no request leaving the folder; pixels where the liver is, hiding and
see-through, distance colours, clipping, picking, scale bar, reset; a two-model page.

Screenshots go to build/web-screenshots/ (README picture, and to look at)."""
import json

import numpy as np
import pytest

from anatomesh.app.flow.recipe import Recipe
from anatomesh.app.flow.run import run
from anatomesh.app.web.page import WebModel, write_page
from anatomesh.app.web.models import mesh_levels
from anatomesh.app.web.pack import display_vertices
from conftest import REPO, SAMPLE
from helpers.browser import Page, chroma, hue_saturation, lit_residual, scene_of

SHOTS = REPO / "build" / "web-screenshots"
LIVER = "liver"


@pytest.fixture(scope="module")
def sample_run(tmp_path_factory):
    """The bundled 41-label sample as `anatomesh mesh --format web --distance-to liver`."""
    out = tmp_path_factory.mktemp("web41")
    res = run(Recipe(input=str(SAMPLE / "example_seg.nii.gz"),
                     label_table=str(SAMPLE / "label_names_total_and_total_mr.json"),
                     out_dir=str(out), formats=["web"], distance_to=LIVER))
    return res, out / "web"


def _liver_mask(page):
    """Pixels that change when the liver is hidden (its visible area), and the two pictures."""
    page.js("document.getElementById('show-distance').click()")  # plain colours
    before = page.pixels()
    page.open_group(LIVER)
    page.page.uncheck(f'input[data-structure="{LIVER}"]')
    hidden = page.pixels()
    return np.abs(before.astype(int) - hidden).max(-1) > 12, before, hidden


def test_page_opens_offline_draws_its_levels_without_errors(page, sample_run, record_property):
    res, folder = sample_run
    api = page.js("({first: anatomesh.firstFrameMs, levels: anatomesh.levels, errors: anatomesh.errors,"
                  " status: document.getElementById('status').textContent})")
    assert api["errors"] == [] and page.errors() == []
    assert api["first"] is not None and api["levels"][-1]["level"] == 1  # the full detail, last
    assert [lv["level"] for lv in api["levels"]] in ([0, 1], [1])  # coarse first unless the full came first
    assert [lv["triangles"] for lv in api["levels"]] == [res.web["levels"][lv["level"]]["triangles"]
                                                         for lv in api["levels"]]
    assert api["status"].startswith("full detail: 132,516 triangles") or "full detail" in api["status"]
    assert all(u.startswith(folder.as_uri()) for u in page.requests), page.requests  # nothing else
    assert {u.rsplit("/", 1)[1] for u in page.requests} >= {"index.html", "scene.js", "viewer.js",
                                                            "lod1.js", "lod0.js"}
    record_property("first_picture_ms", round(api["first"]))
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.page.screenshot(path=str(SHOTS / "sample_distance_to_liver.png"))
    (SHOTS / "timings.json").write_text(json.dumps({"sample_first_picture_ms": api["first"],
                                                    "sample_levels": api["levels"]}))


def test_liver_colour_where_the_liver_is_and_hiding_removes_it(page, sample_run):
    mask, before, hidden = _liver_mask(page)
    box = page.js(f"anatomesh.screenBox('{LIVER}')")
    ys, xs = np.nonzero(mask)
    assert mask.sum() > 3000  # the liver is a large part of the front view
    inside = (xs >= box["x0"] - 1) & (xs <= box["x1"] + 1) & (ys >= box["y0"] - 1) & (ys <= box["y1"] + 1)
    assert inside.mean() > 0.995  # the changed pixels are where the liver projects
    colours = {s["name"]: s["color"] for s in scene_of(sample_run[1])["models"][0]["structures"]}
    mean = before[mask].mean(0)
    fit = {n: lit_residual(mean, c) for n, c in colours.items()}
    assert min(fit, key=fit.get) == LIVER, sorted(fit.items(), key=lambda x: x[1])[:4]
    seen = chroma(mean)
    liver_like = lambda img: (np.abs(chroma(img[mask]) - seen).sum(-1) < 0.03).sum()  # noqa: E731
    assert liver_like(hidden) < 0.05 * liver_like(before)  # its pixels are gone
    page.page.check(f'input[data-structure="{LIVER}"]')
    assert np.abs(page.pixels().astype(int) - before).max() <= 2  # and back


def test_distance_colours_appear_around_the_liver(page):
    on = page.pixels()
    page.js("document.getElementById('show-distance').click()")
    off = page.pixels()
    changed = np.abs(on.astype(int) - off).max(-1) > 12
    h, s = hue_saturation(on[changed])
    bands = {"red": ((h < 8) | (h > 352)) & (s > 0.75), "yellow": (h > 44) & (h < 60) & (s > 0.75),
             "green": (h > 115) & (h < 140) & (s > 0.6)}
    counts = {k: int(v.sum()) for k, v in bands.items()}
    assert all(c > 150 for c in counts.values()), counts
    h0, s0 = hue_saturation(off)
    assert ((h0 > 44) & (h0 < 60) & (s0 > 0.75)).sum() < 0.2 * counts["yellow"]  # not there without


def test_click_names_the_structure_with_its_volume(page, sample_run):
    mask, _, _ = _liver_mask(page)
    page.page.check(f'input[data-structure="{LIVER}"]')
    ys, xs = np.nonzero(mask)
    k = np.argmin((xs - np.median(xs)) ** 2 + (ys - np.median(ys)) ** 2)
    left, top = page.js("(r => [r.left, r.top])(document.getElementById('view').getBoundingClientRect())")
    page.page.mouse.click(left + float(xs[k]) + 0.5, top + float(ys[k]) + 0.5)
    page.page.wait_for_selector("#info:not([hidden])")
    text = page.page.inner_text("#info")
    vol = next(s["volume_mm3"] for s in scene_of(sample_run[1])["models"][0]["structures"] if s["name"] == LIVER)
    assert LIVER in text and f"volume {vol / 1000:.0f} mL" in text, text


def test_opacity_oriented_transparency_and_clipping_change_the_liver(page):
    mask, before, hidden = _liver_mask(page)
    page.page.check(f'input[data-structure="{LIVER}"]')
    page.set_range(f'input[data-opacity="{LIVER}"]', 0.35)
    see = page.pixels()
    d_before = np.abs(see[mask].astype(int) - before[mask]).mean()
    d_hidden = np.abs(see[mask].astype(int) - hidden[mask]).mean()
    assert d_before > 8 and d_hidden > 8  # a blend of the liver and what is behind it
    page.page.check("#oriented")
    oriented = page.pixels()
    assert np.abs(oriented[mask].astype(int) - see[mask]).mean() > 1  # rims more opaque
    page.page.uncheck("#oriented")
    page.set_range(f'input[data-opacity="{LIVER}"]', 1)
    assert np.abs(page.pixels().astype(int) - before).max() <= 2
    page.page.select_option("#clip-axis", "coronal")  # front–back plane through the middle
    cut = page.pixels()
    assert np.abs(cut[mask].astype(int) - before[mask]).max(-1).mean() > 10
    page.set_range("#clip-at", 1.0)  # the plane in front of everything: nothing cut (inner
    changed = np.abs(page.pixels().astype(int) - before).max(-1) > 2  # walls show only edge-on)
    assert changed.mean() < 0.01


def test_scale_bar_measures_the_view(page, sample_run):
    res, _ = sample_run
    liver = next(m for m in res.surfaces if m.name == LIVER)
    d = display_vertices(liver)
    width_mm = d[:, 0].max() - d[:, 0].min()
    box = page.js(f"anatomesh.screenBox('{LIVER}')")
    px_per_mm = (box["x1"] - box["x0"]) / width_mm
    bar = page.js("[document.getElementById('scale-bar').getBoundingClientRect().width,"
                  " document.getElementById('scale-label').textContent]")
    mm = float(bar[1].split()[0])
    assert bar[0] / mm == pytest.approx(px_per_mm, rel=0.01), (bar, px_per_mm)
    assert 40 <= bar[0] <= 110 and mm in (10, 20, 50, 100, 200)


def test_rotate_then_reset_gives_the_first_view_back(page):
    first = page.pixels()
    page.page.mouse.move(640, 300)
    page.page.mouse.down()
    page.page.mouse.move(760, 360, steps=5)
    page.page.mouse.up()
    assert np.abs(page.pixels().astype(int) - first).max(-1).mean() > 5
    page.page.click("#reset")
    assert np.abs(page.pixels().astype(int) - first).max() <= 2


def test_a_page_of_two_variants_switches_models(chromium, sample_run, tmp_path):
    res, _ = sample_run
    full = [m for m in res.surfaces]
    levels = mesh_levels(full, 2)
    without = [[m for m in lv if m.name != LIVER] for lv in levels]
    s = write_page([WebModel("all", levels), WebModel("resected", without)], tmp_path, title="variants")
    assert s["stored_surfaces"] == len(full)  # the second model stores nothing new
    p = Page(chromium, tmp_path)
    try:
        assert p.errors() == [] and p.js("document.getElementById('model').hidden") is False
        a = p.pixels()
        assert p.js(f"!!document.querySelector('input[data-structure=\"{LIVER}\"]')")
        p.page.select_option("#model", "1")
        b = p.pixels()
        assert not p.js(f"!!document.querySelector('input[data-structure=\"{LIVER}\"]')")
        assert np.abs(a.astype(int) - b).max(-1).mean() > 2
        p.page.screenshot(path=str(SHOTS / "variants.png"))
    finally:
        p.page.close()


def test_the_same_page_works_from_a_static_server(chromium, sample_run):
    """Served over HTTP on the loopback address (python's http.server): same page, same levels."""
    import functools
    import http.server
    import threading

    folder = sample_run[1]
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(folder))
    handler.log_message = lambda *a, **k: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/"
        page = chromium.new_page(viewport={"width": 900, "height": 560})
        requests, errors = [], []
        page.on("request", lambda r: requests.append(r.url))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.goto(url + "index.html")
        page.wait_for_function("window.anatomesh && window.anatomesh.done === true", timeout=90000)
        assert errors == [] and page.evaluate("anatomesh.errors") == []
        assert page.evaluate("anatomesh.levels.map(lv => lv.level)") in ([0, 1], [1])
        assert requests and all(u.startswith(url) for u in requests), requests
        page.close()
    finally:
        server.shutdown()
        server.server_close()
