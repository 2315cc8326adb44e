"""Benchmark: every real input in ../shared/data through the whole `anatomesh mesh` command, each
written mesh file read back by tools nobody here wrote.

For each input of :data:`INPUTS` (every DICOM SEG object and RTSTRUCT, every label map, every mask
folder, the head CT at two levels), one fresh process runs the user's command with default
settings::

    python -m anatomesh.app.cli mesh INPUT [ARGS] --out TMP --format stl,ply,obj,3mf,glb[,dicom]

(``dicom`` for the DICOM inputs: one Encapsulated STL object per surface in the source's study),
then every mesh file it wrote is read back:

* trimesh (``process=True``, then vertices merged by position only, ignoring normals and UVs, as
  STL readers and slicers join them) for every format: the per-surface STL/PLY/OBJ/3MF, the
  combined 3MF and GLB (one scene geometry per surface, matched by name), and the STL payload of
  each DICOM Encapsulated STL object (extracted with pydicom);
* Debian's ``admesh`` for every STL.

Columns (one row per input):

* ``surf``: surfaces in the report;
* ``manifold`` / ``closed``: reads that are 2-manifold (every edge in exactly <= 2 faces and every
  vertex's faces one fan) / closed (every edge in >= 2 faces), ``n/N``. N counts one read per
  surface per file: a combined GLB or 3MF of 41 surfaces is 41 reads;
* ``comp==rep``: reads whose face-connected components equal the report's ``components``;
* ``admesh``: STLs where admesh finds 0 degenerate facets, 0 backwards edges, 0 disconnected
  facets and as many parts as the report's ``components``;
* ``specks``: components under 10 % of one voxel's volume, over all default STLs (trimesh
  ``split()`` of each STL as read back, ``abs(volume)``);
* ``volume``: a second, raw run (``--smooth none --format stl``): surfaces whose STL volume (trimesh)
  is within :func:`helpers.readback.pinch_volume_bound` of the label's voxels x voxel volume
  (``input.labels`` of its report), plus the rounding of the report's spacing to 6 decimals
  (``V * sum(5e-7 / spacing)``: 0.9765625 mm is reported as 0.976562, 1e-6 of the volume);
  ``n/a`` for isosurfaces of a scan;
* ``pinch``: the run's ``pinch_points.points`` (default run's report);
* ``mesh s``: wall time of the default ``anatomesh mesh`` process; ``row s``: the whole row (both
  runs and all reading back).

Failures are listed under the table (``details``), at most 6 per input. After it, ``anatomesh
check`` runs on the default STLs of :data:`CHECKED` and its loose shells (parts' ``tiny_shells``)
and components are printed against the mesh report's components. Nothing is asserted: the
bench prints facts.

Run::

    python benchmarks/bench_corpus.py            # the whole corpus
    python benchmarks/bench_corpus.py --quick    # 3 inputs
    python benchmarks/bench_corpus.py --out DIR  # keep the outputs in DIR/<input>/{default,raw}

Needs trimesh with lxml (3MF) and networkx, pydicom, and admesh (``apt-get install admesh``).
Timings are noisy on a shared 2-core machine.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", REPO.parent / "shared" / "data"))
sys.path.insert(0, str(REPO / "tests"))
from helpers.readback import mesh_facts, read_back  # noqa: E402  (tests/ on the path)

FORMATS = "stl,ply,obj,3mf,glb"

#: (name, path under shared/data, extra CLI args, DICOM source with a study: also write ``dicom``)
INPUTS = [
    # label maps
    ("labels41 NIfTI", "totalsegmentator/example_seg.nii.gz", [], False),
    ("labels61 NIfTI", "totalsegmentator/example_seg_fast_force_split.nii.gz", [], False),
    ("labels23 MR NIfTI", "totalsegmentator/example_seg_mr.nii.gz", [], False),
    ("labels31 DICOM-grid NIfTI", "totalsegmentator/example_seg_dicom.nii.gz", [], False),
    ("labels40 fast NIfTI", "totalsegmentator/fast_folder/example_seg_fast.nii.gz", [], False),
    ("brain1 tumour NRRD", "pyradiomics_brain1/brain1_label.nrrd", [], False),
    ("dcmqi liver_seg NRRD", "dicom_seg/dcmqi_ct3slice/labelmaps/liver_seg.nrrd", [], False),
    ("dcmqi overlaps-1 NRRD", "dicom_seg/dcmqi_ct3slice/labelmaps/partial_overlaps-1.nrrd", [], False),
    ("dcmqi overlaps-2 NRRD", "dicom_seg/dcmqi_ct3slice/labelmaps/partial_overlaps-2.nrrd", [], False),
    ("dcmqi overlaps-3 NRRD", "dicom_seg/dcmqi_ct3slice/labelmaps/partial_overlaps-3.nrrd", [], False),
    ("sparse labelmap NRRD", "dicom_seg/synthetic_tiny/24x38x3/sparse_labelmap_noppv_seg.nrrd", [], False),
    # mask folders
    ("masks fast (119, 79 empty)", "totalsegmentator/fast_folder/example_seg_fast", [], False),
    ("masks tissue types", "totalsegmentator/fast_folder/example_seg_tissue_types", [], False),
    ("masks aorta", "totalsegmentator/aorta", [], False),
    ("masks pulmonary (2 grids)", "totalsegmentator/pulmonary", [], False),
    # DICOM SEG objects (`anatomesh inspect FOLDER` lists them; --series picks one). highdicom_ct2
    # holds two studies: `--series N` on that folder is refused ("mixes 2 unrelated studies"),
    # so its SEGs are given as files
    ("SEG dcmqi liver", "dicom_seg/dcmqi_ct3slice", ["--series", "2"], True),
    ("SEG dcmqi partial_overlaps", "dicom_seg/dcmqi_ct3slice", ["--series", "3"], True),
    ("SEG dcmqi liver_j2k", "dicom_seg/dcmqi_ct3slice", ["--series", "4"], True),
    ("SEG dcmqi liver_nonbyte", "dicom_seg/dcmqi_ct3slice", ["--series", "5"], True),
    ("SEG highdicom binary", "dicom_seg/highdicom_ct2/seg_image_ct_binary.dcm", [], True),
    ("SEG highdicom fractional", "dicom_seg/highdicom_ct2/seg_image_ct_binary_fractional.dcm", [], True),
    ("SEG highdicom overlap", "dicom_seg/highdicom_ct2/seg_image_ct_binary_overlap.dcm", [], True),
    ("SEG highdicom true_fract", "dicom_seg/highdicom_ct2/seg_image_ct_true_fractional.dcm", [], True),
    ("SEG highdicom single_frame", "dicom_seg/highdicom_ct2/single_frame/seg_image_ct_binary_single_frame.dcm", [],
     True),
    ("SEG tiny 23x38x3", "dicom_seg/synthetic_tiny/23x38x3", [], True),
    ("SEG tiny 24x38x3", "dicom_seg/synthetic_tiny/24x38x3", ["--series", "2"], True),
    ("SEG tiny labelmap SOP", "dicom_seg/synthetic_tiny/24x38x3", ["--series", "3"], True),
    # RTSTRUCT objects
    ("RT sts_001", "rtstruct/sts_001", [], True),
    ("RT dicompyler breast", "rtstruct/dicompyler_breast", [], True),
    ("RT rtutils phantom", "rtstruct/rtutils_phantom", [], True),
    ("RT eclipse prostate (no CT)", "rtstruct/eclipse_prostate_no_ct/RS_eclipse_prostate.dcm", [], True),
    # scans
    ("head CT level 500", "slicer_ctheadaxial", ["--level", "500"], True),
    ("head CT level 1150", "slicer_ctheadaxial", ["--level", "1150"], True),
]
QUICK = ("labels41 NIfTI", "SEG dcmqi liver", "RT sts_001")
#: inputs whose default STLs `anatomesh check` reads
CHECKED = ("SEG dcmqi liver", "RT sts_001")
SPECK = 0.10  # of one voxel's volume


def cli(*args):
    return [sys.executable, "-m", "anatomesh.app.cli", *map(str, args)]


def mesh_command(path, extra, out, formats):
    t0 = time.perf_counter()
    p = subprocess.run(cli("mesh", path, *extra, "--out", out, "--format", formats, "--overwrite"),
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    rep = None
    if (Path(out) / "report.json").is_file():
        rep = json.loads((Path(out) / "report.json").read_text())
    return p.returncode, wall, rep, p.stderr


# reading back -------------------------------------------------------------------------------

def admesh_facts(path):
    """admesh's reading of an STL: parts, disconnected, degenerate facets, backwards edges.
    (``helpers.readback.admesh_facts`` decodes admesh's output strictly as UTF-8 and fails on the
    80-byte STL header admesh echoes with stray bytes; this one replaces them.)"""
    out = subprocess.run(["admesh", str(path)], capture_output=True, text=True, errors="replace",
                         timeout=300).stdout

    def number(label):
        m = re.search(re.escape(label) + r"\s*:\s*(\d+)", out)
        return int(m.group(1)) if m else -1
    return {"parts": number("Number of parts"), "disconnected": number("Total disconnected facets"),
            "degenerate": number("Degenerate facets"), "backwards": number("Backwards edges")}


def admesh_ok(path, components):
    a = admesh_facts(path)
    ok = a["degenerate"] == 0 and a["backwards"] == 0 and a["disconnected"] == 0 and a["parts"] == components
    return ok, a


def component_volumes(mesh):
    """abs(volume) of each component of a mesh as read back (trimesh ``split()``)."""
    return [abs(float(c.volume)) for c in mesh.split(only_watertight=False)]


# one input ----------------------------------------------------------------------------------

def bench_input(name, rel, extra, dicom, out_root):
    from helpers.readback import pinch_volume_bound

    t_row = time.perf_counter()
    path = DATA / rel
    slug = re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")
    out = Path(out_root) / slug
    formats = FORMATS + (",dicom" if dicom else "")
    row = {"name": name, "details": []}
    det = row["details"]
    rc, wall, rep, err = mesh_command(path, extra, out / "default", formats)
    row["mesh_s"] = wall
    if rep is None or rc not in (0, 1):
        row["error"] = f"mesh exit {rc}: {err.strip().splitlines()[-1] if err.strip() else ''}"
        row["row_s"] = time.perf_counter() - t_row
        return row
    surfaces = rep["surfaces"]
    row["surfaces"] = len(surfaces)
    row["pinch"] = rep.get("pinch_points", {}).get("points", 0)
    sp = rep["input"]["spacing"]
    voxel = float(np.prod(sp))
    reads = man = clo = comp_ok = 0
    stl_n = stl_ok = 0
    specks = 0
    d = out / "default"
    # per-surface files
    for s in surfaces:
        for fmt, fn in s["files"].items():
            read = read_back(d / fn, fmt)
            for gname, m in read.items():
                c, mf, k = mesh_facts(m)
                reads += 1
                clo += c
                man += mf
                comp_ok += k == s["components"]
                if not (c and mf and k == s["components"]):
                    det.append(f"{fn}: closed {c}, manifold {mf}, components {k} (report {s['components']})")
            if fmt == "stl":
                ok, a = admesh_ok(d / fn, s["components"])
                stl_n += 1
                stl_ok += ok
                if not ok:
                    det.append(f"admesh {fn}: {a} (report components {s['components']})")
                vols = component_volumes(read[""])
                small = [v for v in vols if v < SPECK * voxel]
                specks += len(small)
                if small:
                    det.append(f"specks in {fn}: {len(small)} of {len(vols)} components, smallest "
                               f"{min(small):.4g} mm3 (voxel {voxel:.4g} mm3)")
    # combined files: one geometry per surface
    by_name = {s["name"]: s for s in surfaces}
    for fmt in ("3mf", "glb"):
        fn = rep["files"].get(fmt)
        if not fn:
            continue
        geoms = read_back(d / fn, fmt)
        names = list(geoms)
        if len(geoms) != len(surfaces):
            det.append(f"{fn}: {len(geoms)} geometries for {len(surfaces)} surfaces")
        for i, (gname, m) in enumerate(geoms.items()):
            s = by_name.get(gname) or (surfaces[i] if i < len(surfaces) else None)
            c, mf, k = mesh_facts(m)
            reads += 1
            clo += c
            man += mf
            want = s["components"] if s else None
            comp_ok += k == want
            if not (c and mf and k == want):
                det.append(f"{fn}[{names[i]}]: closed {c}, manifold {mf}, components {k} (report {want})")
    row.update(reads=reads, manifold=man, closed=clo, comp_ok=comp_ok, stl_n=stl_n, stl_ok=stl_ok,
               specks=specks, report=rep, out=d)
    # raw run: the volume check
    if rep["input"].get("labels") and "--level" not in extra:
        rc2, _, raw, err2 = mesh_command(path, [*extra, "--smooth", "none"], out / "raw", "stl")
        raw_ok = raw_n = 0
        if raw is None or rc2 not in (0, 1):
            det.append(f"raw run failed ({rc2}): {err2.strip()[-300:]}")
        else:
            rvox = float(np.prod(raw["input"]["spacing"]))
            voxels = {lab["value"]: lab["voxels"] for lab in raw["input"]["labels"]}
            for s in raw["surfaces"]:
                import trimesh

                vf = float(trimesh.load(str(out / "raw" / s["files"]["stl"]), force="mesh", process=True).volume)
                want = voxels.get(s["value"], 0) * rvox
                # + the rounding of the report's spacing (6 decimals: 0.9765625 is written 0.976562)
                bound = pinch_volume_bound(s["pinch_points"], want, rvox) + want * sum(
                    5e-7 / x for x in raw["input"]["spacing"])
                raw_n += 1
                ok = abs(vf - want) <= bound
                raw_ok += ok
                if not ok:
                    det.append(f"raw volume {s['name']}: file {vf:.3f} mm3, voxels {want:.3f} mm3, "
                               f"|diff| {abs(vf - want):.4g} > bound {bound:.4g} "
                               f"(pinch points {s['pinch_points']})")
        row["volume"] = f"{raw_ok}/{raw_n}"
    else:
        row["volume"] = "n/a"
    row["row_s"] = time.perf_counter() - t_row
    return row


def run_check(row):
    """`anatomesh check` on the default STLs: loose shells and components vs the mesh report."""
    rep = row["report"]
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        p = subprocess.run(cli("check", row["out"], "--report", Path(tmp) / "check.json"),
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if not (Path(tmp) / "check.json").is_file():
            return f"{row['name']}: check exit {p.returncode}: {p.stderr.strip()[-300:]}"
        chk = json.loads((Path(tmp) / "check.json").read_text())
    loose = sum(len(part.get("tiny_shells", [])) for part in chk["parts"])
    comps = sum(part.get("components", 0) for part in chk["parts"])
    rcomps = sum(s["components"] for s in rep["surfaces"])
    per = {part["name"]: part.get("components") for part in chk["parts"]}
    differ = [f"{s['name']} check {per.get(s['name'])} vs report {s['components']}"
              for s in rep["surfaces"] if per.get(s["name"]) != s["components"]]
    text = (f"{row['name']:<30} check exit {p.returncode}, {len(chk['parts'])} parts: loose shells "
            f"(< {chk['profile']['min_shell_mm3']:g} mm3) {loose}, components {comps}; report components "
            f"{rcomps} over {len(rep['surfaces'])} surfaces; {wall:.1f} s")
    if differ:
        text += "\n    differ: " + "; ".join(differ[:6])
    return text


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK)}")
    ap.add_argument("--out", help="keep the outputs here (DIR/<input>/{default,raw})")
    args = ap.parse_args(argv)
    import warnings

    warnings.simplefilter("ignore")
    assert shutil.which("admesh"), "admesh is not installed (apt-get install admesh)"
    inputs = [i for i in INPUTS if not args.quick or i[0] in QUICK]
    tmp = None
    if args.out:
        root = Path(args.out)
        root.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="bench_corpus_")
        root = Path(tmp.name)
    # warm the kernel cache (first run of a fresh checkout compiles them), untimed
    subprocess.run(cli("mesh", DATA / "dicom_seg/dcmqi_ct3slice/labelmaps/partial_overlaps-2.nrrd",
                       "--out", root / "_warm", "--overwrite"), capture_output=True)
    print(f"data {DATA}; formats {FORMATS} (+dicom for DICOM inputs); trimesh by position, admesh on STL")
    head = (f"{'input':<30} | {'surf':>4} | {'manifold':>9} | {'closed':>9} | {'comp==rep':>9} | "
            f"{'admesh':>7} | {'specks':>6} | {'volume':>7} | {'pinch':>5} | {'mesh s':>6} | {'row s':>6}")
    print(head)
    print("-" * len(head))
    rows = []
    for name, rel, extra, dicom in inputs:
        row = bench_input(name, rel, extra, dicom, root)
        rows.append(row)
        if "error" in row:
            print(f"{name:<30} | {row['error']}  ({row['row_s']:.1f} s)", flush=True)
            continue
        print(f"{name:<30} | {row['surfaces']:>4} | {row['manifold']:>4}/{row['reads']:<4} | "
              f"{row['closed']:>4}/{row['reads']:<4} | {row['comp_ok']:>4}/{row['reads']:<4} | "
              f"{row['stl_ok']:>3}/{row['stl_n']:<3} | {row['specks']:>6} | {row['volume']:>7} | "
              f"{row['pinch']:>5} | {row['mesh_s']:>6.1f} | {row['row_s']:>6.1f}", flush=True)
    ok = [r for r in rows if "error" not in r]
    vol = [tuple(map(int, r["volume"].split("/"))) for r in ok if r["volume"] != "n/a"]
    print("-" * len(head))
    print(f"{'total (' + str(len(ok)) + ' of ' + str(len(rows)) + ' ran)':<30} | "
          f"{sum(r['surfaces'] for r in ok):>4} | "
          f"{sum(r['manifold'] for r in ok):>4}/{sum(r['reads'] for r in ok):<4} | "
          f"{sum(r['closed'] for r in ok):>4}/{sum(r['reads'] for r in ok):<4} | "
          f"{sum(r['comp_ok'] for r in ok):>4}/{sum(r['reads'] for r in ok):<4} | "
          f"{sum(r['stl_ok'] for r in ok):>3}/{sum(r['stl_n'] for r in ok):<3} | "
          f"{sum(r['specks'] for r in ok):>6} | "
          f"{str(sum(v[0] for v in vol)) + '/' + str(sum(v[1] for v in vol)):>7} | "
          f"{sum(r['pinch'] for r in ok):>5} | {sum(r['mesh_s'] for r in rows):>6.1f} | "
          f"{sum(r['row_s'] for r in rows):>6.1f}")
    print("\ndetails (at most 6 per input):")
    any_detail = False
    for r in rows:
        for line in r["details"][:6]:
            print(f"  {r['name']}: {line}")
            any_detail = True
        if len(r["details"]) > 6:
            print(f"  {r['name']}: ... {len(r['details']) - 6} more")
    if not any_detail:
        print("  none")
    print("\nanatomesh check on the default STLs:")
    for r in rows:
        if r["name"] in CHECKED and "error" not in r:
            print("  " + run_check(r), flush=True)
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
