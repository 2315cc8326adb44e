#!/usr/bin/env bash
# Create ./.venv (Python 3.11) and install Anatomesh for the demo or for the tests:
#   bash tools/setup_env.sh demo    Anatomesh and bpy (Blender as a module) only, the default flow's
#                                   kernels compiled; no system packages (tools/demo.sh)
#   bash tools/setup_env.sh tests   (the default) also the test extras, the Debian and npm packages
#                                   the tests use, and every kernel (tools/test.sh, .ci/run)
# Idempotent: re-running only reinstalls when pyproject.toml changed (a tests setup serves the demo).
set -euo pipefail
cd "$(dirname "$0")/.."
MODE="${1:-tests}"
case "$MODE" in demo|tests) ;; *) echo "usage: bash tools/setup_env.sh [demo|tests]" >&2; exit 2 ;; esac
VENV="${ANATOMESH_VENV:-.venv}"
PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      PY="$cand"; break
    fi
  done
fi
if [ -z "$PY" ]; then
  echo "error: Python 3.11 is needed (bpy 5.0.1 is built for it): sudo apt-get install python3.11 python3.11-venv" >&2
  exit 2
fi
# Debian packages the tests use: the printer toolchain (admesh, prusa-slicer: tests/core/printing/
# test_slicers.py), the DICOM validator (dicom3tools: the Encapsulated STL test), Debian's chromium
# driven by Playwright for the web page tests (no browser is downloaded) and node/npm for the
# viewer's packages. Installed as root in one apt run; elsewhere a note says what is missing.
if [ "$MODE" = tests ]; then
  need=""
  for pair in admesh:admesh prusa-slicer:prusa-slicer dciodvfy:dicom3tools chromium:chromium npm:"nodejs npm"; do
    command -v "${pair%%:*}" >/dev/null 2>&1 || need="$need ${pair#*:}"
  done
  if [ -n "$need" ]; then
    if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
      mkdir -p build
      echo "installing Debian packages for the tests:$need (log: build/apt-get.log)"
      { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $need; } \
        > build/apt-get.log 2>&1 \
        || echo "warning: could not install$need (build/apt-get.log); the tests that need them will fail" >&2
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
fi
if [ ! -x "$VENV/bin/python" ]; then
  echo "creating $VENV with $PY"
  "$PY" -m venv "$VENV"
fi
stamp="$VENV/.anatomesh-installed"
want="$(cat pyproject.toml | sha1sum | cut -d' ' -f1)"
have="$(cat "$stamp" 2>/dev/null || true)"
if [ "$have" != "$want tests" ] && [ "$have" != "$want $MODE" ]; then
  if [ "$MODE" = demo ]; then
    echo "installing Anatomesh and bpy (Blender as a Python module, ~370 MB) into $VENV"
    extras="blender"
  else
    echo "installing Anatomesh with its test extras (pytest, bpy, pymeshlab, dask, playwright, trimesh) into $VENV"
    extras="test"
  fi
  # pip's and the build backend's notes go to a log, shown only when the install fails
  mkdir -p build
  log="build/pip-install-$(basename "$VENV").log"
  { "$VENV/bin/python" -m pip install --quiet --upgrade pip \
      && "$VENV/bin/python" -m pip install --quiet -e ".[$extras]"; } > "$log" 2>&1 \
    || { cat "$log" >&2; echo "error: pip install failed (log: $log)" >&2; exit 1; }
  echo "$want $MODE" > "$stamp"
fi
# our own modules' bytecode, written once: with PYTHONDONTWRITEBYTECODE set (as on CI machines)
# every process would otherwise compile ~250 modules again (~0.2 s per command)
"$VENV/bin/python" -m compileall -q core app addon >/dev/null || true
# numba's kernels, compiled once into the cache next to the sources (two processes share the
# work; a later setup only checks the cache): the demo's default flow, or every kernel
warm="--quiet"
[ "$MODE" = demo ] && warm="--quiet --default-only" && echo "compiling the default flow's kernels once"
"$VENV/bin/python" -m anatomesh.app.warmup $warm || echo "warning: the kernel warm-up failed; kernels compile on first use" >&2
