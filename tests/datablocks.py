"""Every datablock's data in the open file, as values to compare: a step that must leave the file as it was is
checked by comparing them before and after. A byte comparison of saved files cannot tell: Blender 5 writes an
unchanged session differently from one save to the next (the place of an array it shares with the evaluated scene:
2 of 14 pairs of saves in a row differed), and reading data through Python may unshare an array without changing
it.

Each datablock's properties are read through RNA (nested structs and collections a few levels deep, at most 64
items of a collection), its custom properties whole, a mesh's attributes (positions, UV maps, the bake's, ...) and an
image's pixels as digests of their values. The interface's own state (window managers, screens, workspaces) is
left out."""

import hashlib
import warnings

import bpy
import numpy as np

SKIPPED_IDS = ("window_managers", "screens", "workspaces", "all_ids")  # the interface's state; all_ids repeats
MESH_ELEMENTS = ("vertices", "edges", "loops", "polygons", "loop_triangles", "loop_triangle_polygons",
                 "corner_normals", "vertex_normals", "polygon_normals", "attributes", "color_attributes",
                 "uv_layers", "vertex_colors", "skin_vertices", "vertex_creases", "edge_creases")  # as attributes
MOST_ITEMS = 64


def datablocks(depth: int = 3) -> dict:
    """(collection, name) → the datablock's values, for every datablock of bpy.data but the interface's."""
    found = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # reading a property Blender 6 drops is still reading
        for kind in dir(bpy.data):
            collection = getattr(bpy.data, kind)
            if kind in SKIPPED_IDS or not isinstance(collection, bpy.types.bpy_prop_collection):
                continue
            for datablock in collection:
                found[(kind, datablock.name_full)] = _struct(datablock, depth)
    return found


def _value(value, depth):
    """A property's value: an ID by name, a struct's values to `depth`, a sequence item by item."""
    if isinstance(value, bpy.types.ID):
        return ("ID", value.name_full)
    if isinstance(value, bpy.types.bpy_struct):
        return _struct(value, depth - 1) if depth > 0 else ("struct", type(value).__name__)
    if hasattr(value, "__len__") and not isinstance(value, str):
        try:
            return tuple(_value(v, depth) for v in value)
        except TypeError:
            return repr(value)
    return value

def _struct(struct, depth) -> dict:
    """A struct's RNA properties (collections to MOST_ITEMS items), custom properties, and for a mesh its attributes
    and UV maps, for an image its pixels."""
    found = {}
    for prop in struct.bl_rna.properties:
        name = prop.identifier
        if name == "rna_type" or prop.type == "POINTER" and prop.fixed_type.identifier == "Depsgraph":
            continue
        if isinstance(struct, bpy.types.Mesh) and name in MESH_ELEMENTS:
            continue
        try:
            value = getattr(struct, name)
        except Exception as error:
            found[name] = type(error).__name__
            continue
        if prop.type == "COLLECTION":
            found[name] = tuple(_value(item, depth) for item in list(value)[:MOST_ITEMS]) if depth > 0 else len(value)
        else:
            found[name] = _value(value, depth)
    try:
        keys = struct.keys()
    except TypeError:  # a type without custom properties
        keys = []
    if keys:
        for key in keys:
            item = struct[key]
            found["[" + key + "]"] = item.to_dict() if hasattr(item, "to_dict") else (
                item.to_list() if hasattr(item, "to_list") else item)
    if isinstance(struct, bpy.types.Mesh):
        for attribute in struct.attributes:
            found["attribute " + attribute.name] = _attribute(attribute)
        found["uv maps"] = [(layer.name, layer.active, layer.active_render) for layer in struct.uv_layers]
    if isinstance(struct, bpy.types.Image) and struct.has_data:
        pixels = np.empty(len(struct.pixels), dtype=np.float32)
        struct.pixels.foreach_get(pixels)
        found["pixels"] = hashlib.sha1(pixels.tobytes()).hexdigest()
    return found

def _attribute(attribute) -> tuple:
    """An attribute's type, domain and a digest of its values."""
    field = {"FLOAT_VECTOR": "vector", "FLOAT2": "vector", "FLOAT_COLOR": "color", "BYTE_COLOR": "color",
             "QUATERNION": "value", "FLOAT4X4": "value"}.get(attribute.data_type, "value")
    data = attribute.data
    if not len(data):
        return (attribute.data_type, attribute.domain, "")
    width = len(getattr(data[0], field)) if hasattr(getattr(data[0], field), "__len__") else 1
    values = np.empty(len(data) * width, dtype=np.float64)
    data.foreach_get(field, values)
    return (attribute.data_type, attribute.domain, hashlib.sha1(values.tobytes()).hexdigest())
