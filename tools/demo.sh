#!/usr/bin/env bash
# Set up (first time) and run the main job on the bundled sample scan (TotalSegmentator example):
# inspect the CT and its 41-label organ map, then mesh every organ into ./demo_out/.
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
echo "demo output in $OUT/ (report: $OUT/report.json)"
