#!/usr/bin/env bash
# Tests that need no Blender, again on the newest supported Python (3.13) with NumPy 2: the core's
# reading, extraction, model, geometry, export, decimation and preprocessing, the command line,
# recipes and settings, in a venv of their own (.venv-3.13) with their own numba cache. (Blender as a module exists for Python 3.11 only: tools/test.sh runs everything
# there first.) Extra arguments go to pytest. Skipped with a note where no Python 3.13 is found
# (python3.13 on the PATH, or in pyenv's versions), except on CI, where that is an error.
set -euo pipefail
cd "$(dirname "$0")/.."
here="$(pwd -P)"
py=""
for cand in python3.13 "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.13*/bin/python3.13; do
  if "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 13))' >/dev/null 2>&1; then
    py="$cand"; break
  fi
done
if [ -z "$py" ]; then
  if [ "${CI:-}" = true ]; then
    echo "error: no Python 3.13 found for the NumPy 2 pass (python3.13 on the PATH or in pyenv)" >&2
    exit 1
  fi
  echo "note: no Python 3.13 found (python3.13 on the PATH or in pyenv): the NumPy 2 pass is skipped" >&2
  exit 0
fi
echo "the tests without Blender on $("$py" --version) with NumPy 2 (.venv-3.13)"
export NUMBA_CACHE_DIR="$here/build/numba-cache-py313"
PYTHON="$py" ANATOMESH_VENV=.venv-3.13 bash tools/setup_env.sh tests
exec .venv-3.13/bin/python -m pytest -p no:cacheprovider "$@" \
  tests/core/io tests/core/extract tests/core/model tests/core/geometry tests/core/export tests/core/decimate \
  tests/core/preprocess tests/app/test_cli.py tests/app/test_recipe.py tests/app/test_settings.py \
  tests/test_layout.py tests/test_packaging.py
