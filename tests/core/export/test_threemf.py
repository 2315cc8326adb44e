"""3MF: real organs and an analytic sphere round trip exactly; PrusaSlicer reads and slices it."""
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from conftest import SAMPLE

from anatomesh.core import AnatomeshError, Mesh, label_surfaces, load, topology
from anatomesh.core.export import SCENE_FORMATS
from anatomesh.core.export.threemf import NS_ANATOMESH, NS_CORE, read_3mf, write_3mf
from anatomesh.core.model.mesh import signed_volume
from helpers.meshes import icosphere, tiled_spheres

ORGANS = ("kidney_left", "gallbladder", "pancreas")


@pytest.fixture(scope="module")
def organs():
    shells = label_surfaces(load(SAMPLE / "example_seg.nii.gz")).shells()
    return [m for m in shells if m.name in ORGANS]


def _same(a: Mesh, b: Mesh):
    np.testing.assert_array_equal(b.vertices, a.vertices)  # exact float32
    np.testing.assert_array_equal(b.faces, a.faces)
    assert b.name == a.name and b.value == a.value and b.space == a.space


def test_organs_round_trip_exactly(organs, tmp_path):
    p = write_3mf(organs, tmp_path / "organs.3mf", title="three organs")
    assert SCENE_FORMATS["3mf"] is write_3mf
    back = read_3mf(p)
    assert [m.name for m in back] == [m.name for m in organs] and len(organs) == 3
    for a, b in zip(organs, back):
        _same(a, b)
        np.testing.assert_allclose(b.color, a.color, atol=0.5 / 255)  # 8-bit sRGB hex
        assert topology(b.vertices, b.faces).closed
    assert not list(tmp_path.glob("*.part"))


def test_package_layout_unit_and_metadata(organs, tmp_path):
    m = organs[0]
    m2 = Mesh(m.vertices, m.faces, name='a <"odd"> & name', value=7, color=(1.0, 0.0, 0.5, 0.25),
              space="LPS")
    p = write_3mf([m2], tmp_path / "x.3mf", title="T & co")
    with zipfile.ZipFile(p) as zf:
        names = set(zf.namelist())
        model = zf.read("3D/3dmodel.model").decode()
        rels = zf.read("_rels/.rels").decode()
    assert {"[Content_Types].xml", "_rels/.rels", "3D/3dmodel.model"} <= names
    assert 'Target="/3D/3dmodel.model"' in rels
    assert 'unit="millimeter"' in model and NS_CORE in model
    assert f'xmlns:anatomesh="{NS_ANATOMESH}"' in model
    assert '<metadata name="anatomesh:space">LPS</metadata>' in model
    assert '<metadata name="Title">T &amp; co</metadata>' in model
    assert 'displaycolor="#FF008040"' in model  # RGBA with alpha 0.25
    assert "<transform" not in model and "transform=" not in model
    b = read_3mf(p)[0]
    assert b.name == m2.name and b.space == "LPS" and b.value == 7
    np.testing.assert_allclose(b.color, (1.0, 0.0, 128 / 255, 64 / 255))


def test_sphere_volume_after_round_trip(tmp_path):
    v, f = icosphere(5, 30.0)
    m = Mesh(v + [200.0, -100.0, 50.0], f, name="sphere", space="RAS")
    b = read_3mf(write_3mf([m], tmp_path / "s.3mf"))[0]
    vol = signed_volume(b.vertices, b.faces)
    assert vol == signed_volume(m.vertices, m.faces)
    assert abs(vol - 4 / 3 * np.pi * 30.0 ** 3) / (4 / 3 * np.pi * 30.0 ** 3) < 2e-3


def test_reads_other_producers_transforms_components_units(tmp_path):
    """A hand-written model: cm units, a component with a translation, a mirrored build item."""
    model = f"""<?xml version="1.0" encoding="UTF-8"?>
<model unit="centimeter" xmlns="{NS_CORE}"><resources>
<basematerials id="9"><base name="red" displaycolor="#FF0000"/><base name="blue" displaycolor="#0000FF"/></basematerials>
<object id="1" type="model" pid="9" pindex="1"><mesh><vertices>
<vertex x="0" y="0" z="0"/><vertex y="0" x="1" z="0"/><vertex x="0" y="1" z="0"/><vertex z="1" x="0" y="0"/>
</vertices><triangles>
<triangle v1="0" v2="2" v3="1"/><triangle v1="0" v2="1" v3="3" p1="1"/><triangle v1="0" v2="3" v3="2"/><triangle v1="1" v2="2" v3="3"/>
</triangles></mesh></object>
<object id="2" name="pair"><components><component objectid="1"/>
<component objectid="1" transform="1 0 0 0 1 0 0 0 1 5 0 0"/></components></object>
</resources><build><item objectid="2" transform="-1 0 0 0 1 0 0 0 1 0 0 0"/></build></model>"""
    p = tmp_path / "other.3mf"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("3D/3dmodel.model", model)  # no rels: the default part name is used
    (m,) = read_3mf(p)
    assert m.name == "pair" and m.n_faces == 8 and m.n_vertices == 8
    np.testing.assert_allclose(m.vertices.min(axis=0), [-60, 0, 0])  # cm → mm, mirrored in x
    np.testing.assert_allclose(m.vertices.max(axis=0), [0, 10, 10])
    tet = 1000.0 / 6  # (10 mm)³ / 6
    assert signed_volume(m.vertices, m.faces) == pytest.approx(2 * tet)  # still outward
    assert m.color == (0.0, 0.0, 1.0)


@pytest.mark.parametrize("bad, what", [
    ([], "no surfaces"),
    ("nan", "NaN"),
    ("repeated", "repeated vertex"),
    ("nofaces", "no triangles"),
])
def test_bad_inputs(bad, what, tmp_path):
    v, f = icosphere(1, 5.0)
    if bad == "nan":
        v = v.copy()
        v[3, 1] = np.nan
        bad = [Mesh(v, f, name="broken")]
    elif bad == "repeated":
        f = f.copy()
        f[0, 1] = f[0, 0]
        bad = [Mesh(v, f, name="broken")]
    elif bad == "nofaces":
        bad = [Mesh(v, np.zeros((0, 3)), name="broken")]
    with pytest.raises(AnatomeshError, match=what):
        write_3mf(bad, tmp_path / "bad.3mf")
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_unreadable_file(tmp_path):
    p = tmp_path / "junk.3mf"
    p.write_bytes(b"not a zip")
    with pytest.raises(AnatomeshError, match="not a readable 3MF"):
        read_3mf(p)


def test_extreme_coordinates_read_back_exactly(tmp_path):
    """9 significant digits from the numba formatter give the same float32 at every magnitude."""
    rng = np.random.default_rng(7)
    mag = 10.0 ** rng.integers(-44, 38, (3000, 3))
    v = (rng.standard_normal((3000, 3)) * mag).astype(np.float32)
    v[:4] = [[0, -0.0, 1e-5], [9.9999999e-5, 1e8, -99999999.5], [3.4e38, -1.2e-38, 1e-45],
             [123456.789, -0.001, 7]]
    f = np.arange(3000, dtype=np.int32).reshape(-1, 3)
    b = read_3mf(write_3mf([Mesh(v, f, name="extremes")], tmp_path / "e.3mf"))[0]
    np.testing.assert_array_equal(b.vertices, v)


def test_million_triangle_file(tmp_path):
    """A million triangles make one valid model part (the write time is in benchmarks/bench_export.py)."""
    vv, ff = tiled_spheres()
    m = Mesh(vv + [12.5, -7.25, 300.0], ff, name="big")
    p = write_3mf([m], tmp_path / "big.3mf")
    with zipfile.ZipFile(p) as zf:
        assert zf.getinfo("3D/3dmodel.model").file_size > 50e6
    back = read_3mf(p)[0]
    assert back.n_faces == m.n_faces == 1_064_960


PRUSA = shutil.which("prusa-slicer")


@pytest.mark.skipif(PRUSA is None, reason="prusa-slicer (Debian package prusa-slicer) is not installed")
def test_prusaslicer_reads_and_slices(organs, tmp_path):
    p = write_3mf(organs, tmp_path / "organs.3mf")
    info = subprocess.run([PRUSA, "--info", str(p)], capture_output=True, text=True, timeout=300)
    assert info.returncode == 0, info.stderr[-2000:]
    assert info.stdout.count("manifold = yes") == len(organs), info.stdout
    assert "manifold = no" not in info.stdout
    out = tmp_path / "organs.gcode"
    run = subprocess.run([PRUSA, "--export-gcode", "-o", str(out), str(p)], capture_output=True,
                         text=True, timeout=600)
    log = run.stdout + run.stderr
    assert run.returncode == 0, log[-2000:]
    assert out.stat().st_size > 100_000
    for word in ("error", "repair", "warning"):
        assert word not in log.lower(), log[-2000:]
