"""The style table: the default (data), partial user files over it, name matching, bad files."""
import json

import pytest

from anatomesh.core.io.load import load
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.labels import LabelInfo, label_table_for, rgba
from anatomesh.core.model.labels import style_label
from anatomesh.core.model.style import MATERIALS, load_style
from anatomesh.core.model.surfaceset import SurfaceSet
from conftest import shared

MAPS = ("example_seg.nii.gz", "example_seg_fast_force_split.nii.gz", "example_seg_mr.nii.gz")


def _ts_names():
    doc = json.loads(shared("totalsegmentator", "label_names_total_and_total_mr.json").read_text())
    return set(doc["total"].values()) | set(doc["total_mr"].values())


def test_default_table_has_an_entry_for_every_totalsegmentator_and_map_name():
    table = load_style()
    names = _ts_names()
    for f in MAPS:
        names |= {i.name for i in load(shared("totalsegmentator", f)).labels.values()}
    assert len(names) >= 117 + 4
    for n in sorted(names):
        st = table.style_of(n)
        assert st.source == "structure", n  # its own entry, not a keyword rule or the fallback
        assert st.material in MATERIALS and len(st.color) == 3 and all(0 <= c <= 1 for c in st.color)


def test_default_lungs_are_see_through_and_the_rest_opaque():
    table = load_style()
    lungs = [n for n in _ts_names() if n.startswith("lung_") and "vessels" not in n]
    assert len(lungs) == 7
    for n in _ts_names():
        opacity = table.style_of(n).opacity
        assert (0.25 <= opacity <= 0.35) if n in lungs else opacity == 1.0, n


def test_material_classes_of_some_structures():
    t = load_style()
    expect = {"liver": "parenchyma", "colon": "hollow", "aorta": "artery", "iliac_vena_left": "vein",
              "vertebrae_L1": "bone", "costal_cartilages": "cartilage", "autochthon_left": "muscle",
              "spinal_cord": "nerve", "kidney_cyst_left": "lesion", "trachea": "airway",
              "subcutaneous_fat": "fat", "pulmonary_artery": "artery"}
    assert {n: t.style_of(n).material for n in expect} == expect


@pytest.mark.parametrize("name, same_as", [
    ("Left Kidney", "kidney_left"), ("LeftKidney", "kidney_left"), ("Kidney_L", "kidney_left"),
    ("Deep muscle of back, right", "autochthon_right"), ("Small Intestine", "small_bowel"),
    ("Upper lobe of lung, left", "lung_upper_lobe_left"), ("Common iliac artery, Right", "iliac_artery_right"),
    ("L3 vertebra", "vertebrae_L3"), ("Bladder", "urinary_bladder"), ("Lung_R", "lung_right")])
def test_other_names_of_a_structure(name, same_as):
    t = load_style()
    a, b = t.style_of(name), t.style_of(same_as)
    assert (a.color, a.material, a.opacity) == (b.color, b.material, b.opacity)
    assert a.source in ("structure", "synonym")


def test_keyword_rules_and_fallback():
    t = load_style()
    assert t.style_of("liver tumour").material == "lesion"
    assert t.style_of("GTV_Mass_CT").material == "lesion"
    assert t.style_of("left femoral vein").material == "vein"
    assert t.style_of("Segment_1").source == "fallback"


def test_a_partial_user_file_overrides_and_extends_the_default(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('[structures]\nliver = { color = "#00ff00" }\n'
                 'lung_upper_lobe_left = { opacity = 1.0 }\n'
                 'my_implant = { color = [255, 128, 0], material = "other", opacity = 0.5 }\n'
                 '[[rules]]\nkeywords = ["screw"]\ncolor = [0.5, 0.5, 0.5]\nmaterial = "other"\n')
    default, t = load_style(), load_style(f)
    assert t.style_of("liver").color == (0.0, 1.0, 0.0) and t.style_of("liver").user
    assert t.style_of("liver").material == "parenchyma"  # fields not given stay the default's
    assert t.style_of("lung_upper_lobe_left").opacity == 1.0
    assert t.style_of("lung_upper_lobe_left").color == default.style_of("lung_upper_lobe_left").color
    assert not t.style_of("lung_upper_lobe_left").user  # its colour is still the default's
    assert t.style_of("my_implant").color == (1.0, 128 / 255, 0.0) and t.style_of("my_implant").opacity == 0.5
    assert t.style_of("pedicle screw 3").color == (0.5, 0.5, 0.5)
    assert t.style_of("spleen") == default.style_of("spleen")


@pytest.mark.parametrize("text, words", [
    ("[structures\nliver = 1", "not a valid TOML"),
    ('[structures]\nliver = { color = "#00ff00", material = "metal" }', "material 'metal'"),
    ('[structures]\nliver = { color = "green" }', "must be \"#rrggbb\""),
    ('[structures]\nliver = { opacity = 2 }', "opacity must be a number from 0 to 1"),
    ('[structures]\nnew_thing = { opacity = 0.5 }', "has no color"),
    ('[colours]\nliver = "#00ff00"', "unknown section 'colours'"),
    ('[[rules]]\ncolor = "#00ff00"', "needs keywords"),
    ('[structures]\nliver = { color = "#00ff00", shine = 1 }', "unknown field 'shine'")])
def test_a_bad_style_file_is_one_line_naming_the_file(tmp_path, text, words):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(AnatomeshError) as err:
        load_style(f)
    assert str(f) in str(err.value) and words in str(err.value) and "\n" not in str(err.value)


def test_a_missing_style_file(tmp_path):
    with pytest.raises(AnatomeshError, match="style file not found"):
        load_style(tmp_path / "nope.toml")


def test_label_entries_and_their_meshes_carry_material_and_opacity():
    t = label_table_for([1, 2, 3, 4], {1: "liver", 2: "lung_lower_lobe_left", 3: "label_3",
                                       4: LabelInfo(4, "spleen", (0.1, 0.2, 0.3), color_given=True)})
    assert (t[1].material, t[1].opacity) == ("parenchyma", 1.0)
    assert t[2].material == "parenchyma" and t[2].opacity < 1
    assert t[2].mesh_color() == t[2].color + (t[2].opacity,) and t[1].mesh_color() == t[1].color
    assert t[4].color == (0.1, 0.2, 0.3) and t[4].color_given and t[4].material == "parenchyma"
    # a given colour stays through styling; a name the table does not know keeps its colour
    assert style_label(t[4]).color == (0.1, 0.2, 0.3) and style_label(t[3]).color == t[3].color
    vol = load(shared("totalsegmentator", "example_seg_mr.nii.gz"))
    from anatomesh.core.extract.multilabel import label_surfaces

    shells = {m.name: m for m in label_surfaces(vol).shells()}
    lung = shells["lung_right"]
    assert rgba(lung.color)[3] == pytest.approx(load_style().style_of("lung_right").opacity)
    assert lung.meta["material"] == "parenchyma" and shells["aorta"].meta["material"] == "artery"
    assert rgba(shells["liver"].color)[3] == 1.0
    # independent surfaces keep them too
    again = SurfaceSet.from_meshes([lung, shells["aorta"]], vol.affine, vol.space)
    assert again.labels[1].opacity == pytest.approx(rgba(lung.color)[3])
    assert again.labels[2].material == "artery"
