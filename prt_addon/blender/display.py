"""What the artist sees: the PRT colour attribute, and display materials that show it × albedo.

The colour attribute holds Σ_k L_k T_k (the radiance of a white surface), which Workbench's Attribute colour
shows as it is. Display materials multiply it per pixel by the albedo (the original material's Base Color
texture, or its Base Color) into an Emission of strength 1, so EEVEE shows exactly albedo · Σ_k L_k T_k.

Display materials replace an object's materials without losing them: the originals' names are kept in the
object's `_prt_original_materials` property and put back when the display is switched off or the add-on disabled.
"""

import bpy
import numpy as np

from ..core import shading
from . import materials
from .compat import new_node_material

DISPLAY_ATTRIBUTE = "prt_color"
DISPLAY_OF_KEY = "_prt_display_of"  # on a display material: the name of the material it stands for
ALBEDO_MIX = "PRT Albedo"  # the Mix node whose factor is the albedo switch
SHADED_IMAGE_KEY = "_prt_display_image"  # on a texel bake's display material: the shaded image it shows


# -- colours ----------------------------------------------------------------------------------------------------
def write_display_colours(mesh, transfer: np.ndarray, light: np.ndarray, corner_points=None):
    """Σ_k L_k T_k for transfer (P, n²) or (P, 3, n²) and light (3, n²) into a FLOAT_COLOR attribute, alpha 1:
    one product per shading point, written per vertex (POINT), or per face corner through `corner_points` (C,)
    where the bake is per corner.

    Negative values, which a ringing light gives, are clamped to black."""
    alpha_free = np.vstack([light, np.zeros((1, light.shape[1]))])  # a zero row: shade() fills four columns
    rgba = shading.shade(transfer, alpha_free)
    rgba[:, 3] = 1.0
    np.maximum(rgba, 0.0, out=rgba)
    domain = "POINT" if corner_points is None else "CORNER"
    if corner_points is not None:
        rgba = rgba[corner_points]
    write_colour_rows(mesh, rgba, domain)


def write_colour_rows(mesh, rgba: np.ndarray, domain: str):
    """(rows, 4) float32 RGBA into the display colour attribute, per vertex (POINT) or face corner (CORNER)."""
    _colour_attribute(mesh, domain).data.foreach_set("color", rgba.ravel())
    mesh.update_tag()  # a depsgraph tag only: no context needed, so it is safe from a render's frame handler


def _colour_attribute(mesh, domain):
    existing = mesh.color_attributes.get(DISPLAY_ATTRIBUTE)
    if existing is not None and (existing.data_type, existing.domain) != ("FLOAT_COLOR", domain):
        mesh.color_attributes.remove(existing)  # another layout's or someone else's: ours is recomputed anyway
        existing = None
    if existing is None:
        mesh.color_attributes.new(DISPLAY_ATTRIBUTE, "FLOAT_COLOR", domain)
        # The active colour is what Workbench's Attribute colour shows.
        mesh.color_attributes.active_color = mesh.color_attributes[DISPLAY_ATTRIBUTE]
    # Look it up again by name: adding a layer can invalidate earlier references.
    return mesh.color_attributes[DISPLAY_ATTRIBUTE]


# -- display materials ----------------------------------------------------------------------------------------
def is_shown(ob) -> bool:
    return materials.ORIGINALS_KEY in ob


def show(ob, texels=None):
    """Display materials in each of ob's slots (one new slot when it has none); the originals are remembered.
    texels: (shaded image name, UV map) for a texel bake, whose materials show that image instead of the colour
    attribute."""
    image = texels[0] if texels else ""
    if is_shown(ob):
        if all(slot.material is None or slot.material.get(SHADED_IMAGE_KEY, "") == image for slot in ob.material_slots):
            return
        restore(ob)  # baked the other way since it was shown
    originals = [slot.material for slot in ob.material_slots]
    ob[materials.ORIGINALS_KEY] = [material.name if material else "" for material in originals]
    if not originals:
        ob.data.materials.append(display_material(None, texels))
    for slot, original in zip(ob.material_slots, originals):
        slot.material = display_material(original, texels)


def restore(ob):
    """Puts ob's own materials back (removing the slot `show` added) and drops unused display materials."""
    names = list(ob[materials.ORIGINALS_KEY])
    shown = {slot.material for slot in ob.material_slots}
    if names:
        for slot, name in zip(ob.material_slots, names):
            slot.material = bpy.data.materials.get(name) if name else None
    else:
        ob.data.materials.clear()
    del ob[materials.ORIGINALS_KEY]
    for material in shown:
        if material is not None and DISPLAY_OF_KEY in material and material.users == 0:
            bpy.data.materials.remove(material)


def restore_all():
    for ob in bpy.data.objects:
        if is_shown(ob):
            restore(ob)


def set_albedo(use_albedo: bool):
    """The albedo switch: every display material multiplies by its albedo (factor 1) or not (factor 0)."""
    factor = 1.0 if use_albedo else 0.0
    for material in bpy.data.materials:
        if DISPLAY_OF_KEY not in material:
            continue
        switch = _socket(material.node_tree.nodes[ALBEDO_MIX].inputs, "Factor_Float")
        if switch.default_value != factor:
            switch.default_value = factor


def display_material(original, texels=None):
    """The display material standing for `original` (None: an object without material), made once; for a texel
    bake (texels: its shaded image's name and UV map), once per shaded image."""
    stands_for = original.name if original else ""
    image = texels[0] if texels else ""
    existing = next((m for m in bpy.data.materials
                     if m.get(DISPLAY_OF_KEY) == stands_for and m.get(SHADED_IMAGE_KEY, "") == image), None)
    name = (f"PRT {stands_for}" if original else "PRT Display") + (f" {image}" if image else "")
    return existing or _new_display_material(name, original, texels)


def _new_display_material(name, original, texels):
    material = new_node_material(name)
    material[DISPLAY_OF_KEY] = original.name if original else ""
    nodes, links = material.node_tree.nodes, material.node_tree.links
    colour = _shaded_image_node(material, *texels) if texels else nodes.new("ShaderNodeVertexColor")
    if not texels:
        colour.layer_name = DISPLAY_ATTRIBUTE
    mix = nodes.new("ShaderNodeMix")
    mix.name = ALBEDO_MIX
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    emission = nodes.new("ShaderNodeEmission")
    output = nodes.new("ShaderNodeOutputMaterial")
    for x, node in zip((-300, 0, 250, 450), (colour, mix, emission, output)):
        node.location = (x, 0)
    links.new(colour.outputs["Color"], _socket(mix.inputs, "A_Color"))
    links.new(_socket(mix.outputs, "Result_Color"), emission.inputs["Color"])
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    _socket(mix.inputs, "Factor_Float").default_value = 1.0
    _connect_albedo(material, _socket(mix.inputs, "B_Color"), original)
    return material


def _shaded_image_node(material, image_name, uv_map):
    """The texel bake's shaded image through its lightmap UV map, filtered linearly (its gutters hide seams)."""
    material[SHADED_IMAGE_KEY] = image_name
    nodes = material.node_tree.nodes
    image = nodes.new("ShaderNodeTexImage")
    image.image = bpy.data.images[image_name]
    image.interpolation = "Linear"
    image.extension = "EXTEND"
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = uv_map
    uv.location = (-550, 0)
    material.node_tree.links.new(uv.outputs["UV"], image.inputs["Vector"])
    return image


def _socket(sockets, identifier):
    """The Mix node has one socket per data type under the same name; identifiers tell them apart."""
    return next(socket for socket in sockets if socket.identifier == identifier)


def _connect_albedo(material, socket, original):
    """Feeds `socket` with the original's albedo (materials' rule): its Base Color texture, through the same UV
    map, or its value."""
    socket.default_value = (*materials.base_colour_value(original), 1.0)
    texture = materials.base_colour_texture(original)
    if texture is None:
        return
    nodes, links = material.node_tree.nodes, material.node_tree.links
    image = nodes.new("ShaderNodeTexImage")
    image.location = (-300, -250)
    for setting in ("image", "interpolation", "projection", "extension"):
        setattr(image, setting, getattr(texture, setting))
    links.new(image.outputs["Color"], socket)
    uv_map = materials.texture_uv_map(texture)
    if uv_map:
        uv = nodes.new("ShaderNodeUVMap")
        uv.location = (-550, -250)
        uv.uv_map = uv_map
        links.new(uv.outputs["UV"], image.inputs["Vector"])
