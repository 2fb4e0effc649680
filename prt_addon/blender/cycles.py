"""Cycles as ground truth: the same band-limited light, baked by a path tracer into the receivers' vertices.

What makes Cycles comparable with PRT:
- the light is an equirectangular World texture of the SH light's reconstruction (negative lobes clamped: Cycles
  cannot emit them);
- every rendered mesh gets a pure Diffuse BSDF (the Principled BSDF's specular layer takes about 4 % of the
  diffuse light) coloured by its per-vertex albedo through a colour attribute; what the bake does not see (lamps,
  curves, text, meshes hidden in the viewport) is hidden from render;
- Cycles bakes diffuse direct light × albedo into a colour attribute (plus indirect light, with as many diffuse
  bounces as the bake, for interreflected bakes), in passes with different seeds, whose spread measures Cycles'
  own noise.
Everything this changes in the scene is put back exactly afterwards, also on cancel or failure.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import time

import bpy
import numpy as np

from ..core.progress import Job, Progress
from .compat import new_node_material, new_node_world
from .lights import aim_lamp, real_light
from .relighting import paused

REFERENCE_ATTRIBUTE = "_prt_cycles_reference"
ALBEDO_ATTRIBUTE = "_prt_validation_albedo"
# Object types Cycles renders but the bake neither shades nor shadows with.
NOT_BAKED_TYPES = frozenset({"LIGHT", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"})


def environment_image(pixels: np.ndarray, name: str = "PRT band-limited light"):
    """A float equirect image of (H, W, 3) radiance in Blender's layout, negative values clamped to zero."""
    height, width = pixels.shape[:2]
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[..., :3] = np.maximum(pixels, 0.0)
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.pixels.foreach_set(rgba.ravel())
    return image


@dataclass
class LightGroup:
    """Receivers baked under the same conditions: one SH order (so one light), and the same bounces (None: direct
    light only)."""
    objects: list
    environment: np.ndarray  # (H, W, 3) equirect reconstruction of the light
    bounces: int | None
    indirect_only: bool = False  # only the bounced light: what colour bleeding is made of
    alone: bool = False  # rendered without the other meshes (a dynamic object's bake is against itself only)


class CyclesReference(Job):
    """Cycles' diffuse radiance × albedo at the receivers' vertices, or at their face corners for the objects in
    `per_corner` (Cycles evaluates every corner with its own normal and, for a vertex attribute, averages them):
    per light group, `passes` bakes of `samples` each with different seeds. step() runs one bake; the scene is
    restored after the last one or on cancel()."""

    def __init__(self, context, groups: list, albedos: dict, samples: int, passes: int, per_corner=frozenset(),
                 scene_light: bool = False):
        self.context = context
        self.scene_light = scene_light  # lit by the scene's lights as they are (real_light_world): no group image
        self.groups = groups
        self.albedos = albedos  # every rendered mesh object → (V, 3)
        self.samples = samples
        self.passes = passes
        self.per_corner = per_corner
        self.radiance = {ob.name: [] for group in groups for ob in group.objects}  # (V or C, 3) per pass
        self.time_s = 0.0
        self.progress = Progress("PRT validate" + (" (the real light)" if scene_light else ""))
        self._work = self._all_passes()
        self._total_vertices = passes * sum(self._rows(ob) for group in groups for ob in group.objects)
        self._done_vertices = 0
        self.finished = False

    def step(self, budget_s: float = 0.0) -> bool:
        """Runs one pass, whatever `budget_s` (a Cycles bake cannot be split); True once all have run."""
        if not self.finished:
            self.finished = next(self._work, StopIteration) is StopIteration
        return self.finished

    def cancel(self):
        self._work.close()  # leaves the `with` below: the scene is restored

    def _rows(self, ob) -> int:
        return len(ob.data.loops) if ob.name in self.per_corner else len(ob.data.vertices)

    def _all_passes(self):
        receivers = [ob for group in self.groups for ob in group.objects]
        with paused(self.context.scene), scene_restored(self.context, list(self.albedos)) as created:
            environment = _prepare_scene(self.context, receivers, self.albedos, self.samples, created,
                                         self.per_corner)
            if self.scene_light:  # PRT's part of it: a split-off sun is its lamp's
                self.context.scene.world = real_light_world(self.context.scene, created, without_split_suns=True)
            first = True
            for group in self.groups:
                if not self.scene_light:
                    image = environment_image(group.environment)
                    created.append((bpy.data.images, image))
                    environment.image = image
                for seed in range(self.passes):
                    if not first:
                        yield  # one pass per step; the last step also restores the scene
                    first = False
                    self._bake(group, seed)

    def _bake(self, group: LightGroup, seed: int):
        context = self.context
        cycles = context.scene.cycles
        cycles.seed = seed
        if group.bounces is not None:
            cycles.max_bounces = cycles.diffuse_bounces = group.bounces
        names = {ob.name for ob in group.objects}
        for ob in context.view_layer.objects:
            ob.select_set(ob.name in names)
        context.view_layer.objects.active = group.objects[0]
        others = [ob for ob in self.albedos if group.alone and ob.name not in names and not ob.hide_render]
        for ob in others:
            ob.hide_render = True
        start = time.perf_counter()
        try:
            bpy.ops.object.bake(type="DIFFUSE", target="VERTEX_COLORS", use_selected_to_active=False,
                                pass_filter={"COLOR"} | ({"INDIRECT"} if group.bounces else set())
                                | (set() if group.indirect_only else {"DIRECT"}))
        finally:
            for ob in others:
                ob.hide_render = False
        self.time_s += time.perf_counter() - start
        for ob in group.objects:
            values = np.empty(self._rows(ob) * 4, dtype=np.float32)
            ob.data.color_attributes[REFERENCE_ATTRIBUTE].data.foreach_get("color", values)
            self.radiance[ob.name].append(values.reshape(-1, 4)[:, :3].astype(np.float64))
            self._done_vertices += self._rows(ob)
        self.progress.fraction = self._done_vertices / max(1, self._total_vertices)


def _prepare_scene(context, receivers, albedos, samples, created, per_corner):
    """Cycles on the CPU, a World showing an environment texture (returned, its image set per light group), a
    Diffuse BSDF coloured by its per-vertex albedo on every rendered mesh, what the bake does not see hidden, and
    a colour attribute to bake into on each receiver."""
    scene = context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.sample_clamp_indirect = 0.0  # a clamp would darken the bounced light: no bias wanted
    world = new_node_world("PRT validation")
    created.append((bpy.data.worlds, world))
    nodes, links = world.node_tree.nodes, world.node_tree.links
    environment = nodes.new("ShaderNodeTexEnvironment")
    background = nodes.new("ShaderNodeBackground")
    links.new(environment.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], nodes.new("ShaderNodeOutputWorld").inputs["Surface"])
    scene.world = world
    material = _diffuse_material()
    created.append((bpy.data.materials, material))
    for ob, albedo in albedos.items():
        ob.data.color_attributes.new(ALBEDO_ATTRIBUTE, "FLOAT_COLOR", "POINT")
        rgba = np.concatenate([albedo, np.ones((len(albedo), 1))], axis=1).astype(np.float32)
        ob.data.color_attributes[ALBEDO_ATTRIBUTE].data.foreach_set("color", rgba.ravel())
        if not ob.material_slots:  # else Cycles' default surface, a Principled BSDF, would shade it
            ob.data.materials.append(None)
        for slot in ob.material_slots:
            slot.material = material
    for ob in not_baked(context, receivers):
        ob.hide_render = True
    for ob in receivers:
        attributes = ob.data.color_attributes
        attributes.new(REFERENCE_ATTRIBUTE, "FLOAT_COLOR", "CORNER" if ob.name in per_corner else "POINT")
        attributes.active_color = attributes[REFERENCE_ATTRIBUTE]  # what a vertex-colour bake writes
    return environment


def real_light_world(scene, created, without_split_suns: bool = False):
    """A World and Sun lamps lighting Cycles with the scene's SH lights as they are (blender.lights.real_light):
    each environment's image through its rotation (what was along d comes from R·d: the image is looked up at
    R⁻¹·ω) × its colour, the skies as a constant, each sun as a Sun lamp of its direction, Angle and irradiance.
    Everything made is added to `created`."""
    environments, suns, sky = real_light(scene, without_split_suns)
    world = new_node_world("PRT real light")
    created.append((bpy.data.worlds, world))
    nodes, links = world.node_tree.nodes, world.node_tree.links
    shader = _background(nodes, (*sky, 1.0)).outputs["Background"]
    for image, rotation, rgb in environments:
        turned = nodes.new("ShaderNodeVectorRotate")
        turned.rotation_type, turned.invert = "EULER_XYZ", True
        turned.inputs["Rotation"].default_value = rotation
        links.new(nodes.new("ShaderNodeTexCoord").outputs["Generated"], turned.inputs["Vector"])
        texture = nodes.new("ShaderNodeTexEnvironment")
        if isinstance(image, np.ndarray):  # an image without its sun
            image = environment_image(image, "PRT light without its sun")
            created.append((bpy.data.images, image))
        texture.image = image
        links.new(turned.outputs["Vector"], texture.inputs["Vector"])
        background = _background(nodes, (1.0, 1.0, 1.0, 1.0))
        background.inputs["Strength"].default_value = 1.0
        tinted = nodes.new("ShaderNodeVectorMath")  # the image × the light's colour and strength
        tinted.operation = "MULTIPLY"
        tinted.inputs[1].default_value = rgb
        links.new(texture.outputs["Color"], tinted.inputs[0])
        links.new(tinted.outputs["Vector"], background.inputs["Color"])
        both = nodes.new("ShaderNodeAddShader")
        links.new(shader, both.inputs[0])
        links.new(background.outputs["Background"], both.inputs[1])
        shader = both.outputs["Shader"]
    links.new(shader, nodes.new("ShaderNodeOutputWorld").inputs["Surface"])
    for sun in suns:
        lamp = bpy.data.objects.new("PRT real sun", bpy.data.lights.new("PRT real sun", "SUN"))
        scene.collection.objects.link(lamp)
        aim_lamp(lamp, sun)
        created.extend([(bpy.data.lights, lamp.data), (bpy.data.objects, lamp)])  # removed: the object first
    return world


def _background(nodes, colour):
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Color"].default_value = colour
    return background


def rendered_meshes(context, receivers):
    """The meshes Cycles renders and the bake sees: visible ones, and the receivers."""
    names = {ob.name for ob in receivers}
    return [ob for ob in context.view_layer.objects
            if ob.type == "MESH" and not ob.hide_render and (ob.visible_get() or ob.name in names)]


def not_baked(context, receivers):
    """Objects Cycles would render that the bake does not see: other object types, and hidden meshes."""
    names = {ob.name for ob in receivers}
    return [ob for ob in context.view_layer.objects if not ob.hide_render and (
        ob.type in NOT_BAKED_TYPES or ob.type == "MESH" and not ob.visible_get() and ob.name not in names)]


def _diffuse_material():
    """A Diffuse BSDF whose colour is each mesh's ALBEDO_ATTRIBUTE."""
    material = new_node_material("PRT validation")
    nodes, links = material.node_tree.nodes, material.node_tree.links
    albedo = nodes.new("ShaderNodeVertexColor")
    albedo.layer_name = ALBEDO_ATTRIBUTE
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(albedo.outputs["Color"], diffuse.inputs["Color"])
    links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    return material


@contextmanager
def scene_restored(context, meshes):
    """Puts back the world, render settings, materials, render visibility, colour attributes and selection, then
    removes every data-block the body added to the yielded list as (collection, block)."""
    scene = context.scene
    layer_objects = list(context.view_layer.objects)
    saved = {
        "world": scene.world, "engine": scene.render.engine,
        "cycles": {key: getattr(scene.cycles, key) for key in
                   ("device", "samples", "seed", "max_bounces", "diffuse_bounces", "sample_clamp_indirect")},
        "materials": {ob: [slot.material for slot in ob.material_slots] for ob in layer_objects
                      if ob.type == "MESH"},
        "hide_render": {ob: ob.hide_render for ob in layer_objects},
        "colours": {ob: (ob.data.color_attributes.active_color_name, ob.data.color_attributes.default_color_name)
                    for ob in meshes},
        "selected": [ob for ob in layer_objects if ob.select_get()],
        "active": context.view_layer.objects.active,
    }
    created = []
    try:
        yield created
    finally:
        scene.world = saved["world"]
        scene.render.engine = saved["engine"]
        for key, value in saved["cycles"].items():
            setattr(scene.cycles, key, value)
        for ob, materials in saved["materials"].items():
            if not materials and ob.data.materials:
                ob.data.materials.clear()  # the slot given above (pop would leave the object a stale empty slot)
            for slot, material in zip(ob.material_slots, materials):
                slot.material = material
        for ob, hidden in saved["hide_render"].items():
            ob.hide_render = hidden
        for ob, (active, default) in saved["colours"].items():
            attributes = ob.data.color_attributes
            for name in (REFERENCE_ATTRIBUTE, ALBEDO_ATTRIBUTE):
                if name in attributes:
                    attributes.remove(attributes[name])
            # Set even when empty: from Blender 5.2 removing an attribute leaves its name as the active one.
            attributes.active_color_name, attributes.default_color_name = active, default
        for ob in layer_objects:
            ob.select_set(ob in saved["selected"])
        context.view_layer.objects.active = saved["active"]
        for collection, block in reversed(created):  # the world before the image it shows
            collection.remove(block)
