"""Body systems of structure names (the web page's tree), from the palette's keyword rules."""
import json

import pytest

from anatomesh.core.model.labels import SYSTEMS, anatomical_color, structure_system
from conftest import shared


@pytest.mark.parametrize("name, system", [
    ("liver", "organs"), ("kidney_cyst_left", "lesions"), ("liver tumour", "lesions"),
    ("vertebrae_L3", "bones"), ("rib_left_1", "bones"), ("intervertebral_discs", "bones"),
    ("aorta", "vessels"), ("portal_vein_and_splenic_vein", "vessels"),
    ("pulmonary_artery", "vessels"), ("heart_myocardium", "heart"), ("spinal_cord", "nerves"),
    ("brain", "nerves"), ("gluteus_maximus_left", "muscles"), ("trachea", "airways"),
    ("LeftKidney", "organs"), ("skin", "other"), ("label_7", "other"), ("", "other")])
def test_system_of_names(name, system):
    assert structure_system(name) == system
    assert system in SYSTEMS


def test_every_totalsegmentator_name_has_the_system_of_its_colour_rule():
    names = json.loads(shared("totalsegmentator", "label_names_total_and_total_mr.json").read_text())
    for table in names.values():
        for name in table.values():
            s = structure_system(name)
            assert s in SYSTEMS
            assert (s == "other") == (anatomical_color(name) is None) or name.startswith(("skin", "fat"))
