"""The warm-up (app/warmup.py): a cold cache compiles into a fresh folder and the next process
loads from it; two processes share the compiling (a kernel the other claimed runs as Python);
the CLI says when it compiles; `inspect` loads only what it needs."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
from conftest import SAMPLE
from numba.core.dispatcher import Dispatcher

from anatomesh.app.warmup import compile as warmup

_ORIGINAL = Dispatcher._compile_for_args


def _run(args, cache=None, **kw):
    env = dict(os.environ)
    if cache is not None:  # this subprocess only: never the test process's own cache
        env["NUMBA_CACHE_DIR"] = str(cache)
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env,
                          timeout=600, **kw)


def _compiled(out: str) -> int:
    return int(re.search(r"warmup done [\d.]+ s, (\d+) kernels compiled", out).group(1))


def test_as_runs_the_warmup_under_another_package_name_as_tools_test_sh_does(tmp_path):
    """``--as PACKAGE FOLDER``: the kernels are compiled as that package's modules, imported from
    that folder (what the Blender tests load: numba's cache remembers both)."""
    root = tmp_path / "ext" / "repo"
    root.mkdir(parents=True)
    (root / "anatomesh").symlink_to(SAMPLE.parents[1], target_is_directory=True)
    cache = tmp_path / "numba-cache"
    out = _run(["-m", "anatomesh.app.warmup", "--as", "bl_ext.repo.anatomesh", str(root),
                "--steps", "reading", "--lanes", "1"], cache)
    assert out.returncode == 0, out.stderr
    assert _compiled(out.stdout) >= 3
    saved = list(cache.rglob("*.nbc"))
    assert saved and all(b"bl_ext.repo.anatomesh.core.io." in f.read_bytes() for f in saved)


def test_cold_warmup_compiles_into_a_fresh_folder_and_the_next_process_loads_it(tmp_path):
    cache = tmp_path / "numba-cache"
    first = _run(["-m", "anatomesh.app.warmup", "--steps", "reading"], cache)
    assert first.returncode == 0, first.stderr
    assert _compiled(first.stdout) >= 3  # value counts: 8-, 16- and 32-bit
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
                                                 "anatomesh.core.printing.fixes", "anatomesh.app.flow.run"))]
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


def test_a_kernel_another_lane_claimed_runs_as_python_with_the_same_result(tmp_path):
    from anatomesh.core.io._values_kernels import add_counts

    flat = np.array([3, 1, 3, 2, 3, 9, 1], np.uint64)  # a type no code path compiles it for
    counts = np.zeros((4, 9), np.int64)  # four interleaved histograms
    before = list(add_counts.signatures)
    other_lane = warmup._claim(tmp_path, add_counts.py_func, warmup._types(add_counts, (flat, 1, counts)))
    assert other_lane
    with warmup.sharing_kernels(tmp_path), warmup.counting_compiles() as compiled:
        add_counts(flat, 1, counts)
    assert compiled == [] and add_counts.signatures == before  # ran as Python, compiled nothing
    assert counts.sum(0).tolist() == np.bincount(flat.astype(np.int64) - 1, minlength=9).tolist()
    assert Dispatcher._compile_for_args is _ORIGINAL  # numba is as it was after the block


def test_a_kernel_nobody_claimed_is_claimed_and_compiled(tmp_path):
    from anatomesh.core.io._values_kernels import add_counts

    flat = np.array([5, 4, 4], np.int8)  # int8: no code path compiles it for this type either
    counts = np.zeros((1, 2), np.int64)  # one histogram
    with warmup.sharing_kernels(tmp_path):
        add_counts(flat, 4, counts)
    assert counts.tolist() == [[2, 1]]
    # compiled (or loaded from numba's cache on a later test run), not run as Python
    assert any(sig.args[0].dtype.name == "int8" for sig in add_counts.nopython_signatures)
    assert not warmup._claim(tmp_path, add_counts.py_func, warmup._types(add_counts, (flat, 4, counts)))


def test_two_lanes_share_a_cold_first_run_and_the_first_extraction_compiles_nothing(tmp_path):
    cache = tmp_path / "numba-cache"
    first = _run(["-m", "anatomesh.app.warmup", "--steps", "reading,label surfaces", "--lanes", "2"],
                 cache)
    assert first.returncode == 0, first.stderr
    starts = [line for line in first.stdout.splitlines() if line.startswith("warmup ")]
    assert starts[:2] == ["warmup 1/2 reading", "warmup 2/2 label surfaces"]
    by_lane = re.search(r"by lane: (\d+), (\d+)", first.stdout).groups()
    assert all(int(n) > 0 for n in by_lane), first.stdout  # both lanes compiled a share
    code = ("from anatomesh.app.warmup.compile import counting_compiles\n"
            "from anatomesh.core.io import load\n"
            "from anatomesh.core.extract.multilabel import label_surfaces\n"
            "with counting_compiles() as names:\n"
            f"    shells = label_surfaces(load({str(SAMPLE / 'example_seg.nii.gz')!r})).shells()\n"
            "print('SHELLS', len(shells), 'COMPILED', names)")
    after = _run(["-c", code], cache)
    assert after.returncode == 0, after.stderr
    assert "COMPILED []" in after.stdout and "SHELLS 0" not in after.stdout


def test_after_their_steps_label_maps_extract_and_smooth_compiling_nothing(tmp_path):
    """The parallel passes of maps above PARALLEL_MIN_VOXELS have a step of their own (Blender
    used to compile them, frozen, on the first large map after a complete warm-up); the label
    steps leave nothing to compile for the sample's extraction, small or large, with its pinch
    points moved apart, and "label smoothing" nothing for the first smoothing of its surfaces
    (what Blender runs after extracting them)."""
    cache = tmp_path / "numba-cache"
    steps = "reading,label surfaces,large label maps,label smoothing"
    warm = _run(["-m", "anatomesh.app.warmup", "--steps", steps, "--lanes", "1"], cache)
    assert warm.returncode == 0, warm.stderr
    assert _compiled(warm.stdout) >= 10
    code = ("from anatomesh.app.warmup.compile import counting_compiles\n"
            "from anatomesh.core.io import load\n"
            "from anatomesh.core.extract import multilabel\n"
            "from anatomesh.core.smooth.session import SmoothingSession\n"
            "from anatomesh.app.flow.stages import output_shells, smoothing\n"
            "from anatomesh.app.flow.recipe import Recipe\n"
            f"vol = load({str(SAMPLE / 'example_seg.nii.gz')!r})\n"
            "with counting_compiles() as names:\n"
            "    surfaces = multilabel.label_surfaces(vol)\n"
            "    small = surfaces.shells()\n"
            "    output_shells(surfaces)\n"
            "    method, settings = smoothing(Recipe())\n"
            "    moved = SmoothingSession(surfaces).run(method, **settings)[0] - surfaces.vertices\n"
            "    output_shells(surfaces.copy_with_vertices(surfaces.vertices + moved))\n"
            "    multilabel.PARALLEL_MIN_VOXELS = 0\n"
            "    large = multilabel.label_surfaces(vol).shells()\n"
            "assert len(small) == len(large) == 41 and abs(moved).max() > 0.05\n"
            "print('COMPILED', len(names), names)\n")
    out = _run(["-c", code], cache)
    assert out.returncode == 0, out.stderr
    assert "COMPILED 0 []" in out.stdout


def test_a_run_that_compiles_says_so_then_tells_its_progress_and_a_cached_run_says_nothing(tmp_path):
    """The command line's note on a cold cache, then progress lines (how many kernels, how long,
    which one) while kernels go on compiling; nothing at all once numba's cache holds them."""
    code = ("import io, numpy as np\n"
            "from anatomesh.app.warmup.compile import announce_compiling, FIRST_RUN_NOTE\n"
            "from anatomesh.core.io.values import value_counts\n"
            "out = io.StringIO()\n"
            "with announce_compiling(stream=out, every=0.0):\n"
            "    for dtype in (np.uint8, np.int16, np.int32):\n"
            "        value_counts(np.arange(27, dtype=dtype).reshape(3, 3, 3) % 4)\n"
            "lines = out.getvalue().splitlines()\n"
            "print('FIRST', lines[:1] == [FIRST_RUN_NOTE], 'LINES', len(lines))\n"
            "print('\\n'.join(lines[1:]))\n")
    cache = tmp_path / "numba-cache"
    cold = _run(["-c", code], cache)
    assert cold.returncode == 0, cold.stderr
    assert "FIRST True" in cold.stdout and re.search(r"compiling kernels: 1 done in \d+ s, now _values_kernels\.add_counts", cold.stdout)
    warm = _run(["-c", code], cache)
    assert warm.returncode == 0, warm.stderr
    assert "FIRST False LINES 0" in warm.stdout
