"""The page's views in a real browser (Debian's headless Chromium, from file://), on the real
maps: capped cuts, shared interfaces drawn once under a see-through organ, the view in the URL
(every key both ways, bookmarks, saved views), measuring (checked against trimesh's exact
point-to-triangle distances), the tooltip following visibility and clipping, and a plain
screenshot showing the full detail.

Screenshots go to build/web-screenshots/ (the README's pictures in docs/images: tools/web_screenshots.py)."""
import subprocess

import numpy as np
import pytest
import trimesh

from anatomesh.app.flow.recipe import Recipe
from anatomesh.app.flow.run import run
from anatomesh.app.web.pack import display_vertices
from anatomesh.app.web.page import WebModel, write_page
from anatomesh.core.model.mesh import Mesh
from conftest import REPO, SAMPLE, shared
from helpers.browser import CHROMIUM, FLAGS, Page, lit_residual, scene_of

SHOTS = REPO / "build" / "web-screenshots"
TABLE = SAMPLE / "label_names_total_and_total_mr.json"
LIVER, LUNG = "liver", "lung_lower_lobe_right"


@pytest.fixture(scope="module")
def sample_run(tmp_path_factory):
    """The bundled 41-label sample as `anatomesh mesh --format web`."""
    out = tmp_path_factory.mktemp("web41")
    res = run(Recipe(input=str(SAMPLE / "example_seg.nii.gz"), label_table=str(TABLE), out_dir=str(out),
                     formats=["web"]))
    return res, out / "web"


def _go(page, fragment):
    """Set the URL's fragment as a user would and wait until the page has drawn it."""
    page.js("f => { location.hash = f; }", fragment)
    page.js("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")


def _wait_hash(page, fragment):
    """Wait until the page has written ``fragment`` into its URL (it writes shortly after a change)."""
    page.page.wait_for_function("h => location.hash === h", arg="#" + fragment, timeout=20000)


def _names(folder):
    return [s["name"] for s in scene_of(folder)["models"][0]["structures"]]


def _page_vertices(folder, mesh):
    """``mesh``'s vertices as the page stores them: display frame, on its quantisation grid (mm)."""
    q = scene_of(folder)["quantization"]
    origin = np.asarray(q["origin"])
    return origin + np.rint((display_vertices(mesh) - origin) / q["step"]) * q["step"]


def _erode(mask, r=2):
    out = mask.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out &= np.roll(np.roll(mask, dy, 0), dx, 1)
    return out


def luminance(rgb):
    return np.asarray(rgb, np.float64) @ [0.2126, 0.7152, 0.0722]


# ---------------------------------------------------------------------------------------------
def test_a_cut_through_the_liver_is_capped_flat_in_its_colour(page, sample_run):
    folder = sample_run[1]
    others = ",".join(n for n in _names(folder) if n != LIVER)
    _go(page, f"hide={others}")
    whole = page.pixels()
    _go(page, f"hide={others}&clip=coronal:0.5")
    cut = page.pixels()
    page.js("n => anatomesh.viewer.items.find(it => it.s.name === n).cap.quad.material.color.setRGB(0, 1, 0)", LIVER)
    marked = page.pixels()
    cap = _erode(np.abs(marked.astype(int) - cut).max(-1) > 30)  # the cap's pixels, edges left out
    assert cap.sum() > 4000  # the liver's section is a large part of the view
    lum = luminance(cut[cap])
    assert lum.std() < 1.0, lum.std()  # a flat face under a directional light: one shade
    colour = next(s["color"] for s in scene_of(folder)["models"][0]["structures"] if s["name"] == LIVER)
    assert lit_residual(cut[cap].mean(0), colour) < 0.03  # the liver's own colour
    skin = _erode(np.abs(whole.astype(int) - [29, 32, 38]).max(-1) > 20)  # the uncut liver's pixels
    assert luminance(whole[skin]).std() > 5 * max(lum.std(), 1)  # (its shell is shaded: the test can tell)


def test_every_cut_structure_gets_a_cap_and_neighbours_meet_on_it(page, sample_run):
    res, folder = sample_run
    _go(page, "clip=coronal:0.5")
    shot = page.pixels()
    box = scene_of(folder)["models"][0]["box"]
    at = box["min"][2] + 0.5 * (box["max"][2] - box["min"][2])
    cut = {m.name for m in res.surfaces if display_vertices(m)[:, 2].min() < at < display_vertices(m)[:, 2].max()}
    capped = set(page.js("anatomesh.viewer.items.filter(it => it.cut).map(it => it.s.name)"))
    assert capped == cut and len(cut) > 15
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.page.screenshot(path=str(SHOTS / "web_cut_caps_41.png"))
    assert shot.std() > 10


def test_outlines_trace_each_cut_structure_on_the_cut(page, sample_run):
    """With outlines, only pixels along the boundaries of the section change, and they darken;
    every cut structure has its outline, and outlines go with the cut."""
    _go(page, "clip=coronal:0.5")
    plain = page.pixels().astype(int)
    _go(page, "clip=coronal:0.5:outline")
    lined = page.pixels().astype(int)
    changed = np.abs(lined - plain).max(-1) > 20
    assert changed.sum() > 2000  # the outlines of some 30 sections
    on_anatomy = changed & (np.abs(plain - [29, 32, 38]).max(-1) > 20)  # (at the silhouette: background)
    assert (luminance(lined[on_anatomy]) < luminance(plain[on_anatomy])).mean() > 0.9
    edge = np.zeros_like(changed)  # where the plain picture changes colour: boundaries
    for axis in (0, 1):
        step = np.abs(np.diff(plain, axis=axis)).max(-1) > 12
        edge[tuple(slice(None, -1) if a == axis else slice(None) for a in (0, 1))] |= step
        edge[tuple(slice(1, None) if a == axis else slice(None) for a in (0, 1))] |= step
    near_edge = ~_erode(~edge, 2)  # within 2 px of a boundary
    assert near_edge[changed].mean() > 0.9
    outlined = page.js("anatomesh.viewer.items.filter(it => it.cut && it.cap.outline.visible"
                       " && it.cap.outline.geometry.getAttribute('position').count > 0).length")
    assert outlined == page.js("anatomesh.viewer.items.filter(it => it.cut).length") > 15
    _go(page, "")
    assert page.js("anatomesh.viewer.items.every(it => !(it.cap && it.cap.outline && it.cap.outline.visible))")


def _shared_faces(a: Mesh, b: Mesh) -> np.ndarray:
    """Mask of ``b``'s triangles that ``a`` has too (the same three vertex positions)."""
    key = lambda m: [tuple(sorted(map(tuple, np.round(m.vertices[f], 6)))) for f in m.faces]  # noqa: E731
    mine = set(key(a))
    return np.array([k in mine for k in key(b)])


@pytest.mark.parametrize("seg", ["sample 41", "totalsegmentator 61"])
def test_a_see_through_lung_over_the_liver_shows_the_interface_once(chromium, tmp_path, seg):
    path = SAMPLE / "example_seg.nii.gz" if seg == "sample 41" else \
        shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")
    res = run(Recipe(input=str(path), label_table=str(TABLE), labels=[LIVER, LUNG], out_dir=str(tmp_path / "run"),
                     formats=["stl"]))
    liver, lung = (next(m for m in res.surfaces if m.name == n) for n in (LIVER, LUNG))
    shared_faces = _shared_faces(liver, lung)
    assert shared_faces.sum() > 200  # the lung's base lies on the liver: one interface, two owners
    once = Mesh(lung.vertices, lung.faces[~shared_faces], name=LUNG, color=lung.color, space=lung.space)
    write_page([WebModel("both", [[liver, lung]])], tmp_path / "a")
    write_page([WebModel("once", [[liver, once]])], tmp_path / "b")
    # look at the interface from the lung's side, along the liver's outward normal there
    d = display_vertices(lung)
    tri = d[lung.faces[shared_faces]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(0)
    n = -n / np.linalg.norm(n)  # the lung's faces there point into the liver
    up = np.cross(n, [1.0, 0, 0])
    c = tri.reshape(-1, 3).mean(0)
    fragment = (f"opacity={LUNG}:0.4&camera={c[0]:.2f},{c[1]:.2f},{c[2]:.2f};{n[0]:.4f},{n[1]:.4f},{n[2]:.4f};"
                f"{up[0]:.4f},{up[1]:.4f},{up[2]:.4f};2")
    pictures = {}
    for name in ("a", "b"):
        p = Page(chromium, tmp_path / name)
        _go(p, fragment)
        # flat shading: removing triangles changes the smooth normals of their neighbours, not
        # what this compares (which faces are drawn)
        p.js("anatomesh.viewer.items.forEach(it => [it.front, it.back].forEach(m => {"
             " m.material.flatShading = true; m.material.needsUpdate = true; }))")
        pictures[name] = p.pixels()
        if name == "a":
            _go(p, fragment.replace(f"opacity={LUNG}:0.4&", f"hide={LUNG}&"))
            no_lung = p.pixels()
            _go(p, fragment)
            p.js("anatomesh.viewer.items.forEach(it => { it.front.material.polygonOffset = false;"
                 " it.back.material.polygonOffset = false; })")  # the interface drawn twice, as before
            pictures["twice"] = p.pixels()
            if seg.endswith("61"):
                SHOTS.mkdir(parents=True, exist_ok=True)
                p.page.screenshot(path=str(SHOTS / "web_lung_over_liver.png"))
        assert p.errors() == []
        p.page.close()
    a, b = pictures["a"].astype(int), pictures["b"]
    lung_seen = np.abs(a - no_lung).max(-1) > 10
    assert lung_seen.mean() > 0.05  # the see-through lung covers the view's middle
    assert (np.abs(a - b).max(-1) > 3).mean() < 0.001  # drawn once: as without the lung's copy
    twice = np.abs(pictures["twice"].astype(int) - b).max(-1) > 3
    assert twice.mean() > 0.01  # (the same scene drawn twice over differs: the test sees it)


# ---------------------------------------------------------------------------------------------
ROUND_TRIPS = [
    "hide=colon,spleen&opacity=liver:0.35,stomach:0.6&clip=axial:0.425:flip&view=left",
    "opacity=lung_lower_lobe_right:0&clip=sagittal:0.3:outline&camera=10.5,140,160.25;0.6,0,0.8;0,1,0;1.75"
    "&measure=-80.5,130,200;-20,140.125,210",
    "view=superior&measure=12,150,180",
]


def _page_state(page):
    return page.js("""() => ({
        hidden: [...document.querySelectorAll('input[data-structure]')].filter(e => !e.checked).map(e => e.dataset.structure),
        opacity: Object.fromEntries([...document.querySelectorAll('input[data-opacity]')].map(e => [e.dataset.opacity, +e.value])),
        clip: [document.getElementById('clip-axis').value, +document.getElementById('clip-at').value,
               document.getElementById('clip-flip').checked, document.getElementById('clip-outline').checked],
        view: document.getElementById('view-name').value,
        camera: anatomesh.viewer.getCamera(), measure: anatomesh.measure.points(), hash: location.hash})""")


@pytest.mark.parametrize("fragment", ROUND_TRIPS)
def test_every_url_key_round_trips(page, fragment):
    before = page.pixels()
    _go(page, fragment)
    st = _page_state(page)
    assert st["hash"] == "#" + fragment and page.js("anatomesh.warnings") == []
    keys = dict(part.split("=", 1) for part in fragment.split("&"))
    assert sorted(st["hidden"]) == sorted(filter(None, keys.get("hide", "").split(",")))
    for item in filter(None, keys.get("opacity", "").split(",")):
        name, a = item.rsplit(":", 1)
        assert st["opacity"][name] == pytest.approx(float(a))
    if "clip" in keys:
        plane, f, *flags = keys["clip"].split(":")
        assert st["clip"] == [plane, pytest.approx(float(f)), "flip" in flags, "outline" in flags]
    assert st["view"] == keys.get("view", "")
    if "camera" in keys:
        t, d, u, z = keys["camera"].split(";")
        cam = st["camera"]
        for got, want in ((cam["target"], t), (cam["dir"], d), (cam["up"], u)):
            assert got == pytest.approx([float(x) for x in want.split(",")], abs=1e-6)
        assert cam["zoom"] == float(z)
    points = [[float(x) for x in p.split(",")] for p in keys.get("measure", "").split(";") if p]
    assert st["measure"] == points
    assert np.abs(page.pixels().astype(int) - before).max(-1).mean() > 2  # the view changed


def test_a_bookmarked_view_opens_as_saved_and_the_ui_writes_the_url(chromium, sample_run):
    folder = sample_run[1]
    fragment = ROUND_TRIPS[0]
    p = chromium.new_page(viewport={"width": 900, "height": 560})
    p.goto((folder / "index.html").as_uri() + "#" + fragment)
    p.wait_for_function("window.anatomesh && window.anatomesh.done === true", timeout=90000)
    p.wait_for_timeout(300)
    assert p.evaluate("location.hash") == "#" + fragment
    assert not p.is_checked('input[data-structure="spleen"]')
    p.close()
    page = Page(chromium, folder)
    try:
        page.open_group(LIVER)
        page.page.uncheck(f'input[data-structure="{LIVER}"]')
        page.set_range('input[data-opacity="stomach"]', 0.5)
        page.page.select_option("#clip-axis", "axial")
        _wait_hash(page, f"hide={LIVER}&opacity=stomach:0.5&clip=axial:0.5")
        page.page.mouse.move(640, 300)
        page.page.mouse.down()
        page.page.mouse.move(700, 330, steps=4)
        page.page.mouse.up()
        page.page.wait_for_function("location.hash.includes('&camera=')", timeout=20000)
        page.page.click("#reset")
        _wait_hash(page, f"hide={LIVER}&opacity=stomach:0.5&clip=axial:0.5")
        page.page.select_option("#view-name", "posterior")
        _wait_hash(page, f"hide={LIVER}&opacity=stomach:0.5&clip=axial:0.5&view=posterior")
    finally:
        page.page.close()


def test_saved_views_are_listed_and_shown_with_a_click(chromium, sample_run, tmp_path):
    res, _ = sample_run
    views = [{"name": "liver alone", "fragment": "hide=spleen,stomach&clip=coronal:0.5"},
             {"name": "from the left", "fragment": "view=left"}]
    write_page([WebModel("m", [res.surfaces])], tmp_path, views=views)
    page = Page(chromium, tmp_path)
    try:
        links = page.js("[...document.querySelectorAll('#saved-views a')].map(a => a.textContent)")
        assert links == ["liver alone", "from the left"]
        page.page.click("text=liver alone")
        _wait_hash(page, views[0]["fragment"])
        page.js("new Promise(r => requestAnimationFrame(r))")
        assert not page.page.is_checked('input[data-structure="spleen"]')
        assert page.js("anatomesh.viewer.items.filter(it => it.cut).length") > 10
    finally:
        page.page.close()


# ---------------------------------------------------------------------------------------------
def test_measured_distances_are_exact(page, sample_run):
    res, folder = sample_run
    meshes = {m.name: m for m in res.surfaces}
    liver = _page_vertices(folder, meshes[LIVER])
    a, b = np.round(liver[liver[:, 0].argmin()], 3), np.round(liver[liver[:, 1].argmax()], 3)
    _go(page, "measure=" + ";".join(",".join(f"{x:.3f}" for x in p) for p in (a, b)))
    report = page.js("anatomesh.measure.report()")
    assert report["distance"] == pytest.approx(float(np.linalg.norm(a - b)), abs=1e-4)
    assert f"A–B: {np.linalg.norm(a - b):.2f} mm" in page.page.inner_text("#measure-out")
    for point, near in zip((a, b), report["near"]):
        assert near["on"]["name"] == LIVER and near["on"]["distance"] < 0.01
        exact = {}
        for name, m in meshes.items():
            if name != LIVER:
                tri = _page_vertices(folder, m)[m.faces]  # every triangle: trimesh's exact closest points
                q = trimesh.triangles.closest_point(tri, np.repeat(point[None], len(tri), 0))
                exact[name] = float(np.linalg.norm(q - point, axis=1).min())
        nearest = min(exact, key=exact.get)
        assert near["other"]["name"] == nearest
        assert near["other"]["distance"] == pytest.approx(exact[nearest], abs=1e-3)


def test_clicks_measure_on_surfaces_and_write_the_url(page):
    box = page.js(f"anatomesh.screenBox('{LIVER}')")
    left, top = page.js("(r => [r.left, r.top])(document.getElementById('view').getBoundingClientRect())")
    page.page.check("#measure")
    xs = [box["x0"] + 0.3 * (box["x1"] - box["x0"]), box["x0"] + 0.6 * (box["x1"] - box["x0"])]
    y = box["y0"] + 0.5 * (box["y1"] - box["y0"])
    for x in xs:
        page.page.mouse.click(left + x, top + y)
    page.page.wait_for_function("location.hash.startsWith('#measure=')", timeout=20000)
    points = page.js("anatomesh.measure.points()")
    assert len(points) == 2 and page.js("location.hash").count(";") == 1
    # orthographic front view: the points lie on the clicked pixels' rays, 1 px = 1 / pxPerMm mm
    px = page.js("anatomesh.viewer.pxPerMm()")
    assert abs(points[1][0] - points[0][0]) == pytest.approx((xs[1] - xs[0]) / px, abs=2 / px)
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.page.screenshot(path=str(SHOTS / "web_measure_41.png"))


# ---------------------------------------------------------------------------------------------
def test_the_tooltip_follows_visibility_and_clipping(page):
    box = page.js(f"anatomesh.screenBox('{LIVER}')")
    left, top = page.js("(r => [r.left, r.top])(document.getElementById('view').getBoundingClientRect())")
    x, y = left + box["x0"] + 0.3 * (box["x1"] - box["x0"]), top + box["y0"] + 0.5 * (box["y1"] - box["y0"])
    info = lambda: page.js("(e => e.hidden ? '' : e.textContent)(document.getElementById('info'))")  # noqa: E731
    page.page.mouse.click(x, y)
    page.page.wait_for_timeout(200)
    assert info().startswith(LIVER)
    page.open_group(LIVER)
    page.page.uncheck(f'input[data-structure="{LIVER}"]')
    assert not info().startswith(LIVER)
    page.page.check(f'input[data-structure="{LIVER}"]')
    assert info().startswith(LIVER)  # the click's place shows it again
    _go(page, "clip=sagittal:0.9:flip")  # keeps only the patient's far left: the liver is cut away
    page.page.wait_for_function(  # within a moment of the cut (the page redraws, then re-picks)
        f"(e => e.hidden || !e.textContent.startsWith('{LIVER}'))(document.getElementById('info'))",
        timeout=5000)
    assert not info().startswith(LIVER)


def test_a_plain_screenshot_shows_the_full_detail(chromium, sample_run, tmp_path):
    res, folder = sample_run
    write_page([WebModel("one level", [res.surfaces])], tmp_path / "one")
    for f in (folder, tmp_path / "one"):  # two levels, one level: drawn before the load event
        p = chromium.new_page(viewport={"width": 900, "height": 560})
        p.goto((f / "index.html").as_uri(), wait_until="load")
        assert p.evaluate("[anatomesh.done, document.documentElement.dataset.anatomesh]") == [True, "full"]
        p.close()
    shot = tmp_path / "plain.png"
    r = subprocess.run([CHROMIUM, *FLAGS, f"--screenshot={shot}", "--window-size=900,560",
                        (folder / "index.html").as_uri()], capture_output=True, text=True, timeout=120)
    assert shot.exists(), r.stderr[-2000:]
    from PIL import Image

    plain = np.asarray(Image.open(shot).convert("RGB"))[:, 290:].astype(int)
    page = Page(chromium, folder)
    try:
        page.page.screenshot(path=str(tmp_path / "done.png"))
        done = np.asarray(Image.open(tmp_path / "done.png").convert("RGB"))[:, 290:]
    finally:
        page.page.close()
    assert plain.shape == done.shape
    assert (np.abs(plain - done).max(-1) > 12).mean() < 0.002  # the full detail, as drawn when done
