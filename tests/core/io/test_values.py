"""Counting values in one pass (core/io/values.py): the readers' label detection and the input
facts of `inspect` and the report."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import SAMPLE, shared

from anatomesh.core.io import load
from anatomesh.core.io.describe import describe, label_facts
from anatomesh.core.io.values import value_counts
from anatomesh.core.model.labels import LabelInfo
from anatomesh.core.model.volume import Volume


@pytest.mark.parametrize("dtype", [np.bool_, np.uint8, np.int8, np.uint16, np.int16, np.int32,
                                   np.uint32, np.int64, np.float32])
def test_counts_equal_numpy_unique_in_every_layout(dtype):
    rng = np.random.default_rng(3)
    lo = -40 if np.dtype(dtype).kind in "if" else 0
    hi = 2 if dtype is np.bool_ else (100 if np.dtype(dtype).itemsize == 1 else 3000)
    a = rng.integers(lo, hi, (9, 10, 11)).astype(dtype)
    for arr in (a, np.asfortranarray(a), a[:, ::2, 1:], a.transpose(2, 0, 1)):
        values, counts = value_counts(arr)
        expect_v, expect_c = np.unique(arr, return_counts=True)
        np.testing.assert_array_equal(values, expect_v.astype(np.int64))
        np.testing.assert_array_equal(counts, expect_c)
        assert values.dtype == counts.dtype == np.int64


def test_wide_ranges_big_endian_and_empty():
    a = np.array([[[-2**40, 7, 7, 2**40]]], np.int64)  # wider than a table: np.unique per slab
    np.testing.assert_array_equal(value_counts(a)[0], [-2**40, 7, 2**40])
    np.testing.assert_array_equal(value_counts(a)[1], [1, 2, 1])
    b = np.arange(24, dtype=">u2").reshape(2, 3, 4)  # as stored in some NIfTI/NRRD files
    np.testing.assert_array_equal(value_counts(b)[0], np.arange(24))
    assert value_counts(np.zeros((0, 3, 3), np.uint8))[0].size == 0


def test_label_facts_of_the_61_label_map_match_bincount():
    vol = load(shared("totalsegmentator", "example_seg_fast_force_split.nii.gz"))
    assert vol.data.flags.f_contiguous  # NIfTI order: counted through a flat view, no copy
    expect = np.bincount(np.asarray(vol.data, np.int64).ravel())
    facts = label_facts(vol)
    assert len(facts) == 61
    for f in facts:
        assert f["voxels"] == expect[f["value"]]
        assert f["volume_mm3"] == pytest.approx(expect[f["value"]] * 27.0)
    d = describe(vol)
    assert (d["min"], d["max"]) == (int(vol.data.min()), int(vol.data.max()))
    assert d["labels"] == facts


def test_named_labels_absent_from_the_map_are_listed_with_zero_voxels():
    data = np.zeros((4, 4, 4), np.uint8)
    data[1:3, 1:3, 1:3] = 2
    table = {1: LabelInfo(1, "absent"), 2: LabelInfo(2, "present")}
    facts = label_facts(Volume(data, np.diag([2.0, 2.0, 2.0, 1.0]), labels=table))
    assert [(f["value"], f["name"], f["voxels"], f["volume_mm3"]) for f in facts] == \
        [(1, "absent", 0, 0.0), (2, "present", 8, 64.0)]


def test_sample_label_map_detected_with_its_values():
    vol = load(SAMPLE / "example_seg.nii.gz")
    assert vol.is_label_map and vol.data.dtype == np.uint8
    assert sorted(vol.labels) == [int(v) for v in np.unique(vol.data) if v]


def test_histogram_of_the_chest_ct_counts_as_the_clipped_copy_did_with_less_memory():
    import tracemalloc

    from anatomesh.core.io.describe import HIST_BINS, clamped_histogram, histogram

    vol = load(shared("itkelastix_chest_ct"))
    sample = vol.data.ravel()[:: vol.data.size // 4_000_000 + 1]  # what describe histograms
    expected = np.histogram(np.clip(sample, -1100.0, 2000.0), bins=HIST_BINS, range=(-1100.0, 2000.0))
    tracemalloc.start()
    counts, edges = clamped_histogram(sample, HIST_BINS, -1100.0, 2000.0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert np.array_equal(counts, expected[0]) and np.array_equal(edges, expected[1])
    assert counts.sum() == sample.size  # air below -1100 HU and metal above 2000 in the end bins
    assert peak < 0.5 * sample.size * 8  # the float64 clipped copy alone was sample.size * 8
    facts = histogram(vol.data, hounsfield=True)
    assert facts["counts"] == counts.tolist() and "air" in {p.get("tissue") for p in facts["peaks"]}
