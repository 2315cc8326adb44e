"""Benchmark: the web page of the 61-label TotalSegmentator map — size and time to first picture.

Meshes ``example_seg_fast_force_split.nii.gz`` (61 labels, default smoothing) once, then

* writes the page (``app.web.write_page``, 2 levels, distance colours to the liver and without),
  and reports bytes and triangles per level, the viewer's bytes and the folder's total, next to
  the plain GLB of the same surfaces and that GLB gzipped (what a web server would send);
* opens the page from ``file://`` in Debian's headless Chromium (Playwright, no download),
  best of N loads: the time from navigation start to the first picture (the coarse level drawn)
  and to the full detail shown. Target: first picture <= 1 s on this machine (2 cores, no GPU:
  WebGL runs on SwiftShader).

Run: ``python benchmarks/bench_web.py [--runs N] [--out DIR]`` (needs ../shared/data).
"""
from __future__ import annotations

import argparse
import gzip
import os
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
from anatomesh.app.flow import stages  # noqa: E402
from anatomesh.app.flow.recipe import Recipe  # noqa: E402
from anatomesh.app.web.page import WebModel, write_page  # noqa: E402
from anatomesh.app.flow.web_page import set_levels
from anatomesh.app.web.models import color_levels  # noqa: E402
from anatomesh.core.export.gltf import write_glb  # noqa: E402
from anatomesh.core.io import load  # noqa: E402

DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", REPO.parent / "shared" / "data")) / "totalsegmentator"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def surfaces():
    r = Recipe(input=str(DATA / "example_seg_fast_force_split.nii.gz"),
               label_table=str(DATA / "label_names_total_and_total_mr.json"))
    vol = load(r.input, labels=r.label_table)
    smoothed, _ = stages.smooth(stages.extract(vol, r), r)
    return smoothed, smoothed.shells()


def first_pictures(folder: Path, runs: int):
    from playwright.sync_api import sync_playwright

    out = []
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=os.environ.get("ANATOMESH_CHROMIUM", "/usr/bin/chromium"),
                              args=FLAGS)
        for _ in range(runs):
            page = b.new_page(viewport={"width": 1100, "height": 700})
            page.goto((folder / "index.html").as_uri())
            page.wait_for_function("window.anatomesh && window.anatomesh.done === true", timeout=120000)
            out.append(page.evaluate("[anatomesh.firstFrameMs, anatomesh.levels[anatomesh.levels.length - 1].ms]"))
            page.close()
        b.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    out = Path(args.out or tempfile.mkdtemp(prefix="anatomesh_bench_web_"))
    t = time.perf_counter()
    sset, full = surfaces()
    print(f"meshed 61 labels: {sum(m.n_faces for m in full):,} triangles in {time.perf_counter() - t:.1f} s")
    glb = write_glb(full, out / "all.glb")
    raw = glb.stat().st_size
    print(f"plain GLB {raw / 1e6:.2f} MB, gzipped {len(gzip.compress(glb.read_bytes(), 9)) / 1e6:.2f} MB")
    for colour in (False, True):
        t = time.perf_counter()
        levels = set_levels(sset, [m for m in sset.shells()], 2)
        dist = color_levels(levels, "liver", (2, 5, 10)) if colour else None
        t_levels = time.perf_counter() - t
        t = time.perf_counter()
        folder = out / ("page_distance" if colour else "page")
        s = write_page([WebModel("61 labels", levels, dist)], folder, overwrite=True)
        t_write = time.perf_counter() - t
        print(f"\npage {'with distance colours' if colour else 'plain'}: {s['total_bytes'] / 1e6:.3f} MB in all "
              f"(viewer {s['viewer_bytes'] / 1e6:.3f} MB); levels+colours {t_levels:.1f} s, encode+write {t_write:.1f} s")
        for lv in s["levels"]:
            print(f"  {lv['file']}: {lv['triangles']:,} triangles, {lv['vertices']:,} vertices, "
                  f"{lv['bytes'] / 1e6:.3f} MB ({8 * lv['bytes'] / lv['triangles']:.1f} bits/triangle)")
        times = first_pictures(folder, args.runs)
        first = sorted(x[0] for x in times)
        print(f"  first picture from file://: best {first[0]:.0f} ms, median {first[len(first) // 2]:.0f} ms "
              f"(target <= 1000 ms); full detail shown: best {min(x[1] for x in times):.0f} ms "
              f"[{args.runs} loads]")


if __name__ == "__main__":
    main()
