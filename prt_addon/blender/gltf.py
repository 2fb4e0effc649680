"""The bake as a glTF binary (.glb), through Blender's own glTF exporter, without changing the user's data.

The exporter runs on temporary copies in a temporary scene: each baked object (world transform kept, unparented,
its own materials rather than the PRT display's) with its stored `_prt_*` attributes replaced by the profile's
packing (core.gltf_pack) of the transfer rotated into glTF's frame, and `prt_color`, the colours under the current
lights, which the exporter writes as COLOR_0; and the scene's camera. Everything temporary is removed afterwards,
whatever happens. Then the GLB gets what the exporter cannot write: the convention and the SH lights in the
scene's extras, each mesh's packing in its extras, data textures as buffer views, and the original names.

A texel bake travels as its maps (core.gltf_pack.PackedMaps: RGBA32F buffer views read through the lightmap UV set,
which the exporter writes as a TEXCOORD like every UV map), under every profile, since they are no vertex
attributes; its COLOR_0 holds the shaded maps sampled at each face corner's lightmap UV.

A dynamic object's mesh is flagged in its extras (its transfer is in its own frame, and where it takes the probes'
light: per vertex or at its centre) and its COLOR_0 is shaded as the display shades it where it stands
(blender.relighting.dynamic_radiance, dynamic_light); the scene's probe volumes travel in the scene's extras with
their matrices as buffer views (core.gltf_probes).
"""

import contextlib
import os

import bpy
import numpy as np

from ..core import glb, gltf_pack, gltf_probes, lights as core_lights, outputs, shading
from ..core.errors import InputError, StaleBake
from . import display, layouts, materials, probe_volumes, relighting, storage
from .fingerprint import placement_changes
from .lights import scene_lights

COPY_PREFIX = "PRT glTF "  # names of the temporary copies; taken off again in the file
EXPORT_SCENE = "PRT glTF export"
EXPORTER_ADDON = "io_scene_gltf2"
SUFFIXES = (".glb",)  # glTF binary only: the transfer's data textures are buffer views of its one binary chunk
DISPLAY_SETTINGS = ("show_prt", "use_albedo", "mode", "window")  # so the relighting leaves the user's data alone


def export(scene, path: str, profile_name: str) -> dict:
    """Writes the scene's baked meshes to `path` (.glb) packed for the profile, whole or not at all; returns what it
    wrote, with notes on materials left out (materials.lost_note). Nothing is created before the packing fits the
    profile (a refusal names the limit)."""
    profile = gltf_pack.PROFILES.get(profile_name)
    if profile is None:
        raise InputError(f"unknown profile {profile_name!r}: expected one of {', '.join(gltf_pack.PROFILES)}")
    baked = [(ob, layouts.stored(ob.data).gltf(ob, profile)) for ob in storage.baked_objects(scene.objects)]
    if not baked:
        raise InputError("no visible mesh has a PRT bake to export")
    packs = {ob.name: bake.packed for ob, bake in baked}
    dynamic = {ob.name: {"probe_light": "centre", "light_order": storage.light_order(bake.meta)}
               for ob, bake in baked if bake.meta.get(storage.DYNAMIC_KEY, False)}
    stored, volumes, notes = _probe_volumes(scene)
    shining, window, light_source = _lights(scene)
    orders = {storage.light_order(bake.meta) for _, bake in baked}
    cache = core_lights.LightCache()
    totals = cache.totals(shining, orders, window)
    top_order = max(orders)
    with outputs.replacing(path) as written:  # the exporter's file and the extras added to it: whole or nothing
        with _export_scene(scene) as temporary:
            for ob, bake in baked:
                mesh = _link_copy(temporary, ob).data
                _write_packing(mesh, bake.packed, bake.corner_points)
                light = totals[storage.light_order(bake.meta)]
                radiance = _vertex_radiance(ob, bake, light, stored) if ob.name in dynamic else None
                if radiance is not None:
                    dynamic[ob.name]["probe_light"] = "vertex"
                    display.write_radiance(mesh, radiance, bake.corner_points)
                    continue
                if ob.name in dynamic:
                    light = relighting.dynamic_light(stored, ob, light)
                display.write_display_colours(mesh, bake.transfer, light, bake.corner_points)
            if scene.camera is not None:
                _link_copy(temporary, scene.camera)
            _run_exporter(temporary, written)
        _finish_file(written, scene.name, packs, dynamic, volumes, {
            "profile": profile.name, "convention": gltf_pack.CONVENTION, "order": top_order,
            **_window_extras(window, cache), "light_source": light_source, "active_light": scene.prt_active_light,
            "lights": gltf_pack.light_extras(shining, top_order)})
    return {"path": os.path.abspath(path), "profile": profile.name, "objects": list(packs),
            "packs": packs, "light_source": light_source, "dynamic": sorted(dynamic),
            "lit_per_vertex": sorted(name for name, where in dynamic.items() if where["probe_light"] == "vertex"),
            "probe_volumes": [volume.name for volume in volumes],
            "notes": notes + [note for note in (materials.lost_note(ob) for ob, _ in baked) if note is not None]}


def _vertex_radiance(ob, bake, light, stored):
    """(P, 3) a dynamic object's radiance per shading point where the display lights it per vertex through the
    probes (blender.relighting.dynamic_radiance), else None (lit at its centre)."""
    layout = layouts.stored(ob.data)
    shading = layouts.Shading(bake.transfer, layout, bake.corner_points)
    points = layout.points(ob.data, shading)
    return relighting.dynamic_radiance(ob, ob, shading, points, light, stored)


def _probe_volumes(scene):
    """(the baked probe volumes the display lights dynamic objects from (blender.probe_volumes.StoredProbes), the
    same packed for glTF, notes on those left out): every probe volume of the scene with a bake, as the display
    takes them."""
    stored, packed, notes = [], [], []
    for ob in scene.objects:
        if not probe_volumes.is_probe_volume(ob) or probe_volumes.bake_id(ob) is None:
            continue
        try:
            probes = probe_volumes.read(ob)
        except StaleBake as problem:
            notes.append(f"{problem}: not exported")
            continue
        moved = placement_changes(ob)
        if moved:  # as the display says it: the probes go where they were baked
            notes.append(f"probe volume {ob.name!r}: {', '.join(moved)} since its bake; exported where it was baked")
        meta = ob[probe_volumes.METADATA_KEY]
        bake = {key: meta[key] for key in ("layout", "mode", "samples", "rays", "seed", "est_max_error", "date",
                                           "bake_id")}
        stored.append(probes)
        packed.append(gltf_probes.pack_probes(ob.name, probes.matrices, probes.valid,
                                              np.linalg.inv(probes.to_volume), probes.resolution, bake))
    return stored, packed, notes


def _window_extras(window, cache) -> dict:
    """The window as a viewer applies it: Auto as the "tapered" strength it found per order for these lights (a
    viewer keeps it while it turns them)."""
    if window != "auto":
        return {"window": window}
    return {"window": "tapered", "window_strengths": {str(order): strength
                                                       for order, strength in cache.auto_strengths.items()}}


def _lights(scene):
    """(core lights, window, what they are): the scene's SH lights, or the default light validation uses."""
    shining = scene_lights(scene)
    if shining:
        return shining, scene.prt_display.window, "the scene's SH lights"
    sun = core_lights.DEFAULT_SUN
    direction = shading.direction_from_angles(sun["theta"], sun["phi"])
    default = [core_lights.Sun(direction, sun["angular_radius"], (sun["irradiance"],) * 3),
               core_lights.Sky((core_lights.DEFAULT_SKY,) * 3)]
    return default, "hanning", f"the default light, {core_lights.DEFAULT_LIGHT}"


@contextlib.contextmanager
def _export_scene(scene):
    """A temporary scene for the copies, removed with everything linked to it however the export ends."""
    temporary = bpy.data.scenes.new(EXPORT_SCENE)
    temporary.render.resolution_x, temporary.render.resolution_y = (scene.render.resolution_x,
                                                                     scene.render.resolution_y)
    temporary.render.pixel_aspect_x, temporary.render.pixel_aspect_y = (scene.render.pixel_aspect_x,
                                                                        scene.render.pixel_aspect_y)
    for name in DISPLAY_SETTINGS:
        setattr(temporary.prt_display, name, getattr(scene.prt_display, name))
    try:
        yield temporary
    finally:
        for ob in list(temporary.collection.objects):
            data = ob.data
            bpy.data.objects.remove(ob)
            if isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)
        bpy.data.scenes.remove(temporary)


def _link_copy(temporary, ob):
    """A copy of ob in the temporary scene at ob's world transform, with its own materials; a mesh gets its own
    copy of the data without the stored bake."""
    copy = ob.copy()
    copy.name = COPY_PREFIX + ob.name
    copy.animation_data_clear()
    copy.constraints.clear()  # their targets are not in the temporary scene; the world transform is kept instead
    copy.parent = None
    copy.matrix_world = ob.matrix_world.copy()
    temporary.collection.objects.link(copy)
    if ob.type == "MESH":
        copy.data = ob.data.copy()
        copy.data.name = COPY_PREFIX + ob.name
        storage.remove_transfer(copy.data)
        if materials.ORIGINALS_KEY in copy:
            for slot, material in zip(copy.material_slots, materials.original_materials(ob)):
                slot.material = material
            del copy[materials.ORIGINALS_KEY]
    return copy


def _write_packing(mesh, packed, corner_points):
    """The packed rows per vertex (POINT) or face corner (CORNER, through each corner's point); buffers (data
    textures, texel maps) go into the file afterwards."""
    domain = "POINT" if corner_points is None else "CORNER"
    rows = slice(None) if corner_points is None else corner_points
    for name, values in packed.attributes.items():
        mesh.attributes.new(name, "FLOAT_COLOR", domain)
        mesh.attributes[name].data.foreach_set("color", np.ascontiguousarray(values[rows]).ravel())
    if packed.indexed:
        points = np.arange(len(mesh.vertices)) if corner_points is None else corner_points
        mesh.attributes.new(gltf_pack.INDEX_ATTRIBUTE, "FLOAT", domain)
        mesh.attributes[gltf_pack.INDEX_ATTRIBUTE].data.foreach_set("value", points.astype(np.float32))


def _run_exporter(temporary, path):
    """Blender's glTF exporter on the temporary scene alone; it leaves the window showing the scene it found, so the
    user's is put back."""
    if not hasattr(bpy.types, "EXPORT_SCENE_OT_gltf"):  # the user turned it off
        import addon_utils  # Blender's, importable once bpy is
        addon_utils.enable(EXPORTER_ADDON, default_set=False)  # for this session only, not the preferences
    window = bpy.context.window
    shown = window.scene if window else None
    try:
        if window:
            window.scene = temporary
        with bpy.context.temp_override(scene=temporary, view_layer=temporary.view_layers[0]):
            bpy.ops.export_scene.gltf(
                filepath=os.path.abspath(path), export_format="GLB", use_active_scene=True, export_attributes=True,
                export_vertex_color="NAME", export_vertex_color_name=display.DISPLAY_ATTRIBUTE,
                export_all_vertex_colors=False, export_cameras=True, export_lights=False, export_animations=False,
                export_apply=False, export_yup=True, export_extras=False)
    finally:
        if window:
            window.scene = shown


def _finish_file(path, scene_name, packs, dynamic, volumes, scene_extras):
    """Adds extras, data textures, probe volumes and the original names to the exporter's GLB; `dynamic`: the
    dynamic objects' names, each with where it takes the probes' light (probe_light: "vertex" or "centre") and the
    order of the distant light it is lit by (light_order), `volumes` the probe volumes
    (core.gltf_probes.PackedProbes)."""
    with open(path, "rb") as file:
        document, binary = glb.read(file.read())
    for mesh in document.get("meshes", []):
        packed = packs[mesh["name"].removeprefix(COPY_PREFIX)]
        views = [glb.append_buffer_view(document, binary, array.tobytes()) for array in packed.buffers()]
        mesh["extras"] = {"prt": packed.extras(views)}
        where = dynamic.get(mesh["name"].removeprefix(COPY_PREFIX))
        if where is not None:
            mesh["extras"]["prt"].update(dynamic=True, **where)
    for item in document.get("nodes", []) + document.get("meshes", []):
        item["name"] = item.get("name", "").removeprefix(COPY_PREFIX)
    scene = document["scenes"][document.get("scene", 0)]
    if volumes:
        scene_extras["probe_convention"] = gltf_probes.CONVENTION
        scene_extras["probe_volumes"] = [
            volume.extras([glb.append_buffer_view(document, binary, array.tobytes()) for array in volume.buffers()])
            for volume in volumes]
    scene["name"], scene["extras"] = scene_name, {"prt": scene_extras}
    with open(path, "wb") as file:
        file.write(glb.write(document, binary))
