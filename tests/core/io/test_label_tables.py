"""Label tables, the anatomical palette and label-map detection (core/io/labels.py)."""
from __future__ import annotations

import json
import shutil

import nibabel as nib
import numpy as np
import pytest
from conftest import shared

from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.io.label_tables import distinct_values, find_sidecar, image_stem, load_label_table, looks_like_label_map, read_label_table
from anatomesh.core.model.labels import anatomical_color, distinct_color, label_table_for
from anatomesh.core.model.labels import LabelInfo

TS = ("totalsegmentator", "label_names_total_and_total_mr.json")


def _ts_json():
    return json.loads(shared(*TS).read_text())


# -- TotalSegmentator JSON ----------------------------------------------------------------
def test_totalsegmentator_tables_by_key():
    doc = _ts_json()
    total = read_label_table(shared(*TS), key="total")
    mr = read_label_table(shared(*TS), key="total_mr")
    assert len(total) == len(doc["total"]) == 117
    assert len(mr) == len(doc["total_mr"]) == 50
    assert doc["total"]["5"] == "liver" and total[5].name == "liver"
    assert {v: i.name for v, i in total.items()} == {int(k): n for k, n in doc["total"].items()}
    assert {v: i.name for v, i in mr.items()} == {int(k): n for k, n in doc["total_mr"].items()}
    # the two tables differ from value 10 on: the key really selects
    assert total[10].name == "lung_upper_lobe_left" and mr[10].name == "lung_left"


def test_totalsegmentator_key_in_path_and_bad_key():
    t = read_label_table(f"{shared(*TS)}#total_mr")
    assert t[10].name == "lung_left"
    with pytest.raises(AnatomeshError, match="no table 'total_ct'.*total, total_mr"):
        read_label_table(shared(*TS), key="total_ct")
    with pytest.raises(AnatomeshError, match="several tables.*total, total_mr"):
        read_label_table(shared(*TS))


def test_totalsegmentator_auto_pick():
    p = shared(*TS)
    # value 117 exists only in 'total'
    _, src = load_label_table(p, values=[1, 5, 117])
    assert src.endswith("#total")
    # values <= 49 fit both tables: the file name decides, else file order
    _, src = load_label_table(p, values=[1, 5, 49], hint="example_seg_mr.nii.gz")
    assert src.endswith("#total_mr")
    _, src = load_label_table(p, values=[1, 5, 49], hint="example_seg.nii.gz")
    assert src.endswith("#total")
    # on the real MR map: total_mr names
    values = np.unique(np.asanyarray(nib.load(shared("totalsegmentator", "example_seg_mr.nii.gz")).dataobj))
    t, src = load_label_table(p, values=values, hint="example_seg_mr.nii.gz")
    assert src.endswith("#total_mr") and t[49].name == _ts_json()["total_mr"]["49"]


def test_nnunet_dataset_json(tmp_path):
    f = tmp_path / "dataset.json"
    f.write_text(json.dumps({"name": "x", "labels": {"background": 0, "liver": 1, "liver_tumor": 2}}))
    t = read_label_table(f)
    assert t[1].name == "liver" and t[2].name == "liver_tumor" and 0 not in t
    assert t[1].color != t[2].color


# -- 3D Slicer and ITK-SNAP tables -------------------------------------------------------
def test_slicer_color_table(tmp_path):
    f = tmp_path / "colors.ctbl"
    f.write_text("# Color table file colors.ctbl\n# 3 values\n0 Background 0 0 0 0\n"
                 "1 left kidney 255 0 0 255\n7 Vessel_7 0 128 255 200\n")
    t = read_label_table(f)
    assert sorted(t) == [1, 7]  # background left out
    assert t[1].name == "left kidney" and t[1].color == (1.0, 0.0, 0.0)
    assert t[7].name == "Vessel_7"
    np.testing.assert_allclose(t[7].color, (0.0, 128 / 255, 1.0))


def test_plain_value_name_table_gets_palette_colours(tmp_path):
    f = tmp_path / "names.txt"
    f.write_text("1 liver\n2 aorta\n3 something odd\n")
    t = read_label_table(f)
    assert [t[v].name for v in (1, 2, 3)] == ["liver", "aorta", "something odd"]
    r, g, b = t[2].color
    assert r > 0.7 and g < 0.2 and b < 0.2  # arteries red
    assert t[3].color == distinct_color(3)


def test_slicer_csv_table(tmp_path):
    f = tmp_path / "t.csv"
    f.write_text("LabelValue,Name,Color_R,Color_G,Color_B,Color_A\n0,Background,0,0,0,0\n"
                 "4,gallbladder,0,255,0,255\n")
    t = read_label_table(f)
    assert t[4].name == "gallbladder" and t[4].color == (0.0, 1.0, 0.0)


def test_itksnap_label_file(tmp_path):
    f = tmp_path / "labels.txt"
    f.write_text(
        "################################################\n"
        "# ITK-SnAP Label Description File\n"
        "# IDX   -R-  -G-  -B-  -A--  VIS MSH  LABEL\n"
        "################################################\n"
        '    0     0    0    0        0  0  0    "Clear Label"\n'
        '    1   255    0    0        1  1  1    "Right ventricle"\n'
        '   12     0  255  128     0.50  1  0    "Portal vein 2"\n')
    t = read_label_table(f)
    assert sorted(t) == [1, 12]
    assert t[1].name == "Right ventricle" and t[1].color == (1.0, 0.0, 0.0)
    assert t[12].name == "Portal vein 2"
    np.testing.assert_allclose(t[12].color, (0.0, 1.0, 128 / 255))


@pytest.mark.parametrize("content, message", [
    (b"", "empty"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe binary", "cannot read|no label entries"),
    (b"{\"1\": \"liver\",", "invalid JSON"),
    (b"{\"Modality\": \"CT\", \"EchoTime\": 0.01}", "no label table"),
    (b"this is not\na colour table\n", "no label entries"),
])
def test_unreadable_label_table(tmp_path, content, message):
    f = tmp_path / "table.txt"
    f.write_bytes(content)
    with pytest.raises(AnatomeshError, match=message) as err:
        read_label_table(f)
    assert str(f) in str(err.value) and "expected a TotalSegmentator JSON" in str(err.value)


def test_missing_label_table(tmp_path):
    with pytest.raises(AnatomeshError, match="not found"):
        read_label_table(tmp_path / "nope.json")


# -- palette ------------------------------------------------------------------------------
def test_every_totalsegmentator_name_has_an_anatomical_colour():
    doc = _ts_json()
    names = set(doc["total"].values()) | set(doc["total_mr"].values())
    assert [n for n in sorted(names) if anatomical_color(n) is None] == []


def test_palette_classes():
    doc = _ts_json()
    ivory = anatomical_color("femur_left")
    for n in doc["total"].values():
        if n.startswith(("vertebrae_", "rib_")) or n in ("skull", "sacrum", "sternum", "hip_left",
                                                         "clavicula_right", "scapula_left", "humerus_right"):
            assert anatomical_color(n) == ivory, n
    for n in ("aorta", "common_carotid_artery_left", "iliac_artery_right", "brachiocephalic_trunk",
              "pulmonary_vein"):
        r, g, b = anatomical_color(n)
        assert r > 0.7 and r > 3 * g and r > 3 * b, n
    for n in ("inferior_vena_cava", "portal_vein_and_splenic_vein", "iliac_vena_left",
              "brachiocephalic_vein_left", "pulmonary_artery"):
        r, g, b = anatomical_color(n)
        assert b > 0.7 and b > 2 * r, n
    assert anatomical_color("gallbladder")[1] > anatomical_color("gallbladder")[0]  # green
    assert anatomical_color("kidney_cyst_left") != anatomical_color("kidney_left")
    assert anatomical_color("liver") != anatomical_color("spleen")
    assert anatomical_color("intervertebral_discs") != ivory
    assert anatomical_color("spinal_cord") != ivory
    assert anatomical_color("LeftKidney") == anatomical_color("kidney_left")
    assert anatomical_color("liver tumour") == anatomical_color("lesion")
    assert anatomical_color("label_7") is None and anatomical_color("Segment_1") is None


def test_label_table_for():
    t = label_table_for([0, 3, 5, 5, 40], {5: "liver", 40: LabelInfo(40, "mine", (0.1, 0.2, 0.3))})
    assert sorted(t) == [3, 5, 40]  # background skipped, values deduplicated
    assert t[3].name == "label_3" and t[3].color == distinct_color(3)
    assert t[5].name == "liver" and t[40].color == (0.1, 0.2, 0.3)
    assert label_table_for([5], {5: "liver"})[5].color == t[5].color  # deterministic
    cols = np.array([distinct_color(v) for v in range(1, 31)])
    d = np.linalg.norm(cols[:, None] - cols[None], axis=-1) + np.eye(30)
    assert d.min() > 0.02 and np.linalg.norm(cols[1:] - cols[:-1], axis=1).min() > 0.3
    # neighbouring vertebrae share the palette class but are not identical
    v = label_table_for([31, 32], {31: "vertebrae_L1", 32: "vertebrae_T12"})
    assert v[31].color != v[32].color
    for c in (v[31].color, v[32].color):
        assert c[0] >= c[1] >= c[2] > 0.45  # both bone (GenericAnatomyColors bone 241, 214, 145)


# -- label map detection ------------------------------------------------------------------
def test_looks_like_label_map_on_real_data():
    seg = np.asanyarray(nib.load(shared("totalsegmentator", "example_seg.nii.gz")).dataobj)
    ct = np.asanyarray(nib.load(shared("totalsegmentator", "example_ct_sm.nii.gz")).dataobj)
    mask = np.asanyarray(nib.load(shared("totalsegmentator", "aorta", "aorta.nii.gz")).dataobj)
    assert looks_like_label_map(seg) and looks_like_label_map(mask)
    assert not looks_like_label_map(ct)
    assert looks_like_label_map(seg.astype(np.float32))  # whole numbers in a float file
    assert not looks_like_label_map(np.clip(ct, 0, None))  # >512 grey values


def test_looks_like_label_map_synthetic():
    rng = np.random.default_rng(0)
    assert looks_like_label_map(np.zeros((4, 4, 4), bool))
    assert not looks_like_label_map(np.full((4, 4, 4), 0.5, np.float32))
    assert not looks_like_label_map(np.array([[[0, 1, -1]]], np.int16))
    nan = np.zeros((3, 3, 3), np.float32)
    nan[1, 1, 1] = np.nan
    assert not looks_like_label_map(nan)
    many = np.arange(600, dtype=np.uint16).reshape(6, 10, 10)
    assert not looks_like_label_map(many)
    assert looks_like_label_map(many, max_labels=600)
    assert looks_like_label_map(rng.integers(0, 512, (8, 8, 8)))  # exactly at the limit is allowed


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("dtype", [np.uint8, np.int32, np.float32, np.int64])
def test_distinct_values_matches_unique(order, dtype):
    rng = np.random.default_rng(1)
    a = np.asarray(rng.integers(0, 40, (7, 9, 11)) * 3, dtype=dtype, order=order)
    np.testing.assert_array_equal(distinct_values(a), np.unique(a).astype(np.int64))
    assert distinct_values(a, limit=10) is None
    big = np.asarray(rng.integers(2**21, 2**21 + 5, (4, 4, 4)), dtype=np.int64, order=order)
    np.testing.assert_array_equal(distinct_values(big), np.unique(big))


# -- sidecars -----------------------------------------------------------------------------
def test_image_stem():
    assert image_stem("a/aorta.nii.gz") == "aorta"
    assert image_stem("x.seg.nrrd") == "x" and image_stem("b.nhdr") == "b"
    assert image_stem("scan.nii") == "scan"


def test_find_sidecar_rules(tmp_path):
    img = tmp_path / "seg.nii.gz"
    shutil.copy(shared("totalsegmentator", "example_seg.nii.gz"), img)
    assert find_sidecar(img) is None
    # a TotalSegmentator names file in the folder is found ...
    shutil.copy(shared(*TS), tmp_path / "label_names_total_and_total_mr.json")
    assert find_sidecar(img).name == "label_names_total_and_total_mr.json"
    assert find_sidecar(img, folder_tables=False) is None
    # ... a same-stem JSON that is not a label table (BIDS metadata) is skipped ...
    (tmp_path / "seg.json").write_text(json.dumps({"Modality": "CT", "SliceThickness": 3}))
    assert find_sidecar(img).name == "label_names_total_and_total_mr.json"
    # ... and a same-stem colour table wins
    (tmp_path / "seg.ctbl").write_text("0 Background 0 0 0 0\n5 Leber 10 20 30 255\n")
    assert find_sidecar(img).name == "seg.ctbl"
