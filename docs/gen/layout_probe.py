"""What a bake stores, found by baking: a small scene baked per vertex, per face corner, per texel, as a dynamic
object and in a probe volume (shadowed), then interreflected with coloured albedo and unshadowed, each in a moment
(order 2, few rays, one process). The stored-layout page lists exactly the attributes, images and metadata keys
these bakes leave, so it cannot name one the code no longer writes nor miss one it writes."""

from dataclasses import dataclass, field

import bpy

from prt_addon.blender import compat, probe_volumes, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.commands.common import schema_registered
from prt_addon.core.bake import BakeSettings

PER_VERTEX, PER_CORNER, PER_TEXEL, DYNAMIC = "per vertex", "per face corner", "per texel", "dynamic"
INTERREFLECTED, UNSHADOWED = "interreflected (coloured)", "unshadowed"


@dataclass
class Found:
    """What the bakes stored: per case, the mesh attributes (name → (type, domain)), the metadata (key → value) and
    the images (name with the mesh's as <mesh>); the probe volume's custom properties."""
    attributes: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict)
    probe_volume: dict = field(default_factory=dict)


def bake_and_read() -> Found:
    found = Found()
    with schema_registered():
        objects = _scene()
        _bake("shadowed")
        for case, name in ((PER_VERTEX, "Ball"), (PER_CORNER, "Box"), (PER_TEXEL, "Floor"), (DYNAMIC, "Mover")):
            _read(found, case, objects[name])
        volume = objects["Volume"]
        found.probe_volume = {key: volume[key] for key in (probe_volumes.TRANSFER_KEY, probe_volumes.VALID_KEY,
                                                           probe_volumes.METADATA_KEY)}
        found.probe_volume[probe_volumes.METADATA_KEY] = found.probe_volume[probe_volumes.METADATA_KEY].to_dict()
        for case, mode in ((INTERREFLECTED, "interreflected"), (UNSHADOWED, "unshadowed")):
            _bake(mode, ["Ball"])
            _read(found, case, objects["Ball"])
        bpy.ops.wm.read_homefile(use_empty=True)
    return found


def _scene() -> dict:
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    floor = bpy.context.object
    floor.name, floor.prt_storage, floor.prt_resolution = "Floor", "texel", 8
    bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=4, radius=0.5, location=(-1.0, 0.0, 0.6))
    bpy.ops.object.shade_smooth()
    ball = bpy.context.object
    ball.name = "Ball"
    red = compat.new_node_material("Red")
    bsdf = red.node_tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.2, 0.1, 1.0)
    red.node_tree.links.new(bsdf.outputs["BSDF"], red.node_tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    ball.data.materials.append(red)  # coloured albedo: an interreflected bake stores a channel per colour
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(1.0, 0.0, 0.3))
    bpy.context.object.name = "Box"  # flat faces: its vertices split by their corner normals
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1, radius=0.2, location=(0.0, 1.0, 0.5))
    bpy.ops.object.shade_smooth()
    bpy.context.object.name, bpy.context.object.prt_dynamic = "Mover", True
    volume = bpy.data.objects.new("Volume", None)
    volume.empty_display_type, volume.location = "CUBE", (0.0, 1.0, 0.5)
    volume.prt_probe_volume, volume.prt_probe_resolution = True, (2, 2, 2)
    bpy.context.collection.objects.link(volume)
    bpy.ops.object.select_all(action="DESELECT")
    return {ob.name: ob for ob in bpy.data.objects}


def _bake(mode: str, names=None):
    SceneBake(bpy.context, BakeSettings(mode=mode, order=2, samples=16), names, workers=1).run(log=lambda line: None)


def _read(found: Found, case: str, ob):
    mesh = ob.data
    found.attributes[case] = {attribute.name: (attribute.data_type, attribute.domain) for attribute in mesh.attributes
                              if attribute.name.startswith(storage.ATTRIBUTE_PREFIX)}
    found.metadata[case] = mesh[storage.METADATA_KEY].to_dict()
    found.images[case] = sorted(image.name.replace(mesh.name, "<mesh>") for image in bpy.data.images
                                if image.get(storage.MAP_OF_KEY) == mesh.name)
