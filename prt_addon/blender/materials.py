"""What the materials say: the base colour (albedo) and subsurface settings that the bake, the display and the
validation read, found by one rule.

The rule: the shader that renders is the one linked to the material output's Surface; its albedo is its Base Color
(Principled) or Color (Diffuse, and other BSDFs) input: an Image Texture, read through the UV map its Vector input
names (the active render UV map when none), a Color Attribute, or the input's value. A material without nodes, or
whose surface shader has no such input, shows its viewport colour. An object without a material renders
DEFAULT_ALBEDO.

While the PRT display shows, display materials stand in for an object's own: `original_materials` gives the
object's own in either case. The object holds them meanwhile (ORIGINALS_KEY references each one), so they keep a user
and saving the file keeps them; a file whose record names a material it no longer holds gets `lost_note`.
"""

import bpy
import numpy as np

from ..core.colour import srgb_to_linear
from .mesh_arrays import mesh_corner_vertices

DEFAULT_ALBEDO = (0.8, 0.8, 0.8)  # what Blender renders a mesh without material with
# On an object while the display is shown: per slot, its own material (an ID reference, a real user) or "" for an
# empty slot. A name instead of a reference is read by name (files whose record holds names).
ORIGINALS_KEY = "_prt_original_materials"


def record_originals(ob):
    """Remembers ob's own materials, slot by slot, holding a reference to each."""
    ob[ORIGINALS_KEY] = [slot.material or "" for slot in ob.material_slots]


def original_materials(ob) -> list:
    """ob's own materials per slot, also while display materials stand in for them; None for an empty slot or a
    material the file no longer holds (`lost_note` names those)."""
    if ORIGINALS_KEY in ob:
        return [_recorded(entry) for entry in ob[ORIGINALS_KEY]]
    return [slot.material for slot in ob.material_slots]


def _recorded(entry):
    """A recorded original: the material referenced, or the one of that name; None for "", or one gone."""
    if isinstance(entry, str):
        return bpy.data.materials.get(entry) if entry else None
    return entry  # a reference, None once its material was deleted


def lost_note(ob):
    """One sentence naming the recorded originals of ob that the file no longer holds, or None. They are left out:
    their slots stay empty and the default albedo stands in for them."""
    if ORIGINALS_KEY not in ob:
        return None
    lost = [repr(entry) if isinstance(entry, str) else "(deleted)" for entry in ob[ORIGINALS_KEY]
            if entry != "" and _recorded(entry) is None]
    if not lost:
        return None
    return (f"{ob.name!r}: the PRT display stands in for material {', '.join(lost)}, which is not in this file; "
            f"left out (the default albedo in its place): assign the object its material again")


def surface_shader(material):
    """The shader node linked to the material output's Surface, or None."""
    if material is None or material.node_tree is None:
        return None
    output = material.node_tree.get_output_node("ALL")
    links = output.inputs["Surface"].links if output else ()
    return links[0].from_node if links else None


def base_colour_input(material):
    """The surface shader's Base Color or Color input socket, or None (then the viewport colour applies)."""
    shader = surface_shader(material)
    return shader and (shader.inputs.get("Base Color") or shader.inputs.get("Color"))


def base_colour_value(material) -> tuple:
    """The albedo where no texture or attribute varies it: the input's value, else the viewport colour."""
    if material is None:
        return DEFAULT_ALBEDO
    socket = base_colour_input(material)
    return tuple(socket.default_value[:3]) if socket is not None else tuple(material.diffuse_color[:3])


def base_colour_source(material):
    """The node feeding the base colour (an Image Texture with an image, a Color Attribute, or another node), or
    None when the value applies."""
    socket = base_colour_input(material)
    return socket.links[0].from_node if socket is not None and socket.links else None


def base_colour_texture(material):
    """The Image Texture node (with an image) giving the base colour, or None."""
    source = base_colour_source(material)
    return source if source is not None and source.type == "TEX_IMAGE" and source.image is not None else None


def texture_uv_map(texture) -> str:
    """The UV map a UV Map node on the texture's Vector input names; "" for the default, the active render one."""
    links = texture.inputs["Vector"].links
    return links[0].from_node.uv_map if links and links[0].from_node.type == "UVMAP" else ""


def uv_layer(mesh, name: str):
    """The mesh's UV map of that name, or its active render UV map for "" (what a texture without UVs reads)."""
    if name:
        return mesh.uv_layers.get(name)
    return next((layer for layer in mesh.uv_layers if layer.active_render), mesh.uv_layers.active)


def subsurface_material(ob):
    """(weight, mean free path RGB, albedo RGB, IOR) of the object's first material whose surface shader is a
    Principled BSDF with Subsurface Weight > 0, or None. The mean free path is Subsurface Radius × Subsurface
    Scale, in scene units."""
    for material in original_materials(ob):
        node = surface_shader(material)
        if node is not None and node.type == "BSDF_PRINCIPLED" and node.inputs["Subsurface Weight"].default_value > 0:
            inputs = node.inputs
            return (float(inputs["Subsurface Weight"].default_value),
                    np.array(inputs["Subsurface Radius"].default_value[:3]) * inputs["Subsurface Scale"].default_value,
                    np.array(inputs["Base Color"].default_value[:3]), float(inputs["IOR"].default_value))
    return None


# -- albedo per vertex or shading point -----------------------------------------------------------------------
def vertex_albedo(ob, mesh, notes: list, corner_points=None, point_count=None) -> np.ndarray:
    """(V, 3) linear albedo per vertex of `mesh` (the object's mesh or its evaluated mesh): each face corner's base
    colour, averaged over the corners of each vertex; or (P, 3) per shading point, given each corner's point."""
    corner_vertex = mesh_corner_vertices(mesh)
    groups = corner_vertex if corner_points is None else corner_points
    count = len(mesh.vertices) if corner_points is None else point_count
    face_material = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("material_index", face_material)
    face_sizes = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_total", face_sizes)
    corner_material = np.repeat(face_material, face_sizes)
    corner_colour = np.tile(np.array(DEFAULT_ALBEDO), (len(corner_vertex), 1))
    if (lost := lost_note(ob)) is not None:
        notes.append(lost)
    for slot_index, material in enumerate(original_materials(ob)):
        corners = corner_material == slot_index
        if material is not None and corners.any():
            corner_colour[corners] = _material_colours(ob, mesh, material, notes)[corners]
    total = np.zeros((count, 3))
    for channel in range(3):
        total[:, channel] = np.bincount(groups, corner_colour[:, channel], minlength=count)
    corners = np.bincount(groups, minlength=count)[:, None]
    return np.where(corners > 0, total / np.maximum(corners, 1), np.array(DEFAULT_ALBEDO))


def _material_colours(ob, mesh, material, notes) -> np.ndarray:
    """(corners, 3) base colour of `material` at every face corner of the mesh."""
    flat = np.tile(np.array(base_colour_value(material)), (len(mesh.loops), 1))
    source = base_colour_source(material)
    if source is None:
        return flat
    if source.type == "TEX_IMAGE" and source.image is not None:
        layer = uv_layer(mesh, texture_uv_map(source))
        if layer is None:
            notes.append(f"{ob.name!r}: material {material.name!r} uses an image texture but the mesh has no UV "
                         f"map {texture_uv_map(source)!r}; its base colour value is used as albedo instead")
            return flat
        uv = np.empty(len(mesh.loops) * 2, dtype=np.float64)
        layer.data.foreach_get("uv", uv)
        return _sample_image(source.image, uv.reshape(-1, 2), ob, notes, flat)
    if source.type == "VERTEX_COLOR":
        attribute = mesh.color_attributes.get(source.layer_name) if source.layer_name else \
            mesh.color_attributes.active_color
        if attribute is not None:
            return _corner_colours(mesh, attribute)
    notes.append(f"{ob.name!r}: material {material.name!r}'s base colour comes from a {source.type.lower()} "
                 f"node, which the bake cannot read; its colour value is used as albedo")
    return flat


def _sample_image(image, uv, ob, notes, fallback) -> np.ndarray:
    """Nearest texel at each UV (repeating), in linear colour."""
    width, height = image.size
    if width == 0 or height == 0:
        notes.append(f"{ob.name!r}: image {image.name!r} cannot be read; its material's colour value is used")
        return fallback
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(height, width, image.channels)
    repeat = np.mod(uv, 1.0)
    repeat[(repeat == 0.0) & (uv > 0.0)] = 1.0  # u = 1 is the image's right edge, not its left
    column = np.minimum((repeat[:, 0] * width).astype(np.int64), width - 1)
    row = np.minimum((repeat[:, 1] * height).astype(np.int64), height - 1)
    colours = pixels[row, column, :3].astype(np.float64)
    if colours.shape[1] == 1:
        colours = np.repeat(colours, 3, axis=1)
    if image.colorspace_settings.name == "sRGB" and not image.is_float:
        colours = srgb_to_linear(colours)  # byte images hold display-encoded values
    return colours


def _corner_colours(mesh, attribute) -> np.ndarray:
    values = np.empty(len(attribute.data) * 4, dtype=np.float32)
    attribute.data.foreach_get("color", values)  # linear, for byte and float attributes alike
    values = values.reshape(-1, 4)[:, :3].astype(np.float64)
    return values if attribute.domain == "CORNER" else values[mesh_corner_vertices(mesh)]
