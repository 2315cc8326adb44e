"""The look of a scan in Blender: tissue-class node groups, cut surfaces, light presets, no speckle
where shells touch, and a saved .blend that renders its PNG again.

Expected values come from the label map itself (its border voxels), the style table and analytic
scenes; renders are judged by their pixels.
"""
from __future__ import annotations

import importlib

import bpy
import numpy as np
import pytest
from conftest import shared  # tests/conftest.py

from anatomesh.core import load

LABELS = ["liver", "gallbladder", "aorta", "vertebrae_L1", "lung_lower_lobe_right", "lung_upper_lobe_left"]


@pytest.fixture(scope="module")
def seg():
    return str(shared("totalsegmentator", "example_seg.nii.gz")), \
        str(shared("totalsegmentator", "label_names_total_and_total_mr.json"))


@pytest.fixture(scope="module")
def volume(seg):
    return load(seg[0], labels=seg[1])


@pytest.fixture
def mods(addon):
    """The enabled add-on's own modules: materials, lights, render gap, objects, style table."""
    get = lambda name: importlib.import_module(f"{addon.__name__}.{name}")  # noqa: E731
    return {k: get(v) for k, v in (("materials", "addon.scene.materials"), ("lights", "addon.scene.lights"),
                                    ("gap", "addon.scene.render_gap"), ("objects", "addon.scene.objects"),
                                    ("style", "core.model.style"))}


@pytest.fixture
def extracted(empty_scene, seg):
    """The Extract button on six structures of the sample, as extracted (no smoothing)."""
    assert bpy.ops.anatomesh.import_scan(filepath=seg[0], label_table=seg[1], extract=False) == {"FINISHED"}
    assert bpy.ops.anatomesh.extract(labels=", ".join(LABELS), smooth_method="NONE") == {"FINISHED"}
    coll = bpy.data.collections[empty_scene.anatomesh.last_collection]
    return {o.name: o for o in coll.all_objects if "anatomesh_value" in o}


def _border_voxel_faces(data: np.ndarray, value: int) -> int:
    return sum(int((np.take(data, i, axis=ax) == value).sum())
               for ax in range(3) for i in (0, data.shape[ax] - 1))


def _material_indices(obj) -> np.ndarray:
    out = np.zeros(len(obj.data.polygons), np.int32)
    obj.data.polygons.foreach_get("material_index", out)
    return out


# ---------------------------------------------------------------------------------------------
def test_extract_draws_each_structure_with_its_class_group(extracted, mods):
    mat, table = mods["materials"], mods["style"].default_style()
    assert sorted(extracted) == sorted(LABELS)
    groups = {}
    for name, obj in extracted.items():
        style = table.style_of(name)
        assert obj["anatomesh_tissue"] == style.material
        node = obj.data.materials[0].node_tree.nodes[mat.TISSUE_NODE]
        assert node.node_tree.name == mat.group_name(style.material)
        assert groups.setdefault(style.material, node.node_tree) is node.node_tree  # one group per class
        # opacity from the style table, see-through ones with oriented transparency
        assert obj["anatomesh_alpha"] == pytest.approx(style.opacity, abs=1e-6)
        assert obj["anatomesh_oriented"] == (1.0 if style.opacity < 1 else 0.0)
        assert obj.color[3] == pytest.approx(style.opacity, abs=1e-6)  # the Solid view's too
    assert extracted["lung_lower_lobe_right"]["anatomesh_alpha"] < 0.5 <= extracted["liver"]["anatomesh_alpha"]
    assert len(groups) >= 2


def test_tissue_groups_differ_as_tissues_do(empty_scene, mods):
    mat = mods["materials"]
    bsdf = {}
    for tissue in mods["style"].MATERIALS:
        group = mat.tissue_group(tissue)
        assert group is mat.tissue_group(tissue) and group.name == mat.group_name(tissue)
        p = next(n for n in group.nodes if n.type == "BSDF_PRINCIPLED")
        bsdf[tissue] = {k: p.inputs[k].default_value for k in ("Subsurface Weight", "Coat Weight", "Roughness")}
    assert bsdf["parenchyma"]["Subsurface Weight"] > bsdf["other"]["Subsurface Weight"] == 0.0
    assert bsdf["hollow"]["Coat Weight"] > bsdf["parenchyma"]["Coat Weight"]  # wet mucosa
    assert bsdf["bone"]["Roughness"] > bsdf["hollow"]["Roughness"] and bsdf["bone"]["Coat Weight"] == 0.0
    # a group the user edited is kept as it is
    p = next(n for n in mat.tissue_group("bone").nodes if n.type == "BSDF_PRINCIPLED")
    p.inputs["Roughness"].default_value = 0.123
    again = next(n for n in mat.tissue_group("bone").nodes if n.type == "BSDF_PRINCIPLED")
    assert again.inputs["Roughness"].default_value == pytest.approx(0.123)
    with pytest.raises(Exception, match="not one of"):
        mat.tissue_group("granite")


def test_cut_faces_get_the_cut_material(extracted, mods, volume):
    """Exactly the faces on the label map's border voxels (two triangles each) use slot 1, the
    structure's cut material; a structure inside the field of view has no cut slot."""
    mat = mods["materials"]
    data = np.asarray(volume.data)
    cut_structures = 0
    for name, obj in extracted.items():
        expected = 2 * _border_voxel_faces(data, int(obj["anatomesh_value"]))
        idx = _material_indices(obj)
        assert int((idx == 1).sum()) == expected, name
        if expected:
            cut_structures += 1
            cut = obj.data.materials[1]
            node = cut.node_tree.nodes[mat.CUT_NODE]
            assert node.node_tree.name == mat.CUT_GROUP
            assert mat.base_color(cut) == pytest.approx(mat.base_color(obj.data.materials[0]))
        else:
            assert len(obj.data.materials) == 1
    assert extracted["liver"].data.materials[1].name == "liver cut"
    assert len(extracted["gallbladder"].data.materials) == 1  # inside the scan
    assert cut_structures >= 4


def test_decimation_marks_the_new_cut_faces(extracted, empty_scene):
    """Apply Decimation makes new faces; those on the scan's boundary get the cut material again."""
    liver = extracted["liver"]
    inv = np.linalg.inv(np.reshape(list(liver["anatomesh_affine"]), (4, 4)))
    before = len(liver.data.polygons)
    assert bpy.ops.anatomesh.decimate_apply(collection=empty_scene.anatomesh.last_collection,
                                            target="RATIO", ratio=0.3) == {"FINISHED"}
    idx = _material_indices(liver)
    assert len(idx) < 0.5 * before and 0 < int((idx == 1).sum())
    v = np.array([tuple(x.co) for x in liver.data.vertices])
    tri = np.array([tuple(p.vertices) for p in liver.data.polygons])
    k = (v @ inv[:3, :3].T + inv[:3, 3])[tri[idx == 1]][..., 2]  # the slice index of each corner
    assert np.all((k < 0) | (k > liver["anatomesh_shape"][2] - 1))  # on the first or last slice's outer side


def test_set_tissue_operator(extracted, mods):
    mat = mods["materials"]
    liver, aorta = extracted["liver"], extracted["aorta"]
    before = aorta.data.materials[0].node_tree.nodes[mat.TISSUE_NODE].node_tree
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    bpy.context.view_layer.objects.active = None
    with pytest.raises(RuntimeError, match="no Anatomesh surface selected"):  # one clear line
        bpy.ops.anatomesh.set_tissue(tissue="hollow")
    liver.select_set(True)
    assert bpy.ops.anatomesh.set_tissue(tissue="hollow") == {"FINISHED"}
    node = liver.data.materials[0].node_tree.nodes[mat.TISSUE_NODE]
    assert node.node_tree.name == "Anatomesh Hollow" and liver["anatomesh_tissue"] == "hollow"
    assert aorta.data.materials[0].node_tree.nodes[mat.TISSUE_NODE].node_tree is before  # untouched
    assert liver.data.materials[1].node_tree.nodes[mat.CUT_NODE].node_tree.name == mat.CUT_GROUP
    aorta.select_set(True)
    assert bpy.ops.anatomesh.set_tissue(tissue="artery") == {"FINISHED"}
    trees = {o.data.materials[0].node_tree.nodes[mat.TISSUE_NODE].node_tree.name for o in (liver, aorta)}
    assert trees == {"Anatomesh Artery"}


def test_light_presets(extracted, mods):
    lights = mods["lights"]
    assert bpy.ops.anatomesh.frame_camera() == {"FINISHED"}
    sc = bpy.context.scene
    cam = np.array(sc.camera.matrix_world)
    right, to_cam = cam[:3, 0], cam[:3, 2]  # the camera's right and backward (toward the camera)
    box = mods["objects"].bounds(extracted.values())
    centre = box.mean(0)
    assert bpy.ops.anatomesh.apply_lights(preset="STUDIO") == {"FINISHED"}
    made = {o.name: o for o in sc.objects if o.type == "LIGHT"}
    assert sorted(made) == ["Anatomesh Fill", "Anatomesh Key", "Anatomesh Rim"]
    assert all(o.data.type == "AREA" for o in made.values())
    rel = {k.split()[-1]: np.array(o.location) - centre for k, o in made.items()}
    assert rel["Key"] @ right < 0 < rel["Fill"] @ right  # key on the camera's left, fill right
    assert rel["Key"][2] > 0 and rel["Rim"][2] > 0  # both from above
    assert rel["Rim"] @ to_cam < 0 < rel["Key"] @ to_cam  # the rim light behind the anatomy
    assert made["Anatomesh Fill"].data.energy < made["Anatomesh Key"].data.energy
    dark = tuple(sc.world.node_tree.nodes["Backdrop"].inputs["Color"].default_value)[:3]
    sc.anatomesh_recipe.light = "ATLAS"
    assert bpy.ops.anatomesh.apply_lights() == {"FINISHED"}  # "As set": the Settings panel's
    made = [o for o in sc.objects if o.type == "LIGHT"]
    assert [o.name for o in made] == ["Anatomesh Key"] and sc["anatomesh_light"] == "atlas"
    light = tuple(sc.world.node_tree.nodes["Backdrop"].inputs["Color"].default_value)[:3]
    assert min(light) > 0.5 > 0.1 > max(dark)
    with pytest.raises(Exception, match="not one of"):
        lights.apply_lights(sc, extracted.values(), "disco")


def _boxes_render(mods, gap: bool, path, engine: str) -> np.ndarray:
    """Two boxes sharing a face at scanner-like coordinates (mm), the front one see-through,
    seen through the front one, rendered by ``engine``; returns the RGB (H, W, 3) in 0..1."""
    import bmesh

    objects = mods["objects"]
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    objects.setup_units(sc)
    coll = objects.new_collection("boxes")
    offset = np.array([-213.7, 151.3, 912.9])
    for name, x0, colour, alpha in (("front", -40.0, (0.9, 0.2, 0.2), 0.3), ("back", 0.0, (0.2, 0.8, 0.2), 1.0)):
        bm = bmesh.new()
        bmesh.ops.create_cube(bm, size=1.0)
        bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=10, use_grid_fill=True)
        bmesh.ops.triangulate(bm, faces=bm.faces[:])
        v = np.array([tuple(x.co) for x in bm.verts])
        f = np.array([[x.index for x in t.verts] for t in bm.faces])
        v = (v + 0.5) * 40.0 + [x0, -20.0, -20.0] + offset
        obj = objects.add_surface(coll, name, v.astype(np.float32), f, {"anatomesh_value": 1,
                                  "anatomesh_alpha": alpha}, color=colour)
        if gap:
            mods["gap"].add_render_gap([obj], mods["gap"].gap_mm((1.5, 1.5, 3.0)))
    from mathutils import Vector

    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    sc.collection.objects.link(cam)
    sc.camera = cam
    cam.location = tuple(offset + [-150.0, -60.0, 40.0])
    cam.rotation_euler = (Vector(tuple(offset)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens, cam.data.clip_start, cam.data.clip_end = 80.0, 1.0, 1000.0
    mods["lights"].apply_lights(sc, coll.objects, "studio")
    sc.render.engine = engine
    sc.cycles.samples, sc.cycles.use_denoising, sc.cycles.use_adaptive_sampling = 32, False, False
    sc.render.resolution_x, sc.render.resolution_y = 120, 80
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], np.float32).reshape(80, 120, 4)[::-1, :, :3]
    bpy.data.images.remove(img)
    return px


@pytest.mark.parametrize("engine", ["CYCLES", "BLENDER_WORKBENCH"])  # renders; the Solid view
def test_no_speckle_where_shells_touch(addon, mods, tmp_path, engine):
    """Through the see-through box, the shared face is one even colour with the render gap; without
    it the two coincident faces fight (triangles of the front box's colour show through): the
    speckle is what a 5 x 5 median filter removes."""
    from scipy.ndimage import median_filter

    window = (slice(30, 60), slice(45, 75))  # the shared face's middle, seen through the front box
    speckle = {}
    for gap in (True, False):
        px = _boxes_render(mods, gap, tmp_path / f"boxes_{gap}.png", engine)
        green_minus_red = px[..., 1] - px[..., 0]
        residue = np.abs(green_minus_red - median_filter(green_minus_red, 5))[window]
        speckle[gap] = float(np.percentile(residue, 95))
    assert speckle[True] < 0.5 * speckle[False]
    assert speckle[True] < 0.08


def test_the_viewport_draws_the_gap_and_exports_read_the_shapes(addon, extracted, mods):
    """The viewport's evaluation moves each surface inward by the gap (so Solid view and Material
    Preview draw no z-fighting either); exports and print checks read the surfaces unmoved, and
    the gap is on again afterwards."""
    bridge = importlib.import_module(f"{addon.__name__}.addon.scene.bridge")
    export = importlib.import_module(f"{addon.__name__}.addon.operators.export")
    objs = list(extracted.values())
    gap = objs[0].modifiers[mods["gap"].GAP_MODIFIER].strength
    assert gap < 0 and all(o.modifiers[mods["gap"].GAP_MODIFIER].show_viewport for o in objs)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for o in objs:
        base, faces = bridge.world_arrays(o)
        drawn, drawn_faces = bridge.world_arrays(o, depsgraph)
        normals = np.empty(3 * len(o.data.vertices), np.float32)
        o.data.vertices.foreach_get("normal", normals)
        moved = np.einsum("ij,ij->i", drawn - base, normals.reshape(-1, 3))
        assert np.array_equal(faces, drawn_faces) and moved == pytest.approx(gap, abs=1e-4)
    shapes = bridge.shapes(bpy.context, objs)
    meshes = export.object_meshes(bpy.context, objs)
    for o, (v, f), m in zip(objs, shapes, meshes):
        base, faces = bridge.world_arrays(o)
        assert np.array_equal(v, base) and np.array_equal(m.vertices, base) and np.array_equal(f, faces)
        assert o.modifiers[mods["gap"].GAP_MODIFIER].show_viewport
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert not np.array_equal(bridge.world_arrays(objs[0], depsgraph)[0], bridge.world_arrays(objs[0])[0])


# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def made(addon, seg, tmp_path_factory):
    """The command line's run on four structures: blend + a small png in the atlas light."""
    core = importlib.import_module(addon.__name__ + ".app.flow.run")
    out = tmp_path_factory.mktemp("look")
    recipe = core.Recipe(input=seg[0], out_dir=str(out), labels=LABELS[:4] + LABELS[4:5],
                         formats=["blend", "png"], render_samples=8, render_size=[96, 54], light="atlas")
    return core.run(recipe), out


def test_saved_blend_renders_its_png_again(made, mods, tmp_path):
    result, out = made
    material = mods["materials"]
    bpy.ops.wm.open_mainfile(filepath=str(out / "example_seg.blend"))
    sc = bpy.context.scene
    surfaces = [o for o in sc.objects if "anatomesh_value" in o]
    assert len(surfaces) == 5
    for o in surfaces:
        node = o.data.materials[0].node_tree.nodes[material.TISSUE_NODE]
        assert node.node_tree.name == material.group_name(o["anatomesh_tissue"])
        assert mods["gap"].GAP_MODIFIER in o.modifiers
    assert sc["anatomesh_light"] == "atlas"
    sc.render.filepath = str(tmp_path / "again.png")
    bpy.ops.render.render(write_still=True)
    a, b = (bpy.data.images.load(str(p)) for p in (out / "example_seg.png", tmp_path / "again.png"))
    assert tuple(a.size) == tuple(b.size) == (96, 54)
    pa, pb = (np.array(i.pixels[:], np.float32).reshape(54, 96, 4)[..., :3] for i in (a, b))
    assert np.abs(pa - pb).mean() < 0.01  # the same engine, samples, lights and materials
    assert pa.mean() > 0.5  # the atlas's light backdrop
