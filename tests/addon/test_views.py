"""Camera views, turntable and labels on the real TotalSegmentator maps (41 and 61 labels).

Framing is judged from the outside: every vertex's projection by Blender's own
``world_to_camera_view`` (on the convex hull's vertices, which hold every extreme), and the pixels
of a real render against its background.
"""
from __future__ import annotations

import importlib
import json

import bpy
import numpy as np
import pytest
from conftest import shared  # tests/conftest.py
from scipy.spatial import ConvexHull

MAPS = {"41": "example_seg.nii.gz", "61": "example_seg_fast_force_split.nii.gz"}
LABELLED = ["liver", "spleen", "stomach", "gallbladder", "kidney_left", "aorta"]


def mod(addon, name):
    return importlib.import_module(f"{addon.__name__}.{name}")


def _run_map(key, addon, tmp_path_factory):
    """The decimated surfaces of one map (run as the command line runs)."""
    run = mod(addon, "app.flow.run")
    out = tmp_path_factory.mktemp(f"map{key}")
    recipe = run.Recipe(input=str(shared("totalsegmentator", MAPS[key])), out_dir=str(out),
                        decimate=0.5, formats=["glb"])
    return key, run.run(recipe)


def _to_scene(result, addon, scene):
    """The map's scan collection in ``scene`` at 960x540, lit as the headless run lights it."""
    headless = mod(addon, "addon.headless")
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    coll = headless.result_to_scene(bpy.context, result[1])
    headless.setup_look(scene, coll)
    return result[0], coll


@pytest.fixture(scope="module", params=sorted(MAPS))
def result(request, addon, tmp_path_factory):
    return _run_map(request.param, addon, tmp_path_factory)


@pytest.fixture(scope="module")
def sample_result(addon, tmp_path_factory):
    return _run_map("41", addon, tmp_path_factory)


@pytest.fixture
def scan(result, addon, empty_scene):
    """Each map's scan collection (framing and labels are checked on both maps)."""
    return _to_scene(result, addon, empty_scene)


@pytest.fixture
def sample_scan(sample_result, addon, empty_scene):
    """The 41-label sample's scan collection (renders: one map is enough)."""
    return _to_scene(sample_result, addon, empty_scene)


def hull_points(objs) -> np.ndarray:
    from mathutils import Matrix

    pts = []
    for o in objs:
        co = np.array([v.co[:] for v in o.data.vertices])
        m = np.array(Matrix(o.matrix_world))
        pts.append(co @ m[:3, :3].T + m[:3, 3])
    pts = np.concatenate(pts)
    return pts[ConvexHull(pts).vertices]


def camera_view(scene, cam, pts) -> np.ndarray:
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    bpy.context.view_layer.update()
    return np.array([world_to_camera_view(scene, cam, Vector(p))[:] for p in pts])


def test_every_preset_fills_the_frame(scan, addon):
    """>= 80 % of the width or the height, never outside the frame, for all seven presets."""
    cams, objects = mod(addon, "addon.scene.camera"), mod(addon, "addon.scene.objects")
    name, coll = scan
    scene = bpy.context.scene
    objs = objects.surface_objects(coll)
    pts = hull_points(objs)
    fills = {}
    for view in cams.VIEWS:
        cam = cams.frame_view(scene, objs, coll.anatomesh.space, view)
        p = camera_view(scene, cam, pts)
        assert p[:, :2].min() >= 0.0 and p[:, :2].max() <= 1.0 and p[:, 2].min() > 0, view
        fx, fy = np.ptp(p[:, 0]), np.ptp(p[:, 1])
        fills[view] = (round(fx, 3), round(fy, 3))
        assert max(fx, fy) >= 0.8, (view, fx, fy)
        assert abs(p[:, 0].min() - (1 - p[:, 0].max())) < 0.01  # centred
        assert abs(p[:, 1].min() - (1 - p[:, 1].max())) < 0.01
    print(f"fill (width, height) of the {name}-label map:", json.dumps(fills))


def test_views_look_from_the_named_side(scan, addon):
    """The liver (patient's right) and the spleen (left) where each view shows them."""
    cams, objects = mod(addon, "addon.scene.camera"), mod(addon, "addon.scene.objects")
    _, coll = scan
    scene = bpy.context.scene
    objs = objects.surface_objects(coll)
    liver, spleen = (bpy.data.objects[n] for n in ("liver", "spleen"))

    def where(view):
        cam = cams.frame_view(scene, objs, coll.anatomesh.space, view)
        return [camera_view(scene, cam, hull_points([o])).mean(0) for o in (liver, spleen)]

    (l, s) = where("anterior")
    assert l[0] < 0.5 < s[0]  # the patient's right on the image's left
    (l, s) = where("posterior")
    assert s[0] < 0.5 < l[0]
    (l, s) = where("lateral_left")
    assert s[2] < l[2]  # the spleen nearer the camera
    (l, s) = where("lateral_right")
    assert l[2] < s[2]
    (l, s) = where("inferior")
    assert l[0] < s[0]  # from the feet, the patient's right on the image's left


@pytest.mark.parametrize("space,elevation,azimuth", [("RAS", 0.0, 0.0), ("LPS", 30.0, -25.0)])
def test_a_torus_fills_exactly_the_asked_part(addon, empty_scene, space, elevation, azimuth):
    """An analytic shape: a ring of radius 200 + 50 mm seen from the front fills 0.9 of the
    width (500 mm across), every vertex inside the frame, however the camera is raised or turned."""
    from helpers.meshes import torus

    cams, objects = mod(addon, "addon.scene.camera"), mod(addon, "addon.scene.objects")
    v, f = torus(R=200.0, r=50.0)
    obj = objects.add_surface(objects.new_collection("scan"), "ring", (v + [30, -40, 700]).astype(np.float32), f,
                              {"anatomesh_value": 1})
    empty_scene.render.resolution_x, empty_scene.render.resolution_y = 640, 480
    cam = cams.frame_view(empty_scene, [obj], space, "anterior", elevation, azimuth)
    front = 1 if space == "RAS" else -1  # the patient's front: +y in RAS, -y in LPS
    assert (cam.location.y + 40) * front > 200
    assert (cam.location.z > 700 + 50) == (elevation > 0)
    p = camera_view(empty_scene, cam, hull_points([obj]))
    assert p[:, :2].min() >= 0 and p[:, :2].max() <= 1 and p[:, 2].min() > 0
    assert max(np.ptp(p[:, 0]), np.ptp(p[:, 1])) == pytest.approx(0.9, abs=1e-4)
    if elevation == 0:
        assert cam.data.ortho_scale == pytest.approx(500 / 0.9, rel=1e-3)


def test_lps_scenes_are_seen_from_the_same_side(addon):
    cams = mod(addon, "addon.scene.camera")
    flip = np.diag([-1.0, -1.0, 1.0])  # RAS <-> LPS
    for view in cams.VIEWS:
        ras, lps = cams.view_axes(view, "RAS"), cams.view_axes(view, "LPS")
        np.testing.assert_allclose(flip @ ras[0], lps[0], atol=1e-12)
        np.testing.assert_allclose(flip @ ras[1], lps[1], atol=1e-12)


def read_png(path) -> np.ndarray:
    """(H, W, 4) float RGBA, top row first."""
    img = bpy.data.images.load(str(path))
    w, h = img.size
    px = np.array(img.pixels[:], np.float32).reshape(h, w, 4)[::-1]
    bpy.data.images.remove(img)
    return px


def anatomy_mask(px: np.ndarray) -> np.ndarray:
    """Pixels unlike the background (the median of the border pixels)."""
    border = np.concatenate([px[0], px[-1], px[:, 0], px[:, -1]])[:, :3]
    return np.abs(px[..., :3] - np.median(border, 0)).max(-1) > 0.04


def test_render_fills_the_frame(sample_scan, addon, tmp_path):
    """A real small render: the pixels unlike the background span >= 80 % of the width or height,
    with background all around."""
    pictures = mod(addon, "addon.scene.pictures")
    _, coll = sample_scan
    scene = bpy.context.scene
    pictures.configure(scene, 2, (160, 90))
    for view in ("anterior", "lateral_left"):
        pictures.add_view(scene, coll, view)
        mask = anatomy_mask(read_png(pictures.render_still(scene, tmp_path / f"{view}.png")))
        rows, cols = np.nonzero(mask.sum(1) > 2)[0], np.nonzero(mask.sum(0) > 2)[0]  # not a stray pixel
        fx, fy = (cols[-1] - cols[0] + 1) / 160, (rows[-1] - rows[0] + 1) / 90
        assert max(fx, fy) >= 0.8, (view, fx, fy)
        assert cols[0] > 0 and rows[0] > 0 and cols[-1] < 159 and rows[-1] < 89  # a margin all round


def test_labels_stand_outside_apart_and_render(scan, addon, tmp_path):
    cams, labels = mod(addon, "addon.scene.camera"), mod(addon, "addon.scene.labels")
    pictures, objects = mod(addon, "addon.scene.pictures"), mod(addon, "addon.scene.objects")
    name, coll = scan
    scene = bpy.context.scene
    pictures.configure(scene, 2, (320, 180))
    cam = pictures.add_view(scene, coll, "anterior", LABELLED)
    lab = next(c for c in bpy.data.collections if c.get("anatomesh_camera") == cam.name)
    assert list(lab["anatomesh_hidden"]) == []
    assert all(o.parent == cam for o in lab.objects)
    boxes = labels.label_boxes(scene, cam, lab)
    assert sorted(boxes) == sorted(LABELLED)
    for kind in ("line", "dot"):
        assert sorted(o["anatomesh_label"] for o in lab.objects if o.name.endswith(kind)) == sorted(LABELLED)
    b = np.array(list(boxes.values()))
    assert b[:, :2].min() >= 0 and b[:, 2:].max() <= 1  # inside the frame
    for i in range(len(b)):
        for j in range(i + 1, len(b)):  # no two boxes overlap
            assert b[i, 2] <= b[j, 0] or b[j, 2] <= b[i, 0] or b[i, 3] <= b[j, 1] or b[j, 3] <= b[i, 1]
    anatomy = cams.projected(scene, cam, hull_points(objects.surface_objects(coll)))
    for box in b:  # beside the anatomy's silhouette (outside even its bounding box)
        assert box[2] < anatomy[:, 0].min() or box[0] > anatomy[:, 0].max()
    px = read_png(pictures.render_still(scene, tmp_path / "labelled.png"))
    h, w = px.shape[:2]
    for label, (x0, y0, x1, y1) in boxes.items():  # the letters are in the PNG, beside the anatomy
        region = anatomy_mask(px)[int((1 - y1) * h):int(np.ceil((1 - y0) * h)), int(x0 * w):int(np.ceil(x1 * w))]
        assert region.sum() >= 0.15 * region.size, label


def test_unknown_label_names_close_ones(scan, addon):
    labels, objects = mod(addon, "addon.scene.labels"), mod(addon, "addon.scene.objects")
    core_errors = mod(addon, "core.model.errors")
    with pytest.raises(core_errors.AnatomeshError, match="'livr'.*liver"):
        labels.find_structures(objects.surface_objects(scan[1]), ["livr"])


def test_turntable_writes_its_frames_and_video(sample_scan, addon, tmp_path):
    turntable, pictures = mod(addon, "addon.scene.turntable"), mod(addon, "addon.scene.objects")
    _, coll = sample_scan
    scene = bpy.context.scene
    mod(addon, "addon.scene.pictures").configure(scene, 1, (64, 36))
    cam = turntable.add_turntable(scene, pictures.surface_objects(coll), coll.anatomesh.space, 4)
    pts = hull_points(pictures.surface_objects(coll))
    for frame in range(1, 5):  # the whole anatomy in the frame at every angle, a quarter turn a frame
        scene.frame_set(frame)
        p = camera_view(scene, cam, pts)
        assert p[:, :2].min() >= 0 and p[:, :2].max() <= 1
        assert cam.parent.rotation_euler.z == pytest.approx((frame - 1) * np.pi / 2, abs=1e-5)
    frames = list(turntable.render_frames(scene, cam, tmp_path / "turntable"))
    assert [f.name for f in frames] == [f"frame_{i:04d}.png" for i in range(1, 5)]
    first, second = read_png(frames[0]), read_png(frames[1])
    assert anatomy_mask(first).any() and np.abs(first - second).max() > 0.1  # it turned
    video = turntable.encode_video(frames, tmp_path / "turntable.mp4")
    if turntable.can_encode_video():
        assert video is not None and video.read_bytes()[4:8] == b"ftyp"  # an MP4 container
    else:
        assert video is None


def test_command_line_views_labels_turntable(addon, tmp_path):
    """``anatomesh mesh --view anterior,lateral_left --labels-on liver --turntable 2``: a PNG per
    view and the frames, listed in report.json; the saved .blend renders the first PNG again."""
    cli = mod(addon, "app.cli")
    recipe = tmp_path / "small.toml"
    recipe.write_text("[output]\nrender_samples = 2\nrender_size = [96, 54]\n")
    out = tmp_path / "out"
    code = cli.main(["mesh", str(shared("totalsegmentator", "example_seg.nii.gz")), "--recipe", str(recipe),
                     "--out", str(out), "--labels", "liver,spleen,stomach,gallbladder", "--format", "blend,png",
                     "--view", "anterior,lateral_left", "--labels-on", "liver", "--turntable", "2"])
    assert code == 0
    rep = json.loads((out / "report.json").read_text())
    files = rep["files"]
    assert files["png_anterior"] == "example_seg_anterior.png"
    assert files["png_lateral_left"] == "example_seg_lateral_left.png"
    assert "png" not in files and files["turntable"] == "turntable"
    assert sorted(p.name for p in (out / "turntable").iterdir()) == ["frame_0001.png", "frame_0002.png"]
    turntable = mod(addon, "addon.scene.turntable")
    assert ("mp4" in files) == turntable.can_encode_video() == (out / "turntable.mp4").exists()
    for name in ("png_anterior", "png_lateral_left"):
        assert (out / files[name]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    views = rep["render"]["views"]
    assert views["anterior"]["labels"] == views["lateral_left"]["labels"] == ["liver"]
    assert max(views["anterior"]["fill"]) >= 0.8 and rep["render"]["turntable"]["frames"] == 2
    bpy.ops.wm.open_mainfile(filepath=str(out / "example_seg.blend"))
    scene = bpy.context.scene
    assert scene.camera.name == "Anatomesh Camera anterior"
    labels = [o for o in bpy.data.objects if o.get("anatomesh_label") == "liver" and o.type == "FONT"]
    assert sorted(o.parent.name for o in labels) == ["Anatomesh Camera anterior", "Anatomesh Camera lateral_left"]
    scene.render.filepath = str(tmp_path / "again.png")
    bpy.ops.render.render(write_still=True)
    again, written = read_png(tmp_path / "again.png"), read_png(out / files["png_anterior"])
    assert np.abs(again - written).mean() < 0.01


def test_operators_frame_label_and_turn(sample_scan, addon, tmp_path):
    """The panel's buttons: a view preset, labels on the selection, a small turntable."""
    _, coll = sample_scan
    scene = bpy.context.scene
    mod(addon, "addon.scene.pictures").configure(scene, 1, (64, 36))
    with pytest.raises(RuntimeError, match="set a view first"):  # the operator's one-line error
        bpy.ops.anatomesh.label_selected(collection=coll.name)
    assert bpy.ops.anatomesh.frame_camera(collection=coll.name, view="LATERAL_RIGHT") == {"FINISHED"}
    assert scene.camera.name == "Anatomesh Camera lateral_right" and scene.camera.data.type == "ORTHO"
    for o in bpy.data.objects:
        o.select_set(o.name in ("liver", "gallbladder"))
    assert bpy.ops.anatomesh.label_selected(collection=coll.name) == {"FINISHED"}
    texts = sorted(o["anatomesh_label"] for o in bpy.data.objects if o.type == "FONT")
    assert texts == ["gallbladder", "liver"]
    assert bpy.ops.anatomesh.render_turntable(collection=coll.name, frames=3, directory=str(tmp_path)) == {"FINISHED"}
    assert len(list((tmp_path / "turntable").glob("frame_*.png"))) == 3
    assert scene.camera.name == "Anatomesh Camera lateral_right"  # the view is back
