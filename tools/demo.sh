#!/usr/bin/env bash
# Set up (first time) and run the main job on the bundled sample scan (TotalSegmentator example):
# inspect the CT and its 41-label organ map, mesh every organ (smoothed, closed, seams shared) and
# the CT's skin and bone into ./demo_out/, then build the Blender scene and render it with Cycles.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup_env.sh
PY="${ANATOMESH_VENV:-.venv}/bin/python"
OUT="${1:-demo_out}"
"$PY" -m anatomesh.core.cli inspect data/sample/example_ct_sm.nii.gz
"$PY" -m anatomesh.core.cli inspect data/sample/example_seg.nii.gz
"$PY" -m anatomesh.core.cli mesh data/sample/example_seg.nii.gz --out "$OUT" --format stl,ply --overwrite
"$PY" -m anatomesh.core.cli mesh data/sample/example_ct_sm.nii.gz --level -500 --level 300 \
  --out "$OUT/ct" --format stl --keep-largest --overwrite
# the same organs in Blender (bpy module): coloured, smoothed live by the add-on, saved and rendered
"$PY" examples/blender_import_labels.py --out "$OUT/blender"
echo "demo output in $OUT/: per-organ STL+PLY and report.json, ct/ (skin and bone), blender/ (.blend + PNG)"
