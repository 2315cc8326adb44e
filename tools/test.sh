#!/usr/bin/env bash
# Set up (first time) and run the test suite, and beside it its tests without Blender on Python
# 3.13 with NumPy 2 (tools/test_newest_python.sh). Extra arguments go to pytest (chosen tests:
# Python 3.11 only).
set -euo pipefail
cd "$(dirname "$0")/.."
here="$(pwd -P)"
# The tests keep numba's kernels in a cache of their own (tests/addon/conftest.py says why): the
# setup's warm-up fills that one here, and a second warm-up the same kernels under the add-on's
# package name, as the Blender tests import them (without these, pytest compiles them all
# itself, on one core: ~9 min of a fresh machine's run)
export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-$here/build/numba-cache-blender-tests}"
bash tools/setup_env.sh tests
ext="$here/build/blender-test-extensions/anatomesh_dev"
mkdir -p "$ext"
ln -sfn "$here" "$ext/anatomesh"  # as tests/addon/conftest.py links it (a link left by another checkout replaced)
"${ANATOMESH_VENV:-.venv}/bin/python" -m anatomesh.app.warmup --quiet --as bl_ext.anatomesh_dev.anatomesh "$ext" \
  || echo "warning: the add-on's kernel warm-up failed; the Blender tests compile them" >&2
# Tests that need no Blender, again on the newest supported Python with NumPy 2 (its own venv and
# kernel cache; tools/test_newest_python.sh says which), unless the arguments chose tests. It
# runs beside the main suite, at a lower priority (the suite leaves one core mostly idle), and its
# output follows the suite's.
only_flags() {
  for arg in "$@"; do case "$arg" in -q|-v|-x|-ra|--quiet|--verbose|--exitfirst) ;; *) return 1 ;; esac; done
}
newest=""
if only_flags "$@"; then
  mkdir -p build
  nice -n 10 bash tools/test_newest_python.sh "$@" > build/test-newest-python.log 2>&1 &
  newest=$!
fi
status=0
"${ANATOMESH_VENV:-.venv}/bin/python" -m pytest "$@" || status=$?
if [ -n "$newest" ]; then
  wait "$newest" || status=$?
  cat build/test-newest-python.log
fi
exit $status
