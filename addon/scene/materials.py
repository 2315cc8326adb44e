"""Tissue materials: one shared node group per tissue class, one material per structure.

Each tissue class of the style table (:data:`~anatomesh.core.model.style.MATERIALS`:
parenchyma, hollow, artery, vein, bone, ...) is a shader node group named
``Anatomesh <Class>`` (:func:`tissue_group`): inputs *Base Color* and *Alpha*, output *BSDF*.
Inside, a Principled BSDF with the class's look (:data:`TISSUE_PRESETS`): subsurface scattering
for solid organs, fat and cartilage (Jensen et al. 2001, "A practical model for subsurface light
transport"; Cycles' random walk), a glossy clear coat for the wet mucosa of hollow organs, vessels
and airways, a rough, dry surface for bone, and a faint noise in colour and bump (object
coordinates, mm) so surfaces do not look like plastic.

A structure's material holds that group (node named :data:`TISSUE_NODE`) with the structure's own
colour on *Base Color*, so editing a group in the node editor changes every structure of its
class, and :func:`set_tissue` switches a structure to another class by swapping the group.

The opacity comes from the object as before: its ``anatomesh_alpha`` property, mixed with the
oriented transparency of :func:`oriented_alpha_group` by ``anatomesh_oriented``
(:func:`alpha_from_object`), into the group's *Alpha*.

Cut surfaces (faces on the scan's field-of-view boundary, :mod:`anatomesh.core.geometry.cut_faces`)
get a second material of the same structure built on :func:`cut_group`: the colour lighter and
paler, matte, with thin diagonal hatching — the convention of a sectioned surface in anatomical
and technical drawing — so a viewer sees where the scan cut the organ.
"""
from __future__ import annotations

import math
from typing import Dict, Sequence

import bpy

from ...core.model.style import MATERIALS

ORIENTED_GROUP = "Anatomesh Oriented Alpha"
CUT_GROUP = "Anatomesh Cut Surface"
#: the name of the tissue group node inside a structure's material (and of the cut group node)
TISSUE_NODE = "Anatomesh Tissue"
CUT_NODE = "Anatomesh Cut"
#: custom property (object and material) naming the tissue class
TISSUE_PROPERTY = "anatomesh_tissue"
#: spacing of the hatching lines on cut surfaces (mm) by default, and as a fraction of the scan's
#: diagonal (:func:`hatch_spacing`): about 100 lines across the picture of a whole scan
HATCH_MM = 3.0
HATCH_FRACTION = 0.01

#: Principled BSDF settings of each tissue class. roughness, specular (IOR level), subsurface
#: weight, radius (R, G, B mean free path relative to) scale (mm), coat weight and roughness,
#: sheen weight; mottle: +/- fraction of the colour's value varied by noise; bump: strength of a
#: noise bump of feature size ``grain`` (mm).
TISSUE_PRESETS: Dict[str, Dict] = {
    "parenchyma": dict(roughness=0.45, specular=0.45, subsurface=0.35, radius=(1.0, 0.35, 0.2),
                       scale=2.5, coat=0.3, coat_roughness=0.25, sheen=0.0, mottle=0.06, bump=0.05,
                       grain=6.0),
    "hollow": dict(roughness=0.35, specular=0.5, subsurface=0.15, radius=(1.0, 0.5, 0.35), scale=1.5,
                   coat=0.6, coat_roughness=0.12, sheen=0.0, mottle=0.05, bump=0.08, grain=4.0),
    "artery": dict(roughness=0.3, specular=0.5, subsurface=0.1, radius=(1.0, 0.3, 0.2), scale=1.0,
                   coat=0.7, coat_roughness=0.08, sheen=0.0, mottle=0.03, bump=0.02, grain=5.0),
    "vein": dict(roughness=0.32, specular=0.5, subsurface=0.1, radius=(0.8, 0.4, 0.5), scale=1.0,
                 coat=0.7, coat_roughness=0.1, sheen=0.0, mottle=0.03, bump=0.02, grain=5.0),
    "bone": dict(roughness=0.6, specular=0.35, subsurface=0.12, radius=(1.0, 0.8, 0.6), scale=1.0,
                 coat=0.0, coat_roughness=0.3, sheen=0.0, mottle=0.08, bump=0.15, grain=2.0),
    "cartilage": dict(roughness=0.28, specular=0.5, subsurface=0.5, radius=(0.8, 0.85, 1.0),
                      scale=2.0, coat=0.5, coat_roughness=0.12, sheen=0.0, mottle=0.04, bump=0.03,
                      grain=4.0),
    "muscle": dict(roughness=0.5, specular=0.4, subsurface=0.2, radius=(1.0, 0.3, 0.2), scale=2.0,
                   coat=0.25, coat_roughness=0.25, sheen=0.1, mottle=0.08, bump=0.1, grain=3.0),
    "fat": dict(roughness=0.38, specular=0.45, subsurface=0.45, radius=(1.0, 0.9, 0.5), scale=3.0,
                coat=0.3, coat_roughness=0.2, sheen=0.0, mottle=0.06, bump=0.08, grain=5.0),
    "nerve": dict(roughness=0.45, specular=0.4, subsurface=0.3, radius=(1.0, 1.0, 0.8), scale=1.0,
                  coat=0.2, coat_roughness=0.2, sheen=0.4, mottle=0.03, bump=0.03, grain=2.0),
    "lesion": dict(roughness=0.55, specular=0.4, subsurface=0.15, radius=(1.0, 0.5, 0.4), scale=1.5,
                   coat=0.1, coat_roughness=0.3, sheen=0.0, mottle=0.1, bump=0.12, grain=3.0),
    "airway": dict(roughness=0.32, specular=0.5, subsurface=0.2, radius=(1.0, 0.6, 0.5), scale=1.0,
                   coat=0.6, coat_roughness=0.1, sheen=0.0, mottle=0.04, bump=0.04, grain=3.0),
    "skin": dict(roughness=0.5, specular=0.4, subsurface=0.4, radius=(1.0, 0.4, 0.25), scale=2.0,
                 coat=0.1, coat_roughness=0.3, sheen=0.2, mottle=0.05, bump=0.06, grain=2.0),
    "other": dict(roughness=0.45, specular=0.5, subsurface=0.0, radius=(1.0, 0.5, 0.3), scale=1.0,
                  coat=0.15, coat_roughness=0.2, sheen=0.0, mottle=0.0, bump=0.0, grain=5.0),
}
assert tuple(TISSUE_PRESETS) == MATERIALS, "one preset per tissue class of the style table"

#: the classes as Blender enum items (identifier, name, description)
TISSUE_ITEMS = tuple((m, m.capitalize(), f"Draw as {m} (node group 'Anatomesh {m.capitalize()}')")
                     for m in MATERIALS)


def group_name(tissue: str) -> str:
    """The node group name of a tissue class (``"hollow"`` → ``"Anatomesh Hollow"``)."""
    return f"Anatomesh {tissue.capitalize()}"


def check_tissue(tissue: str) -> str:
    """``tissue`` if it is a class of :data:`MATERIALS`, else :class:`AnatomeshError`."""
    if tissue not in TISSUE_PRESETS:
        from ...core.model.errors import AnatomeshError

        raise AnatomeshError(f"tissue class {tissue!r} is not one of {', '.join(MATERIALS)}")
    return tissue


# ---------------------------------------------------------------------------------------------
# the shared node groups
# ---------------------------------------------------------------------------------------------
def _new_shader_group(name: str) -> bpy.types.ShaderNodeTree:
    """An empty shader group with inputs Base Color, Alpha and output BSDF."""
    ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
    s = ng.interface.new_socket("Base Color", in_out="INPUT", socket_type="NodeSocketColor")
    s.default_value = (0.8, 0.8, 0.8, 1.0)
    s = ng.interface.new_socket("Alpha", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 1.0, 0.0, 1.0
    ng.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    return ng


def _existing(name: str):
    ng = bpy.data.node_groups.get(name)
    return ng if ng is not None and ng.bl_idname == "ShaderNodeTree" else None


def tissue_group(tissue: str) -> bpy.types.ShaderNodeTree:
    """The node group of a tissue class, made once per file; an existing group of that name
    (perhaps edited by the user) is used as it is."""
    check_tissue(tissue)
    ng = _existing(group_name(tissue))
    if ng is not None:
        return ng
    p = TISSUE_PRESETS[tissue]
    ng = _new_shader_group(group_name(tissue))
    nodes, links = ng.nodes, ng.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    gin.location, gout.location = (-900, 0), (400, 0)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.location = (50, 0)
    values = {"Roughness": p["roughness"], "Specular IOR Level": p["specular"],
              "Subsurface Weight": p["subsurface"], "Subsurface Radius": p["radius"],
              "Subsurface Scale": p["scale"], "Coat Weight": p["coat"],
              "Coat Roughness": p["coat_roughness"], "Sheen Weight": p["sheen"]}
    for key, value in values.items():
        if key in bsdf.inputs:
            bsdf.inputs[key].default_value = value
    links.new(gin.outputs["Alpha"], bsdf.inputs["Alpha"])
    links.new(bsdf.outputs["BSDF"], gout.inputs["BSDF"])
    # a faint noise (object coordinates: mm) in the colour's value and in the bump
    coords = nodes.new("ShaderNodeTexCoord")
    coords.location = (-900, -250)
    noise = nodes.new("ShaderNodeTexNoise")
    noise.location = (-700, -250)
    noise.inputs["Scale"].default_value = 1.0 / p["grain"]
    noise.inputs["Detail"].default_value = 3.0
    links.new(coords.outputs["Object"], noise.inputs["Vector"])
    shade = nodes.new("ShaderNodeMath")  # value factor 1 + m - 2 m noise, in [1 - m, 1 + m]
    shade.operation, shade.location = "MULTIPLY_ADD", (-450, -100)
    links.new(noise.outputs["Fac"], shade.inputs[0])
    shade.inputs[1].default_value = -2.0 * p["mottle"]
    shade.inputs[2].default_value = 1.0 + p["mottle"]
    hsv = nodes.new("ShaderNodeHueSaturation")
    hsv.location = (-250, 50)
    links.new(shade.outputs["Value"], hsv.inputs["Value"])
    links.new(gin.outputs["Base Color"], hsv.inputs["Color"])
    links.new(hsv.outputs["Color"], bsdf.inputs["Base Color"])
    bump = nodes.new("ShaderNodeBump")
    bump.location = (-250, -300)
    bump.inputs["Strength"].default_value = p["bump"]
    bump.inputs["Distance"].default_value = 0.3  # mm
    links.new(noise.outputs["Fac"], bump.inputs["Height"])
    links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return ng


def cut_group() -> bpy.types.ShaderNodeTree:
    """The cut-surface group: the base colour paler and lighter, matte, with thin diagonal
    hatching *Spacing* mm apart (object coordinates); no subsurface, no coat."""
    ng = _existing(CUT_GROUP)
    if ng is not None:
        return ng
    ng = _new_shader_group(CUT_GROUP)
    spacing = ng.interface.new_socket("Spacing", in_out="INPUT", socket_type="NodeSocketFloat")
    spacing.default_value, spacing.min_value, spacing.max_value = HATCH_MM, 0.1, 1000.0
    nodes, links = ng.nodes, ng.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    gin.location, gout.location = (-900, 0), (400, 0)
    pale = nodes.new("ShaderNodeHueSaturation")
    pale.location = (-600, 100)
    pale.inputs["Saturation"].default_value = 0.7
    pale.inputs["Value"].default_value = 1.25
    links.new(gin.outputs["Base Color"], pale.inputs["Color"])
    coords = nodes.new("ShaderNodeTexCoord")
    coords.location = (-900, -250)
    wave = nodes.new("ShaderNodeTexWave")  # bands along x + y + z: sin(10 * scale * (x + y + z))
    wave.location = (-700, -250)
    wave.wave_type, wave.bands_direction = "BANDS", "DIAGONAL"
    scale = nodes.new("ShaderNodeMath")  # lines Spacing mm apart: scale = 2 pi / (10 sqrt(2) Spacing)
    scale.operation, scale.location = "DIVIDE", (-900, -50)
    scale.inputs[0].default_value = 2.0 * math.pi / (10.0 * math.sqrt(2.0))
    links.new(gin.outputs["Spacing"], scale.inputs[1])
    links.new(scale.outputs["Value"], wave.inputs["Scale"])
    wave.inputs["Distortion"].default_value = 0.0
    wave.inputs["Detail"].default_value = 0.0
    links.new(coords.outputs["Object"], wave.inputs["Vector"])
    line = nodes.new("ShaderNodeMapRange")  # thin lines where the wave peaks
    line.location = (-500, -250)
    line.inputs["From Min"].default_value, line.inputs["From Max"].default_value = 0.7, 0.9
    links.new(wave.outputs["Fac"], line.inputs["Value"])
    ink = nodes.new("ShaderNodeMix")
    ink.data_type, ink.blend_type, ink.location = "RGBA", "MULTIPLY", (-250, 50)
    links.new(line.outputs["Result"], ink.inputs["Factor"])
    links.new(pale.outputs["Color"], ink.inputs["A"])
    ink.inputs["B"].default_value = (0.72, 0.72, 0.72, 1.0)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.location = (50, 0)
    bsdf.inputs["Roughness"].default_value = 0.8
    bsdf.inputs["Specular IOR Level"].default_value = 0.25
    links.new(ink.outputs["Result"], bsdf.inputs["Base Color"])
    links.new(gin.outputs["Alpha"], bsdf.inputs["Alpha"])
    links.new(bsdf.outputs["BSDF"], gout.inputs["BSDF"])
    return ng


def oriented_alpha_group() -> bpy.types.ShaderNodeTree:
    """The shared node group: ``Alpha out = mix(Alpha, Edge Alpha, Facing)``.

    Inputs: *Alpha* (opacity facing the viewer), *Edge Alpha* (opacity at the silhouette, default
    1), *Blend* (Layer Weight blend, 0..1: larger = wider opaque rim). Created once per file; an
    existing group of that name (perhaps edited by the user) is reused as is.
    """
    ng = _existing(ORIENTED_GROUP)
    if ng is not None:
        return ng
    ng = bpy.data.node_groups.new(ORIENTED_GROUP, "ShaderNodeTree")
    iface = ng.interface
    s = iface.new_socket("Alpha", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 0.3, 0.0, 1.0
    s = iface.new_socket("Edge Alpha", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 1.0, 0.0, 1.0
    s = iface.new_socket("Blend", in_out="INPUT", socket_type="NodeSocketFloat")
    s.default_value, s.min_value, s.max_value = 0.35, 0.0, 1.0
    iface.new_socket("Alpha", in_out="OUTPUT", socket_type="NodeSocketFloat")
    nodes, links = ng.nodes, ng.links
    gin = nodes.new("NodeGroupInput")
    gin.location = (-500, 0)
    gout = nodes.new("NodeGroupOutput")
    gout.location = (300, 0)
    lw = nodes.new("ShaderNodeLayerWeight")
    lw.location = (-250, -150)
    links.new(gin.outputs["Blend"], lw.inputs["Blend"])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "FLOAT"
    mix.clamp_factor = True
    mix.location = (50, 0)
    links.new(lw.outputs["Facing"], mix.inputs["Factor"])
    links.new(gin.outputs["Alpha"], mix.inputs["A"])
    links.new(gin.outputs["Edge Alpha"], mix.inputs["B"])
    links.new(mix.outputs["Result"], gout.inputs["Alpha"])
    return ng


# ---------------------------------------------------------------------------------------------
# a structure's materials
# ---------------------------------------------------------------------------------------------
def organ_material(name: str, rgba: Sequence[float], tissue: str,
                   render_method: str = "DITHERED") -> bpy.types.Material:
    """A new material ``name``: the tissue group of ``tissue`` with base colour ``rgba``
    (linear), opacity from the object (:func:`alpha_from_object`)."""
    mat = _group_material(name, tissue_group(check_tissue(tissue)), TISSUE_NODE, rgba, render_method)
    mat[TISSUE_PROPERTY] = tissue
    return mat


def cut_material(name: str, rgba: Sequence[float], render_method: str = "DITHERED",
                 spacing_mm: float = HATCH_MM) -> bpy.types.Material:
    """A new material ``name`` for a structure's cut surface: :func:`cut_group` in colour ``rgba``,
    hatching lines ``spacing_mm`` apart."""
    mat = _group_material(name, cut_group(), CUT_NODE, rgba, render_method)
    mat.node_tree.nodes[CUT_NODE].inputs["Spacing"].default_value = float(spacing_mm)
    return mat


def hatch_spacing(affine, shape) -> float:
    """Hatching spacing (mm) for a scan: :data:`HATCH_FRACTION` of its diagonal, at least 1 mm."""
    import numpy as np

    size = np.linalg.norm(np.asarray(affine, float)[:3, :3] @ np.asarray(shape, float))
    return max(1.0, HATCH_FRACTION * float(size))


def _group_material(name, group, node_name, rgba, render_method) -> bpy.types.Material:
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    mat.diffuse_color = tuple(rgba)  # viewport Solid mode "Material" colour
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for node in [n for n in nodes if n.type != "OUTPUT_MATERIAL"]:
        nodes.remove(node)
    out = next((n for n in nodes if n.type == "OUTPUT_MATERIAL"), None) or \
        nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    node = nodes.new("ShaderNodeGroup")
    node.node_tree, node.name, node.label, node.location = group, node_name, group.name, (0, 0)
    node.inputs["Base Color"].default_value = tuple(rgba)
    links.new(alpha_from_object(nodes, links), node.inputs["Alpha"])
    links.new(node.outputs["BSDF"], out.inputs["Surface"])
    render_settings(mat, render_method)
    return mat


def alpha_from_object(nodes, links) -> bpy.types.NodeSocket:
    """Nodes giving mix(object ``anatomesh_alpha``, oriented alpha, object ``anatomesh_oriented``);
    returns that output socket."""
    alpha = _object_attribute(nodes, "anatomesh_alpha", (-700, -200))
    oriented_on = _object_attribute(nodes, "anatomesh_oriented", (-700, -420))
    group = nodes.new("ShaderNodeGroup")
    group.node_tree = oriented_alpha_group()
    group.location = (-480, -260)
    links.new(alpha.outputs["Fac"], group.inputs["Alpha"])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "FLOAT"
    mix.location = (-260, -300)
    links.new(oriented_on.outputs["Fac"], mix.inputs["Factor"])
    links.new(alpha.outputs["Fac"], mix.inputs["A"])
    links.new(group.outputs["Alpha"], mix.inputs["B"])
    return mix.outputs["Result"]


def _object_attribute(nodes, name: str, location) -> bpy.types.Node:
    node = nodes.new("ShaderNodeAttribute")
    node.attribute_type = "OBJECT"
    node.attribute_name = name
    node.label = name
    node.location = location
    return node


def render_settings(mat: bpy.types.Material, method: str) -> None:
    """Transparency that works for surfaces nested inside each other (EEVEE 4.2+; Cycles needs none)."""
    if hasattr(mat, "surface_render_method"):  # Blender 4.2+
        mat.surface_render_method = method if method in ("DITHERED", "BLENDED") else "DITHERED"
        # BLENDED: show the back faces too and sort them within the object
        mat.use_transparency_overlap = True
    else:  # pragma: no cover - Blender < 4.2
        mat.blend_method = "BLEND" if method == "BLENDED" else "HASHED"
        mat.show_transparent_back = True
    mat.use_backface_culling = False
    if hasattr(mat, "use_transparent_shadow"):
        mat.use_transparent_shadow = True


# ---------------------------------------------------------------------------------------------
# reading and switching
# ---------------------------------------------------------------------------------------------
def tissue_node(mat: bpy.types.Material):
    """The tissue group node of a structure's material, or None (a material made elsewhere)."""
    if mat is None or mat.node_tree is None:
        return None
    return mat.node_tree.nodes.get(TISSUE_NODE)


def base_color(mat: bpy.types.Material) -> tuple:
    """The linear RGBA base colour of a structure's material (its tissue or cut group's input;
    the viewport colour of a material made elsewhere)."""
    node = tissue_node(mat) or (mat.node_tree.nodes.get(CUT_NODE) if mat.node_tree else None)
    return tuple(node.inputs["Base Color"].default_value) if node is not None else tuple(mat.diffuse_color)


def set_tissue(objects, tissue: str) -> int:
    """Draw ``objects`` as tissue class ``tissue``: their structure materials use that class's
    group; sets the ``anatomesh_tissue`` property of object and material. Returns how many
    objects changed (those without an Anatomesh material are left alone)."""
    group = tissue_group(check_tissue(tissue))
    changed = 0
    for obj in objects:
        mats = [m for m in getattr(obj.data, "materials", []) if tissue_node(m) is not None]
        for mat in mats:
            tissue_node(mat).node_tree = group
            mat[TISSUE_PROPERTY] = tissue
        if mats:
            obj[TISSUE_PROPERTY] = tissue
            changed += 1
    return changed


def tissue_for(name: str, material=None) -> str:
    """The tissue class of a structure: ``material`` (a mesh's ``meta["material"]``, from the
    style table it was made with) when it is a class, else the default style table's class of
    ``name`` (:meth:`~anatomesh.core.model.style.StyleTable.style_of`)."""
    if material in TISSUE_PRESETS:
        return str(material)
    from ...core.model.style import default_style

    return default_style().style_of(str(name)).material
