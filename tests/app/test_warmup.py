"""The warm-up (app/warmup.py): a cold cache compiles into a fresh folder and the next process
loads from it; the CLI says when it compiles; `inspect` loads only what it needs."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

from conftest import SAMPLE

from anatomesh.app import warmup


def _run(args, cache=None, **kw):
    env = dict(os.environ)
    if cache is not None:  # this subprocess only: never the test process's own cache
        env["NUMBA_CACHE_DIR"] = str(cache)
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          timeout=600, **kw)


def _compiled(out: str) -> int:
    return int(re.search(r"warmup done [\d.]+ s, (\d+) kernels compiled", out).group(1))


def test_cold_warmup_compiles_into_a_fresh_folder_and_the_next_process_loads_it(tmp_path):
    cache = tmp_path / "numba-cache"
    first = _run(["-m", "anatomesh.app.warmup", "--steps", "reading"], cache)
    assert first.returncode == 0, first.stderr
    assert _compiled(first.stdout) >= 3  # value counts (8/16/32-bit) and the DICOM layout kernel
    saved = list(cache.rglob("*.nbc"))
    assert saved and list(cache.rglob("*.nbi"))
    second = _run(["-m", "anatomesh.app.warmup", "--steps", "reading"], cache)
    assert second.returncode == 0, second.stderr
    assert _compiled(second.stdout) == 0  # every kernel came from the cache
    assert sorted(cache.rglob("*.nbc")) == sorted(saved)  # nothing new was written


def test_the_cli_says_once_when_it_compiles_and_not_when_cached(tmp_path):
    cache = tmp_path / "numba-cache"
    cmd = ["-m", "anatomesh.app.cli", "inspect", str(SAMPLE / "example_seg.nii.gz"), "--json"]
    first = _run(cmd, cache)
    assert first.returncode == 0, first.stderr
    assert first.stderr.count("first run: compiling Anatomesh's kernels once") == 1
    assert json.loads(first.stdout)["labels"]  # the command itself ran normally
    second = _run(cmd, cache)
    assert second.returncode == 0 and "first run" not in second.stderr


def test_inspect_loads_no_smoothing_decimation_or_print_code():
    code = ("import sys; from anatomesh.app.cli import main; "
            f"main(['inspect', {str(SAMPLE / 'example_seg.nii.gz')!r}, '--json']); "
            "print('MODULES', ' '.join(sorted(sys.modules)))")
    out = _run(["-c", code])
    assert out.returncode == 0, out.stderr
    loaded = out.stdout.split("MODULES ", 1)[1].split()
    heavy = [m for m in loaded if m.startswith(("anatomesh.core.smooth", "anatomesh.core.decimate",
                                                 "anatomesh.core.extract", "anatomesh.core.export",
                                                 "anatomesh.core.printing.checks",
                                                 "anatomesh.core.printing.fixes", "anatomesh.app.run"))]
    assert heavy == []
    assert "anatomesh.core.io.nifti" in loaded  # it did read the file


def test_steps_are_known_and_ordered_for_a_first_session():
    assert warmup.DEFAULT_STEPS[:3] == ("reading", "label surfaces", "isosurfaces")
    assert "smoothing" in warmup.DEFAULT_STEPS
    try:
        warmup.warm_up(["no such step"])
    except ValueError as err:
        assert "no such step" in str(err)
    else:
        raise AssertionError("an unknown step must be refused")
