#!/usr/bin/env bash
# Create ./.venv (Python 3.11) and install Anatomesh with its test extras. Idempotent: re-running
# only reinstalls when pyproject.toml changed. Used by tools/demo.sh, tools/test.sh and .ci/run.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${ANATOMESH_VENV:-.venv}"
PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      PY="$cand"; break
    fi
  done
fi
# independent printer toolchain for tests/test_slicers.py (Debian packages; skipped when not root)
if ! command -v admesh >/dev/null 2>&1 || ! command -v prusa-slicer >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends admesh prusa-slicer \
      || echo "warning: could not install admesh/prusa-slicer; tests/test_slicers.py will skip" >&2
  else
    echo "note: admesh/prusa-slicer missing (install as root: apt-get install admesh prusa-slicer); tests/test_slicers.py will skip" >&2
  fi
fi
# DICOM validator for the Encapsulated STL write-back test (tests/core/export/test_dicom_stl.py; skipped when absent)
if ! command -v dciodvfy >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends dicom3tools \
      || (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends dicom3tools) \
      || echo "warning: could not install dicom3tools; the dciodvfy test will skip" >&2
  else
    echo "note: dciodvfy missing (install as root: apt-get install dicom3tools); its test will skip" >&2
  fi
fi
if [ -z "$PY" ]; then
  echo "error: Python 3.11 is needed (bpy 5.0.1 is built for it): sudo apt-get install python3.11 python3.11-venv" >&2
  exit 2
fi
if [ ! -x "$VENV/bin/python" ]; then
  echo "creating $VENV with $PY"
  "$PY" -m venv "$VENV"
fi
stamp="$VENV/.anatomesh-installed"
want="$(cat pyproject.toml | sha1sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  "$VENV/bin/python" -m pip install --quiet -e ".[test]"
  echo "$want" > "$stamp"
fi
