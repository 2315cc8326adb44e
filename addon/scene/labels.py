"""Leader-line labels for one camera view: a structure's name beside the anatomy, a thin line to a
point of it the camera sees, and a dot there.

Layout: external labels in columns, as anatomical plates place them ("boundary labelling",
Bekos, Kaufmann, Symvonis & Wolff 2007, Computational Geometry 36(3); flush columns in 3D
illustrations, Ali, Hartmann & Strothotte 2005, Journal of WSCG 13): the labels stand in two
columns just outside the anatomy's projected bounding box, left and right, each on the side of
its anchor; within a column they keep their anchors' order from top to bottom and are pushed
apart greedily so no two overlap. The camera's frame is widened to hold the columns
(:func:`add_labels` re-aims it).

Everything is built in the camera's own coordinates and parented to the camera (text facing it,
the lines and dots on a plane in front of every surface), so the labels belong to that view and
travel with it; they sit in their own collection, ``Labels <camera>``, and render in emission
colours that stand out from the world's background.
"""
from __future__ import annotations

import difflib
from typing import Dict, List, Sequence, Tuple

import bpy
import numpy as np

from . import camera as cams

#: letter height as a fraction of the frame's height, gap between anatomy and text (letter heights)
TEXT_HEIGHT, GAP = 0.045, 1.0
#: rows of labels at least this many letter heights apart
ROW = 1.6
#: surfaces at least this opaque hide what is behind them (see-through organs do not)
OPAQUE = 0.5


def find_structures(objects: Sequence[bpy.types.Object], names: Sequence[str]) -> List[bpy.types.Object]:
    """The surface objects named ``names`` (their ``anatomesh_name`` or object name, any case).

    An unknown name raises :class:`AnatomeshError` naming the closest known ones."""
    from ...core.model.errors import AnatomeshError

    by_name = {str(o.get("anatomesh_name", o.name)).lower(): o for o in objects}
    by_name.update({o.name.lower(): o for o in objects if o.name.lower() not in by_name})
    out = []
    for name in names:
        key = str(name).strip().lower()
        if key not in by_name:
            close = difflib.get_close_matches(key, list(by_name), n=4, cutoff=0.5)
            hint = f"close names: {', '.join(close)}" if close else "no close name; see the scene's objects"
            raise AnatomeshError(f"no structure named {name!r} to label ({hint})")
        out.append(by_name[key])
    return out


def display_name(obj: bpy.types.Object) -> str:
    """The name a label shows: the structure's name, underscores as spaces."""
    return str(obj.get("anatomesh_name", obj.name)).replace("_", " ")


def anchor(scene: bpy.types.Scene, cam: bpy.types.Object, target: bpy.types.Object,
           samples: int = 400):
    """A point (3,) world mm on ``target`` the camera sees (rays from the image plane; see-through
    surfaces let them pass), near the middle of its seen part; None when it is hidden."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    pts = cams.world_points([target])
    rng = np.random.default_rng(0)
    pts = pts[rng.choice(len(pts), min(samples, len(pts)), replace=False)]
    forward = -np.array(cam.matrix_world, np.float64)[:3, 2]
    seen = []
    for p in pts:
        hit = _first_opaque_hit(scene, depsgraph, p - forward * (cam.data.clip_end * 2), forward)
        if hit is not None and hit[1] == target.name:
            seen.append(hit[0])
    if not seen:
        return None
    seen = np.array(seen)
    flat = cams.projected(scene, cam, seen)[:, :2]
    inner = np.linalg.norm(flat[:, None] - flat[None], axis=2).sum(1)  # the medoid: well inside
    return seen[int(np.argmin(inner))]


def _first_opaque_hit(scene, depsgraph, origin: np.ndarray, direction: np.ndarray):
    """``(location, object name)`` of the first surface at least :data:`OPAQUE` along the ray,
    or the first see-through one when nothing opaque is hit; None for a miss."""
    from mathutils import Vector

    o, first = Vector(origin), None
    d = Vector(direction)
    for _ in range(16):
        hit, loc, _, _, obj, _ = scene.ray_cast(depsgraph, o, d)
        if not hit:
            return first
        name = obj.original.name if obj is not None else ""
        if float(obj.original.get("anatomesh_alpha", 1.0)) >= OPAQUE:
            return np.array(loc), name
        first = first or (np.array(loc), name)
        o = loc + d * 0.01
    return first


def stack(wanted: Sequence[float], spacing: float, low: float, high: float) -> np.ndarray:
    """Heights for labels wanting ``wanted`` (top to bottom order kept), at least ``spacing`` apart
    and within [low, high] where they fit: pushed down from the top, then back up from the bottom."""
    order = np.argsort(-np.asarray(wanted, float))
    y = np.asarray(wanted, float)[order].copy()
    for i in range(len(y)):
        y[i] = min(y[i], high) if i == 0 else min(y[i], y[i - 1] - spacing)
    for i in range(len(y) - 1, -1, -1):
        y[i] = max(y[i], low) if i == len(y) - 1 else max(y[i], y[i + 1] + spacing)
    out = np.empty_like(y)
    out[order] = y
    return out


def ink(scene: bpy.types.Scene) -> Tuple[float, float, float, float]:
    """A label colour (linear RGBA) that stands out from the world's background colour."""
    color = (0.1, 0.1, 0.1)
    world = scene.world
    bg = world.node_tree.nodes.get("Background") if world is not None and world.node_tree else None
    if bg is not None:
        color = tuple(bg.inputs["Color"].default_value)[:3]
    light = 0.2126 * color[0] + 0.7152 * color[1] + 0.0722 * color[2] > 0.2
    return (0.02, 0.02, 0.02, 1.0) if light else (0.95, 0.95, 0.95, 1.0)


def emission_material(name: str, rgba) -> bpy.types.Material:
    """A material that shows ``rgba`` unlit (labels read the same under any light)."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = rgba
    em.inputs["Strength"].default_value = 1.0
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(em.outputs["Emission"], out.inputs["Surface"])
    mat.diffuse_color = rgba
    return mat


def add_labels(scene: bpy.types.Scene, cam: bpy.types.Object, objects: Sequence[bpy.types.Object],
               names: Sequence[str], fill: float = cams.FILL) -> bpy.types.Collection:
    """Label the structures ``names`` in the view of the orthographic ``cam`` (framed by
    :func:`~anatomesh.addon.scene.camera.frame_view`); re-aims the camera so the anatomy and the
    label columns fill ``fill`` of the frame. Replaces the camera's earlier labels; returns their
    collection. Structures the camera cannot see are left out (listed in the collection's
    ``anatomesh_hidden``)."""
    targets = find_structures(objects, names)
    remove_labels(cam)
    coll = bpy.data.collections.new(f"Labels {cam.name}")
    scene.collection.children.link(coll)
    coll["anatomesh_camera"] = cam.name
    found = [(t, anchor(scene, cam, t)) for t in targets]
    coll["anatomesh_hidden"] = [t.name for t, a in found if a is None]
    found = [(t, a) for t, a in found if a is not None]
    if not found:
        return coll
    m = np.array(cam.matrix_world, np.float64)
    to_cam, up = m[:3, 2], m[:3, 1]
    pts = cams.world_points(cams.visible(objects))
    right = np.cross(-to_cam, up)
    mid = 0.5 * ((pts @ right).min() + (pts @ right).max())
    left_side = [float(a @ right) < mid for _, a in found]
    texts = [_text(coll, cam, display_name(t), "RIGHT" if ls else "LEFT", t.name)
             for (t, _), ls in zip(found, left_side)]
    bpy.context.view_layer.update()
    widths = np.array([tx.dimensions.x for tx in texts])  # letters of size 1
    height = cams.frame_size(scene, cam.data.ortho_scale)[1]
    for _ in range(4):  # the letters scale with the frame, the frame with the columns
        size = TEXT_HEIGHT * height
        extra = [max([w for w, ls in zip(widths, left_side) if ls == side] or [-GAP]) * size + GAP * size
                 for side in (True, False)]
        cams.aim(cam, pts, to_cam, up, scene, fill, extra)
        height = cams.frame_size(scene, cam.data.ortho_scale)[1]
    _place(scene, cam, coll, texts, [a for _, a in found], left_side, pts, TEXT_HEIGHT * height)
    return coll


def _place(scene, cam, coll, texts, anchors, left_side, pts, size: float) -> None:
    """Put the texts in their columns, lines from them to their anchors, dots at the anchors
    (camera coordinates; the plane 2 mm in front of the nearest surface)."""
    inv = np.linalg.inv(np.array(cam.matrix_world, np.float64))
    local = pts @ inv[:3, :3].T + inv[:3, 3]
    ends = np.array(anchors) @ inv[:3, :3].T + inv[:3, 3]
    z = float(local[:, 2].max()) + 2.0
    fw, fh = cams.frame_size(scene, cam.data.ortho_scale)
    line = 1.6 * fw / max(1, scene.render.resolution_x)  # about 1.6 pixels wide
    ink_mat = emission_material("Anatomesh Label", ink(scene))
    for side in (True, False):
        idx = [i for i, ls in enumerate(left_side) if ls == side]
        if not idx:
            continue
        ys = stack([ends[i, 1] for i in idx], ROW * size, -fh / 2 + size, fh / 2 - size)
        x = local[:, 0].min() - GAP * size if side else local[:, 0].max() + GAP * size
        for i, y in zip(idx, ys):
            tx = texts[i]
            tx.scale = (size, size, size)  # the letters drawn at size 1: their bounds stay true
            tx.location = (x, y, z)
            start = np.array([x + (0.3 if side else -0.3) * size, y, z])
            end = np.array([ends[i, 0], ends[i, 1], z])
            _mesh(coll, cam, f"{tx.name} line", *_ribbon(start, end, line), ink_mat, tx["anatomesh_label"])
            _mesh(coll, cam, f"{tx.name} dot", *_disc(end, 2.2 * line), ink_mat, tx["anatomesh_label"])
    for tx in texts:
        tx.data.materials.clear()
        tx.data.materials.append(ink_mat)


def _text(coll, cam, body: str, align: str, label: str) -> bpy.types.Object:
    curve = bpy.data.curves.new(f"Label {label}", "FONT")
    curve.body, curve.align_x, curve.align_y, curve.size = body, align, "CENTER", 1.0
    obj = bpy.data.objects.new(f"Label {label}", curve)
    _attach(obj, coll, cam, label)
    return obj


def _attach(obj, coll, cam, label: str) -> None:
    from mathutils import Matrix

    coll.objects.link(obj)
    obj.parent = cam
    obj.matrix_parent_inverse = Matrix.Identity(4)
    obj["anatomesh_label"] = label
    obj.visible_shadow = False


def _mesh(coll, cam, name: str, verts: np.ndarray, faces: List, mat, label: str) -> bpy.types.Object:
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], faces)
    me.materials.append(mat)
    obj = bpy.data.objects.new(name, me)
    _attach(obj, coll, cam, label)
    return obj


def _ribbon(a: np.ndarray, b: np.ndarray, width: float):
    """A flat quad (camera plane) of ``width`` from ``a`` to ``b``."""
    d = (b - a)[:2]
    n = np.array([-d[1], d[0], 0.0]) / max(np.linalg.norm(d), 1e-9) * width / 2
    return np.array([a - n, b - n, b + n, a + n]), [(0, 1, 2, 3)]


def _disc(c: np.ndarray, radius: float, n: int = 20):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = c + radius * np.column_stack([np.cos(t), np.sin(t), np.zeros(n)])
    return np.vstack([c, ring]), [(0, 1 + i, 1 + (i + 1) % n) for i in range(n)]


def remove_labels(cam: bpy.types.Object) -> None:
    """Delete the labels of ``cam`` (their collection, objects and data)."""
    for coll in [c for c in bpy.data.collections if c.get("anatomesh_camera") == cam.name]:
        for obj in list(coll.objects):
            data = obj.data
            bpy.data.objects.remove(obj)
            if data is not None and data.users == 0:
                (bpy.data.curves if isinstance(data, bpy.types.Curve) else bpy.data.meshes).remove(data)
        bpy.data.collections.remove(coll)


def label_boxes(scene: bpy.types.Scene, cam: bpy.types.Object, coll: bpy.types.Collection) -> Dict[str, np.ndarray]:
    """Each text label's box in the image (x0, y0, x1, y1), fractions of the frame (0, 0 bottom left)."""
    from mathutils import Vector

    bpy.context.view_layer.update()
    out = {}
    for obj in coll.objects:
        if obj.type == "FONT":
            corners = np.array([obj.matrix_world @ Vector(c) for c in obj.bound_box])
            p = cams.projected(scene, cam, corners)
            out[obj["anatomesh_label"]] = np.array([p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max()])
    return out
