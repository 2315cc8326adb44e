"""Software snapshots: shapes land where they are, colours are the meshes', PNGs read back."""
import struct
import zlib

import numpy as np
import pytest
from helpers.meshes import box, icosphere

from anatomesh.core.export.snapshot import contact_sheet, render, write_png
from anatomesh.core.model.errors import AnatomeshError
from anatomesh.core.model.mesh import Mesh


def _read_png(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w, h = 8, b"", None, None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        assert struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0] == zlib.crc32(kind + body)
        if kind == b"IHDR":
            w, h = struct.unpack(">II", body[:8])
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    assert not raw[:, 0].any()  # filter type 0 on every row
    return raw[:, 1:].reshape(h, w, 3)


def test_sphere_fills_a_disc_of_the_right_area():
    v, f = icosphere(4, 10.0)
    img = render([Mesh(v, f, color=(1.0, 0.0, 0.0))], size=(200, 200), margin=0.1)
    covered = np.any(img != 255, axis=2)
    # the sphere's outline spans 80 % of the width: area pi * 80^2 pixels
    assert covered.sum() == pytest.approx(np.pi * 80 ** 2, rel=0.03)
    assert np.all(img[covered][:, 1:] < 40) and img[covered][:, 0].max() > 200  # red, shaded


def test_anterior_view_puts_the_patients_right_on_the_left():
    right = Mesh(*box((-60, -5, -5), (-40, 5, 5)), color=(0, 0, 1.0), space="RAS")   # x < 0: right
    head = Mesh(*box((-5, -5, 40), (5, 5, 60)), color=(0, 1.0, 0), space="RAS")      # z > 0: up
    img = render([right, head], size=(120, 120), view="anterior")
    blue = np.argwhere((img[..., 2] > 200) & (img[..., 0] < 50))
    green = np.argwhere((img[..., 1] > 200) & (img[..., 0] < 50))
    assert blue[:, 1].mean() < 60 and green[:, 0].mean() < 60  # left of centre; top half
    lps = Mesh(right.vertices * [-1, -1, 1], right.faces[:, ::-1], color=(0, 0, 1.0), space="LPS")
    assert np.array_equal(render([lps, head], size=(120, 120)), img)  # same anatomy, same picture


def test_nearer_surface_hides_the_farther_one():
    front = Mesh(*box((-10, 20, -10), (10, 30, 10)), color=(1.0, 0, 0))   # anterior: nearer
    back = Mesh(*box((-20, -30, -20), (20, -20, 20)), color=(0, 0, 1.0))
    img = render([back, front], size=(100, 100), view="anterior")
    assert img[50, 50, 0] > 150 and img[50, 50, 2] < 50
    img = render([back, front], size=(100, 100), view="posterior")
    assert img[50, 50, 2] > 150 and img[50, 50, 0] < 50


def test_png_round_trip_and_contact_sheet(tmp_path):
    v, f = icosphere(2, 5.0)
    pics = [render([Mesh(v, f, color=c)], size=(40, 30)) for c in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    sheet = contact_sheet(pics, columns=2, gap=2)
    assert sheet.shape == (2 * 30 + 3 * 2, 2 * 40 + 3 * 2, 3)
    p = write_png(sheet, tmp_path / "sheet.png")
    assert np.array_equal(_read_png(p), sheet)


def test_bad_arguments():
    v, f = icosphere(1, 5.0)
    with pytest.raises(AnatomeshError, match="unknown view"):
        render([Mesh(v, f)], view="sideways")
    with pytest.raises(AnatomeshError, match="uint8"):
        write_png(np.zeros((4, 4, 3)), "x.png")
