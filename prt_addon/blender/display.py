"""What the artist sees: the PRT colour attribute, and display materials that show it × albedo.

The colour attribute holds Σ_k L_k T_k (the radiance of a white surface), which Workbench's Attribute colour
shows as it is. Display materials multiply it per pixel by the albedo (the original material's Base Color
texture, or its Base Color) into an Emission of strength 1, so EEVEE shows exactly albedo · Σ_k L_k T_k.
Where a sun is split off an environment into a lamp, they add EEVEE's diffuse light (× the same albedo), which
draws that sun's sharp shadows; the World then lights camera rays only, since PRT carries its light.

Display materials replace an object's materials without losing them: the object keeps referencing its own
(materials.record_originals), so they survive saving, and they are put back when the display is switched off, the
bake cleared or the add-on disabled.
"""

import bpy
import numpy as np

from ..core import shading
from . import materials
from .compat import new_node_material

DISPLAY_ATTRIBUTE = "prt_color"
DISPLAY_OF_KEY = "_prt_display_of"  # on a display material: the name of the material it stands for
ALBEDO_MIX = "PRT Albedo"  # the Mix node whose factor is the albedo switch
DIFFUSE_ALBEDO_MIX = "PRT Diffuse Albedo"  # the same switch for the lamp's diffuse light
LAMP_SWITCH = "PRT Lamp"  # the Mix Shader adding EEVEE's diffuse light from a split-off sun's lamp (factor 1)
CAMERA_ONLY = "PRT Camera Only"  # the World's Mix Shader that keeps its light from everything but camera rays
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
    _write_points(mesh, rgba, corner_points)


def write_radiance(mesh, radiance: np.ndarray, corner_points=None):
    """Radiance (P, 3) already formed per shading point (a dynamic object lit per vertex through the probes) into
    the colour attribute, as write_display_colours writes its products."""
    rgba = np.ones((len(radiance), 4), dtype=np.float32)
    rgba[:, :3] = radiance
    _write_points(mesh, rgba, corner_points)


def _write_points(mesh, rgba, corner_points):
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
    materials.record_originals(ob)
    if not originals:
        ob.data.materials.append(display_material(None, texels))
    for slot, original in zip(ob.material_slots, originals):
        slot.material = display_material(original, texels)


def restore(ob):
    """Puts ob's own materials back (removing the slot `show` added) and drops unused display materials. Returns
    materials.lost_note (None when every original came back): a slot whose material the file lost stays empty."""
    originals = materials.original_materials(ob)
    lost = materials.lost_note(ob)
    shown = {slot.material for slot in ob.material_slots}
    if originals:
        for slot, original in zip(ob.material_slots, originals):
            slot.material = original
    else:
        ob.data.materials.clear()
    del ob[materials.ORIGINALS_KEY]
    for material in shown:
        if material is not None and DISPLAY_OF_KEY in material and material.users == 0:
            bpy.data.materials.remove(material)
    return lost


def restore_all():
    """Every object's own materials back (as `restore`) and every World as it was."""
    for ob in bpy.data.objects:
        if is_shown(ob):
            restore(ob)
    for world in bpy.data.worlds:
        if world.node_tree is not None:
            _world_for_camera_only(world.node_tree, False)


def set_albedo(use_albedo: bool):
    """The albedo switch: every display material multiplies by its albedo (factor 1) or not (factor 0)."""
    for material in _display_materials():
        for name in (ALBEDO_MIX, DIFFUSE_ALBEDO_MIX):
            _set_factor(material, name, "Factor_Float", use_albedo)


def set_lamp_light(scene, lamps: bool):
    """Adds EEVEE's diffuse light to every display material (a split-off sun shines), or not; with it, the World
    lights camera rays only, so that EEVEE does not light the display with what PRT already carries."""
    for material in _display_materials():
        _set_factor(material, LAMP_SWITCH, "Fac", lamps)
    if scene.world is not None and scene.world.node_tree is not None:
        _world_for_camera_only(scene.world.node_tree, lamps)


def _display_materials():
    return [material for material in bpy.data.materials if DISPLAY_OF_KEY in material]


def _set_factor(material, node_name, identifier, on: bool):
    node = material.node_tree.nodes.get(node_name)  # display materials of earlier versions lack the lamp's nodes
    if node is not None:
        switch = _socket(node.inputs, identifier)
        if switch.default_value != float(on):
            switch.default_value = float(on)


def _world_for_camera_only(tree, camera_only: bool):
    """Inserts (or takes out) a Mix Shader before the World Output: the World's surface for camera rays, nothing
    for the light it casts."""
    mix = tree.nodes.get(CAMERA_ONLY)
    output = next((node for node in tree.nodes if node.type == "OUTPUT_WORLD" and node.is_active_output), None)
    if output is None or camera_only == (mix is not None):
        return
    if camera_only:
        surface = output.inputs["Surface"].links[0].from_socket if output.inputs["Surface"].links else None
        mix = tree.nodes.new("ShaderNodeMixShader")
        mix.name = CAMERA_ONLY
        path = tree.nodes.new("ShaderNodeLightPath")
        path.name = f"{CAMERA_ONLY} Path"
        tree.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
        if surface is not None:
            tree.links.new(surface, mix.inputs[2])
        tree.links.new(mix.outputs["Shader"], output.inputs["Surface"])
    else:
        surface = mix.inputs[2].links[0].from_socket if mix.inputs[2].links else None
        tree.nodes.remove(tree.nodes[f"{CAMERA_ONLY} Path"])
        tree.nodes.remove(mix)
        if surface is not None:
            tree.links.new(surface, output.inputs["Surface"])


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
    for x, node in zip((-300, 0, 250, 650), (colour, mix, emission, output)):
        node.location = (x, 0)
    links.new(colour.outputs["Color"], _socket(mix.inputs, "A_Color"))
    links.new(_socket(mix.outputs, "Result_Color"), emission.inputs["Color"])
    _socket(mix.inputs, "Factor_Float").default_value = 1.0
    emitted, diffused = _with_lamp_light(material, emission.outputs["Emission"])
    _connect_albedo(material, [_socket(mix.inputs, "B_Color"), diffused], original)
    links.new(emitted, output.inputs["Surface"])
    return material


def _with_lamp_light(material, emission):
    """(emission + switch · Diffuse BSDF(albedo), the socket that takes the diffuse's albedo): EEVEE's light from a
    split-off sun's lamp; the switch (LAMP_SWITCH) starts off."""
    nodes, links = material.node_tree.nodes, material.node_tree.links
    albedo = nodes.new("ShaderNodeMix")  # white × albedo when the albedo switch is on, else white
    albedo.name = DIFFUSE_ALBEDO_MIX
    albedo.data_type, albedo.blend_type = "RGBA", "MULTIPLY"
    _socket(albedo.inputs, "A_Color").default_value = (1.0, 1.0, 1.0, 1.0)
    _socket(albedo.inputs, "Factor_Float").default_value = 1.0
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    both = nodes.new("ShaderNodeAddShader")
    switch = nodes.new("ShaderNodeMixShader")
    switch.name = LAMP_SWITCH
    switch.inputs["Fac"].default_value = 0.0
    for x, y, node in ((0, -500, albedo), (250, -500, diffuse), (450, -250, both), (450, 0, switch)):
        node.location = (x, y)
    links.new(_socket(albedo.outputs, "Result_Color"), diffuse.inputs["Color"])
    links.new(emission, both.inputs[0])
    links.new(diffuse.outputs["BSDF"], both.inputs[1])
    links.new(emission, switch.inputs[1])
    links.new(both.outputs["Shader"], switch.inputs[2])
    return switch.outputs["Shader"], _socket(albedo.inputs, "B_Color")


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


def _connect_albedo(material, sockets, original):
    """Feeds `sockets` with the original's albedo (materials' rule): its Base Color texture, through the same UV
    map (one texture node for all), or its value."""
    for socket in sockets:
        socket.default_value = (*materials.base_colour_value(original), 1.0)
    texture = materials.base_colour_texture(original)
    if texture is None:
        return
    nodes, links = material.node_tree.nodes, material.node_tree.links
    image = nodes.new("ShaderNodeTexImage")
    image.location = (-300, -250)
    for setting in ("image", "interpolation", "projection", "extension"):
        setattr(image, setting, getattr(texture, setting))
    for socket in sockets:
        links.new(image.outputs["Color"], socket)
    uv_map = materials.texture_uv_map(texture)
    if uv_map:
        uv = nodes.new("ShaderNodeUVMap")
        uv.location = (-550, -250)
        uv.uv_map = uv_map
        links.new(uv.outputs["UV"], image.inputs["Vector"])
