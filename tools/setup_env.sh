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
# Debian packages the tests use: the printer toolchain (admesh, prusa-slicer: tests/core/printing/
# test_slicers.py), the DICOM validator (dicom3tools: the Encapsulated STL test), Debian's chromium
# driven by Playwright for the web page tests (no browser is downloaded) and node/npm for the
# viewer's packages. Installed as root in one apt run; elsewhere a note says what is missing.
need=""
for pair in admesh:admesh prusa-slicer:prusa-slicer dciodvfy:dicom3tools chromium:chromium npm:"nodejs npm"; do
  command -v "${pair%%:*}" >/dev/null 2>&1 || need="$need ${pair#*:}"
done
if [ -n "$need" ]; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $need \
      || echo "warning: could not install$need; the tests that need them will fail or skip" >&2
  else
    echo "note:$need missing (install as root: apt-get install$need); the tests that need them will fail or skip" >&2
  fi
fi
# the web viewer's packages (web/package-lock.json): its unit tests and the check that
# app/web/viewer/viewer.js is the build of the lockfile
if command -v npm >/dev/null 2>&1; then
  web_stamp="web/node_modules/.anatomesh-lock"
  web_want="$(sha1sum web/package-lock.json | cut -d' ' -f1)"
  if [ ! -f "$web_stamp" ] || [ "$(cat "$web_stamp")" != "$web_want" ]; then
    (cd web && npm ci --no-audit --no-fund --loglevel=error) && echo "$web_want" > "$web_stamp" \
      || echo "warning: npm ci in web/ failed; the viewer's tests will fail" >&2
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
# our own modules' bytecode, written once: with PYTHONDONTWRITEBYTECODE set (as on CI machines)
# every process would otherwise compile ~250 modules again (~0.2 s per command)
"$VENV/bin/python" -m compileall -q core app addon >/dev/null || true
# numba's kernels, compiled once into the cache next to the sources (two processes share the
# work: ~2 min on 2 cores the first time, ~5 s to check later)
"$VENV/bin/python" -m anatomesh.app.warmup --quiet || echo "warning: the kernel warm-up failed; kernels compile on first use" >&2
