"""The 61-label TotalSegmentator map's page: at most 2 MB in all at full detail (with distance
colours), bytes and triangles per level, and its first picture in Chromium from file://.

The time to the first picture is measured and recorded (pytest's ``record_property`` and
build/web-screenshots/sizes_61.json), not asserted: timings are noisy on a shared machine
(benchmarks/bench_web.py measures it best of N)."""
import json

import pytest

from anatomesh.app.flow.recipe import Recipe
from anatomesh.app.flow.run import run
from conftest import REPO, shared
from helpers.browser import Page, browser

SHOTS = REPO / "build" / "web-screenshots"
MB = 1_000_000


@pytest.mark.slow
def test_61_label_page_is_at_most_2_mb_and_shows_progressively(tmp_path, record_property):
    res = run(Recipe(input=str(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz")),
                     label_table=str(shared("totalsegmentator", "label_names_total_and_total_mr.json")),
                     out_dir=str(tmp_path), formats=["web"], distance_to="liver"))
    web = res.web
    folder = tmp_path / "web"
    on_disk = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    assert web["total_bytes"] == on_disk <= 2 * MB
    full, coarse = web["levels"][-1], web["levels"][0]
    assert len(res.surfaces) == web["structures"] == web["stored_surfaces"] == 61
    assert full["triangles"] == sum(m.n_faces for m in res.surfaces) > 380_000  # full detail
    assert coarse["triangles"] < full["triangles"] / 6 and coarse["bytes"] < full["bytes"] / 4
    assert web["quantization_mm"] == 1 / 16
    with browser() as b:
        page = Page(b, folder)
        api = page.js("({first: anatomesh.firstFrameMs, levels: anatomesh.levels})")
        assert page.errors() == [] and [lv["level"] for lv in api["levels"]] in ([0, 1], [1])
        assert all(u.startswith(folder.as_uri()) for u in page.requests)
        SHOTS.mkdir(parents=True, exist_ok=True)
        page.page.set_viewport_size({"width": 1100, "height": 620})
        for name in ("colon", "small_bowel", "stomach", "duodenum"):  # the gut see-through
            page.open_group(name)
            page.set_range(f'input[data-opacity="{name}"]', 0.2)
        page.page.check("#oriented")
        page.page.wait_for_timeout(300)
        assert page.errors() == []
        page.page.screenshot(path=str(SHOTS / "totalsegmentator_61.png"))
    record_property("first_picture_ms", round(api["first"]))
    record_property("total_bytes", on_disk)
    (SHOTS / "sizes_61.json").write_text(json.dumps({
        "total_bytes": on_disk, "viewer_bytes": web["viewer_bytes"], "levels": web["levels"],
        "first_picture_ms": api["first"], "levels_shown_ms": [lv["ms"] for lv in api["levels"]]}, indent=1))
