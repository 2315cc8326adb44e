#!/usr/bin/env bash
# Set up (first time) and run the test suite. Extra arguments go to pytest.
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
exec "${ANATOMESH_VENV:-.venv}/bin/python" -m pytest "$@"
