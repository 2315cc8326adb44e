"""Benchmark: the web page of the 61-label TotalSegmentator map — size and time to first picture.

Meshes ``example_seg_fast_force_split.nii.gz`` (61 labels, default smoothing) once, then

* writes the page (``app.web.write_page``, 2 levels, distance colours to the liver and without),
  and reports bytes and triangles per level, the viewer's bytes and the folder's total, next to
  the plain GLB of the same surfaces and that GLB gzipped (what a web server would send);
* opens the page from ``file://`` in Debian's headless Chromium (Playwright, no download),
  best of N loads: the time from navigation start to the first picture (the coarse level drawn)
  and to the full detail shown. Target: first picture <= 1 s on this machine (2 cores, no GPU:
  WebGL runs on SwiftShader);
* with ``--against DIR ...``: other pages of the same map (say, written by an earlier release)
  loaded in turn with ours, load by load, so that both see the same machine: sizes, medians and
  ratios side by side.

Run: ``python benchmarks/bench_web.py [--runs N] [--out DIR] [--against DIR ...]`` (needs
../shared/data).
"""
from __future__ import annotations

import argparse
import gzip
import os
import statistics
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


def first_pictures(folders, runs: int):
    """{folder: [(first picture, full detail shown, load event) ms per load]}, the folders loaded
    in turn, ``runs`` times each."""
    from playwright.sync_api import sync_playwright

    out = {f: [] for f in folders}
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=os.environ.get("ANATOMESH_CHROMIUM", "/usr/bin/chromium"),
                              args=FLAGS)
        for _ in range(runs):
            for folder in folders:
                page = b.new_page(viewport={"width": 1100, "height": 700})
                page.goto((Path(folder) / "index.html").as_uri())
                page.wait_for_function("window.anatomesh && window.anatomesh.done === true", timeout=120000)
                page.wait_for_load_state("load")
                out[folder].append(page.evaluate(
                    "[anatomesh.firstFrameMs, anatomesh.levels[anatomesh.levels.length - 1].ms,"
                    " performance.getEntriesByType('navigation')[0].loadEventStart]"))
                page.close()
        b.close()
    return out


def compare(ours: Path, others, runs: int) -> None:
    """Our page and others loaded in turn: bytes, medians (ms) and their ratios to ours."""
    times = first_pictures([ours, *others], runs)
    size = {f: sum(p.stat().st_size for p in Path(f).rglob("*") if p.is_file()) for f in times}
    print(f"\nside by side, {runs} loads each in turn (medians; ratio to ours):")
    print(f"  {'page':40s} {'MB':>6s} {'first ms':>9s} {'full ms':>8s} {'load ms':>8s}")
    for f, t in times.items():
        cols = [statistics.median(x[j] for x in t) for j in range(3)]
        ref = [statistics.median(x[j] for x in times[ours]) for j in range(3)]
        print(f"  {str(f)[-40:]:40s} {size[f] / 1e6:6.3f} " + " ".join(
            f"{c:5.0f} ({c / r:4.2f})" for c, r in zip(cols, ref)) + f"  size ({size[f] / size[ours]:4.2f})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default=None)
    ap.add_argument("--against", nargs="+", default=[], metavar="DIR",
                    help="other pages of the 61-label map, loaded in turn with ours")
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
        times = first_pictures([folder], args.runs)[folder]
        first = sorted(x[0] for x in times)
        print(f"  first picture from file://: best {first[0]:.0f} ms, median {first[len(first) // 2]:.0f} ms "
              f"(target <= 1000 ms); full detail shown: best {min(x[1] for x in times):.0f} ms "
              f"[{args.runs} loads]")
    if args.against:
        compare(out / "page", args.against, args.runs)


if __name__ == "__main__":
    main()
