"""Label map → coloured, smoothed organ surfaces in Blender → .blend + a rendered PNG.

Runs inside Blender or with Blender as a Python module, from a checkout of this repository::

    blender -b -P examples/blender_import_labels.py -- [options]
    python examples/blender_import_labels.py [options]          # pip install bpy==5.0.1

What it does, with the add-on's own operators (the same ones the sidebar buttons call):

1. enables the Anatomesh add-on from this checkout (unless an installed copy is enabled);
2. ``anatomesh.import_scan``: reads the label map with its label table (names, colours) and
   extracts it, smoothed with the command line's default (``organ``: Taubin, every vertex kept
   inside its voxel cell, volumes restored, nothing crossing);
3. ``anatomesh.smooth``: the same driver with other settings when ``--iterations`` is given;
4. frames a camera from the patient's front, lights the scene (the ``studio`` preset), saves a
   .blend and renders a PNG with Cycles on the CPU; each structure is drawn as its tissue class
   of the style table, the lungs see-through (opacity + oriented transparency), cut faces marked.

Options (defaults in brackets)::

    --input PATH       label map (NIfTI/NRRD/DICOM)  [data/sample/example_seg.nii.gz]
    --labels PATH      label table (JSON, Slicer .ctbl, ITK-SNAP)  [the sample's JSON]
    --out DIR          where the .blend and .png go  [demo_out/]
    --iterations N     smoothing iterations  [the organ preset's own: 20]
    --space RAS|LPS    coordinates of the vertices  [RAS]
    --samples N        Cycles samples  [32]
    --size W H         image size in pixels  [960 540]
    --elevation DEG    camera above the front view  [30]
    --azimuth DEG      camera turned around the body axis  [-25]
    --no-render        only save the .blend

The sample is TotalSegmentator's 41-label abdomen/thorax example (Apache-2.0, see
data/sample/README.md).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from pathlib import Path

import bpy

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "data" / "sample"


def parse_args():
    if "--" in sys.argv:  # blender -b -P script.py -- options
        argv = sys.argv[sys.argv.index("--") + 1:]
    elif sys.argv and Path(sys.argv[0]).resolve() == Path(__file__).resolve():  # python script.py options
        argv = sys.argv[1:]
    else:  # inside Blender without "--": all arguments are Blender's own
        argv = []
    ap = argparse.ArgumentParser(prog="blender_import_labels.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--input", default=str(SAMPLE / "example_seg.nii.gz"))
    ap.add_argument("--labels", default=str(SAMPLE / "label_names_total_and_total_mr.json"))
    ap.add_argument("--out", default=str(REPO / "demo_out"))
    ap.add_argument("--iterations", type=int, default=0, help="0: the organ preset's own")
    ap.add_argument("--space", choices=("RAS", "LPS"), default="RAS")
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--size", type=int, nargs=2, default=(960, 540), metavar=("W", "H"))
    ap.add_argument("--elevation", type=float, default=30.0, help="camera degrees above the front view")
    ap.add_argument("--azimuth", type=float, default=-25.0, help="camera degrees around the body axis")
    ap.add_argument("--no-render", action="store_true")
    return ap.parse_args(argv)


def enable_addon():
    """Register the add-on from this checkout, unless an installed Anatomesh is enabled already."""
    if hasattr(bpy.types, "ANATOMESH_OT_extract"):
        return
    pkg = sys.modules.get("anatomesh")
    if pkg is None or Path(pkg.__file__).resolve().parent != REPO:
        spec = importlib.util.spec_from_file_location("anatomesh", REPO / "__init__.py",
                                                      submodule_search_locations=[str(REPO)])
        pkg = importlib.util.module_from_spec(spec)
        sys.modules["anatomesh"] = pkg
        spec.loader.exec_module(pkg)
    pkg.register()


def headless():
    """The enabled add-on's ``addon.headless`` module (scene look and the Cycles render)."""
    package = bpy.types.ANATOMESH_OT_extract.__module__.rsplit(".addon.", 1)[0]
    return importlib.import_module(package + ".addon.headless")


def main():
    args = parse_args()
    enable_addon()
    t0 = time.perf_counter()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = args.size
    try:
        bpy.ops.anatomesh.import_scan(filepath=args.input, label_table=args.labels, space=args.space,
                                      extract=True)
        coll = bpy.data.collections[scene.anatomesh.last_collection]
        if args.iterations:
            bpy.ops.anatomesh.smooth(collection=coll.name, smooth_method="ORGAN",
                                     smooth_iterations=args.iterations)
    except RuntimeError as err:  # the add-on reports user errors as RuntimeError("Error: ...")
        sys.exit(str(err))
    print(f"{len(coll.objects)} surfaces in '{coll.name}' ({time.perf_counter() - t0:.1f} s)")
    # a slightly raised, turned view reads better than a flat front view
    bpy.ops.anatomesh.frame_camera(collection=coll.name, elevation=args.elevation, azimuth=args.azimuth)
    look = headless()
    look.setup_look(scene, coll)
    os.makedirs(args.out, exist_ok=True)
    stem = Path(args.input).name.split(".")[0]
    blend = os.path.join(os.path.abspath(args.out), f"{stem}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print(f"saved {blend}")
    if not args.no_render:
        png = os.path.join(os.path.abspath(args.out), f"{stem}.png")
        t1 = time.perf_counter()
        look.render(scene, png, args.samples, args.size)
        print(f"rendered {png} ({time.perf_counter() - t1:.1f} s)")


if __name__ == "__main__":
    main()
