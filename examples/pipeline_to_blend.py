"""The headless pipeline from Python: label map → decimated organs → STL, GLB, .blend and a PNG.

The same job as ``anatomesh mesh --format stl,glb,blend,png``, through the Python API
(:class:`anatomesh.app.flow.run.Recipe` and :func:`~anatomesh.app.flow.run.run`); the .blend is
built by the add-on exactly as its Extract button builds it. Runs with Blender as a Python module
or inside Blender, from a checkout of this repository::

    python examples/pipeline_to_blend.py [options]                    # pip install bpy==5.0.1
    blender -b -P examples/pipeline_to_blend.py -- [options]

Options (defaults in brackets)::

    --input PATH       label map (NIfTI/NRRD/DICOM)  [data/sample/example_seg.nii.gz]
    --labels LIST      all, or names/values: liver,spleen,5  [all]
    --decimate RATIO   fraction of the faces kept  [0.5]
    --out DIR          output folder  [demo_out/pipeline]
    --samples N        Cycles samples of the PNG  [32]
    --overwrite        replace existing files
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def parse_args():
    if "--" in sys.argv:  # blender -b -P script.py -- options
        argv = sys.argv[sys.argv.index("--") + 1:]
    elif sys.argv and Path(sys.argv[0]).resolve() == Path(__file__).resolve():
        argv = sys.argv[1:]
    else:
        argv = []
    ap = argparse.ArgumentParser(prog="pipeline_to_blend.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--input", default=str(REPO / "data" / "sample" / "example_seg.nii.gz"))
    ap.add_argument("--labels", default="all")
    ap.add_argument("--decimate", type=float, default=0.5)
    ap.add_argument("--out", default=str(REPO / "demo_out" / "pipeline"))
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--overwrite", action="store_true")
    return ap.parse_args(argv)


def anatomesh_package():
    """``import anatomesh``, from this checkout when it is not installed (e.g. inside Blender)."""
    try:
        import anatomesh
    except ImportError:
        spec = importlib.util.spec_from_file_location("anatomesh", REPO / "__init__.py",
                                                      submodule_search_locations=[str(REPO)])
        anatomesh = importlib.util.module_from_spec(spec)
        sys.modules["anatomesh"] = anatomesh
        spec.loader.exec_module(anatomesh)
    return anatomesh


def main():
    args = parse_args()
    import bpy  # noqa: F401  (first: Blender's libraries load before any other native module)

    anatomesh_package()
    from anatomesh.core.model.errors import AnatomeshError
    from anatomesh.app.flow.run import run
    from anatomesh.app.flow.recipe import Recipe

    labels = "all" if args.labels == "all" else [t.strip() for t in args.labels.split(",") if t.strip()]
    recipe = Recipe(input=args.input, labels=labels, out_dir=args.out, decimate=args.decimate,
                    formats=["stl", "glb", "blend", "png"], render_samples=args.samples,
                    overwrite=args.overwrite)
    try:
        result = run(recipe)
    except AnatomeshError as err:
        sys.exit(f"error: {err}")
    dec = result.report["decimation"]
    print(f"{len(result.surfaces)} surfaces, {dec['faces_before']} -> {dec['faces_after']} faces, "
          f"max error {dec['hausdorff_mm']:.2f} mm; files in {args.out}: "
          + ", ".join(sorted(result.report["files"].values())))


if __name__ == "__main__":
    main()
