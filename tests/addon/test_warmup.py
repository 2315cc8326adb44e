"""First run in Blender (addon/warmup.py): the kernels compile in a background process of the
running Python, under the add-on's own package name, while operators wait without freezing."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import bpy
import pytest
from conftest import SAMPLE, shared


@pytest.fixture
def warmup(addon):
    mod = sys.modules[addon.__name__ + ".addon.operators.warmup"]
    yield mod
    mod.stop()


def _compiled(out: str) -> int:
    return int(re.search(r"warmup done [\d.]+ s, (\d+) kernels compiled", out).group(1))


def test_the_background_process_runs_our_python_under_the_add_on_name(warmup, addon, tmp_path):
    cmd = warmup.command(["reading"])
    assert cmd[0] == sys.executable and cmd[3] == addon.__name__ == "bl_ext.anatomesh_dev.anatomesh"
    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache),  # for these processes only
               PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    first = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert first.returncode == 0, first.stdout + first.stderr
    assert _compiled(first.stdout) >= 3
    saved = list(cache.rglob("*.nbc"))
    # the kernels were compiled as the add-on's modules, which is what Blender loads
    assert saved and all(b"bl_ext.anatomesh_dev.anatomesh.core.io." in f.read_bytes() for f in saved)
    again = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert again.returncode == 0 and _compiled(again.stdout) == 0  # loaded what the first wrote


def test_start_wait_stamp_and_operators_deferred_until_ready(warmup, empty_scene):
    assert warmup.start(force=True, steps=["reading", "label surfaces"])
    assert warmup.STATE["running"] and not warmup.ready("label surfaces")
    seg = str(SAMPLE / "example_seg.nii.gz")
    # while compiling: the operator returns at once and runs again by itself once ready
    assert bpy.ops.anatomesh.import_scan(filepath=seg, extract=True) == {"FINISHED"}
    assert not empty_scene.anatomesh.last_collection
    assert warmup.wait(timeout=900), warmup.STATE
    assert warmup.ready("label surfaces") and warmup.STATE["done"] == ["reading", "label surfaces"]
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    assert len(coll.all_objects) == 41  # the deferred import ran: every label of the sample
    assert warmup.stamp_path().exists()
    assert not warmup.start()  # the stamp says these sources are compiled: no new process
    assert warmup.status_text() == ""


def test_reading_waits_for_reading_and_a_dicom_series_for_the_scans_step(warmup, tmp_path):
    """The label maps' first extraction waits for the fewest kernels: DICOM's pixel layout
    compiles with the scans (``isosurfaces``), NIfTI/NRRD files and mask folders only count
    values (``reading``)."""
    assert warmup.reading_step(str(SAMPLE / "example_seg.nii.gz")) == "reading"
    masks = tmp_path / "segmentations"
    masks.mkdir()
    (masks / "liver.nii.gz").write_bytes(b"")  # a TotalSegmentator mask folder (by its names)
    assert warmup.reading_step(str(masks)) == "reading"
    series = shared("itkelastix_chest_ct")
    assert warmup.reading_step(str(series)) == "isosurfaces"
    assert warmup.reading_step(str(next(series.glob("*.dcm")))) == "isosurfaces"
    assert "isosurfaces" in warmup.STEPS and "reading" in warmup.STEPS


def test_large_label_maps_wait_for_their_parallel_passes(warmup, addon):
    import importlib
    from types import SimpleNamespace

    load = importlib.import_module(addon.__name__ + ".core").load
    assert warmup.extraction_step(load(str(SAMPLE / "example_seg.nii.gz"))) == "label surfaces"

    def volume(shape, labels=True):  # what a Volume and a Segmentation (layers) both have
        return SimpleNamespace(is_label_map=labels, shape=shape)

    assert warmup.extraction_step(volume((122, 101, 112))) == "label surfaces"
    assert warmup.extraction_step(volume((512, 512, 200))) == "large label maps"
    assert warmup.extraction_step(volume((512, 512, 200), labels=False)) == "isosurfaces"
    assert warmup.STEPS.index("large label maps") > warmup.STEPS.index("label surfaces")


def test_smoothing_before_its_kernels_are_compiled_waits_and_never_runs_twice(warmup, addon,
                                                                            empty_scene):
    """First run, the smoothing steps still compiling: a new label map's organs, slider moves
    and the Smooth operator wait (nothing compiles in the UI); the organs are smoothed once
    "label smoothing" is ready (a session's first run), with the slider's latest value; the
    operator, a second run (which lists the candidate pairs), once "smoothing" is."""
    import numpy as np

    live = sys.modules[addon.__name__ + ".addon.operators.smooth"]
    bridge = sys.modules[addon.__name__ + ".addon.scene.bridge"]
    warmup.STATE.update(running=True, done=["reading", "label surfaces", "isosurfaces"])
    assert bpy.ops.anatomesh.import_scan(filepath=str(SAMPLE / "example_seg.nii.gz"),
                                         extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    obj = coll.all_objects[0]
    extracted = bridge.positions(obj.data).copy()
    for n in (10, 20, 30):  # a slider dragged while compiling
        coll.anatomesh.smooth_iterations = n
    assert bpy.ops.anatomesh.smooth(collection=coll.name, smooth_iterations=12) == {"FINISHED"}
    assert np.array_equal(bridge.positions(obj.data), extracted)  # not smoothed yet
    # one for the collection (however often the slider moved), one for the operator
    assert [step for step, _ in warmup._WAITING] == ["label smoothing", "label smoothing"]
    warmup.STATE["done"].append("label smoothing")
    warmup._run_waiting()
    first = bridge.positions(obj.data).copy()
    assert np.abs(first - extracted).max() > 0.05  # mm: smoothed, with 30 iterations
    assert coll.anatomesh.smooth_iterations == 30
    assert [step for step, _ in warmup._WAITING] == ["smoothing"]  # the operator: a second run
    warmup.STATE["done"].append("smoothing")
    warmup._run_waiting()
    assert not warmup._WAITING and coll.anatomesh.smooth_iterations == 12
    smoothed = bridge.positions(obj.data).copy()
    assert np.abs(smoothed - first).max() > 0.01  # 12 iterations now
    warmup.STATE["running"] = False
    live.smooth_collection(coll)  # the same settings again: the same positions
    assert np.allclose(bridge.positions(obj.data), smoothed, atol=1e-5)


def test_decimation_and_export_before_their_kernels_are_compiled_wait(warmup, empty_scene,
                                                                      tmp_path):
    """First run: Decimate and Export asked for while their step still compiles return at once
    and run by themselves once it is ready (nothing compiles in the UI meanwhile)."""
    empty_scene.anatomesh.smooth_method = "NONE"  # as extracted: decimated below
    assert bpy.ops.anatomesh.import_scan(filepath=str(SAMPLE / "example_seg.nii.gz"),
                                         extract=True) == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    faces = sum(len(o.data.polygons) for o in coll.all_objects)
    steps = list(warmup.STEPS)
    warmup.STATE.update(running=True, done=steps[:steps.index(warmup.DECIMATION_STEP)])
    out = tmp_path / "stl"
    assert bpy.ops.anatomesh.decimate_apply(collection=coll.name, target="RATIO",
                                            ratio=0.5) == {"FINISHED"}
    assert bpy.ops.anatomesh.export(directory=str(out), format="STL",
                                    collection=coll.name) == {"FINISHED"}
    assert sum(len(o.data.polygons) for o in coll.all_objects) == faces and not out.exists()
    warmup.STATE["done"].append(warmup.DECIMATION_STEP)
    warmup._run_waiting()
    assert sum(len(o.data.polygons) for o in coll.all_objects) < 0.6 * faces
    assert len(list(out.glob("*.stl"))) == 41
