#!/usr/bin/env bash
# Set up (first time) and run the main job on the bundled sample scan (TotalSegmentator example):
# inspect the CT and its 41-label organ map, then mesh every organ (smoothed, closed, seams shared,
# decimated to half the faces with the error in mm reported) into ./demo_out/: per-organ STL and
# 3MF, one combined print-ready 3MF, a GLB for web viewers (+ 3 levels of detail), a 3D web page
# (web/index.html, works offline), the Blender scene (.blend) and its
# Cycles render (PNG), report.json and recipe.toml; and the CT's skin and bone (with the ribs:
# only pieces under 100 mm³ are dropped) into ./demo_out/ct/skin.stl and bone.stl.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup_env.sh demo
PY="${ANATOMESH_VENV:-.venv}/bin/python"
OUT="${1:-demo_out}"
"$PY" -m anatomesh.app.cli inspect data/sample/example_ct_sm.nii.gz
"$PY" -m anatomesh.app.cli inspect data/sample/example_seg.nii.gz
"$PY" -m anatomesh.app.cli mesh data/sample/example_seg.nii.gz --out "$OUT" --decimate 0.5 \
  --format stl,3mf,glb,web,blend,png --lod 3 --overwrite
"$PY" -m anatomesh.app.cli mesh data/sample/example_ct_sm.nii.gz --level skin:-500 --level bone:300 \
  --out "$OUT/ct" --format stl --min-component 100 --overwrite
echo "demo output in $OUT/: per-organ STL+3MF, example_seg.3mf (all organs), example_seg.glb (+ _lod0..2),"
echo "web/index.html (double-click it), example_seg.blend + example_seg.png (Cycles), report.json, recipe.toml;"
echo "ct/skin.stl and ct/bone.stl (the CT's isosurfaces at -500 and 300 HU, ribs kept)"
echo "run it again from the recipe: $(dirname "$PY")/anatomesh mesh --recipe $OUT/recipe.toml --overwrite"
