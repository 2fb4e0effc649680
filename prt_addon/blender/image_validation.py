"""Validation in image space, two ways.

validate_image (`prt validate --image`): what the camera sees of the PRT display against a Cycles render under the
same band-limited light, pixel by pixel, so that everything a viewer sees counts: the Monte Carlo noise, and what the
storage loses between vertices or texels (interpolation across faces, a shadow edge crossing a face).

Both sides show white surfaces (albedo 1), so the comparison is of the transfer itself: Cycles renders every mesh
as a white Diffuse BSDF under the light's SH reconstruction as its World (direct light only, as shadowed bakes;
with the bake's bounces for interreflected ones), in passes with different seeds whose spread measures its noise;
EEVEE renders the PRT display (Emission of Σ L_k T_k, per vertex or per texel). Both are read as linear float
EXR. The pixels compared are the lit pixels of baked receivers: covered wholly by one (Workbench renders the
mask; pixels at an object's silhouette, which the two renderers filter differently, are left out) and brighter
than 2 % of the RMS. Errors are relative to the RMS of Cycles' radiance there, with Cycles' noise taken out as in
the vertex validation (core.statistics).

compare_images (the light-fidelity check of blender.lights): what EEVEE shows (the PRT display, with a split-off
sun's lamp adding its diffuse light and sharp shadows) against Cycles under the scene's lights as they are (the raw
HDRI). Cycles renders the same display materials with the PRT emission off and the diffuse term on, so both see the
same albedo and geometry; the lamps of split-off suns are hidden from it (the raw image holds their suns). Both
render with a transparent film, and only pixels covered in both are compared.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import os
import tempfile
import time

import bpy
import numpy as np

from ..core import heatmap, lobes
from ..core.errors import InputError
from ..core.statistics import compare
from . import display as prt_display, heatmaps, outputs, storage
from .compat import eevee_engine_id, new_node_material, new_node_world
from .relighting import Relighter, paused
from .cycles import environment_image, not_baked, real_light_world, rendered_meshes, scene_restored
from .validation import ENVIRONMENT_SIZE, scene_light

DEFAULT_RESOLUTION = (160, 120)
DEFAULT_PASSES = 2
LIT_FRACTION = 0.02  # of the RMS radiance over the receivers' pixels: darker pixels are not "lit"
UNLIT_SRGB = (0.25, 0.25, 0.25)  # the heatmap's pixels that were not compared
WHOLE_PIXEL = 0.99  # a white-on-black mask pixel this bright is covered wholly (Workbench dithers by 1/256 or so)
COVERED = 0.999  # compare_images: alpha above which a pixel shows an object in both renders
LIGHT_SAMPLES = (16, 64)  # compare_images: EEVEE's, Cycles' per pass


@dataclass
class ImageReport:
    camera: str
    resolution: tuple
    comparison: object  # core.statistics.Comparison over the lit pixels ("vertices" are pixels)
    cycles_time_s: float
    display_time_s: float
    light: str
    heatmap: str | None
    notes: list

    def line(self) -> str:
        c = self.comparison
        return (f"PRT validate --image: camera {self.camera!r}, {self.resolution[0]} × {self.resolution[1]}, "
                f"{c.vertices} lit pixels vs Cycles: {c.text()}; Cycles {self.cycles_time_s:.1f} s, PRT display "
                f"{self.display_time_s:.1f} s; {self.light}" + (f"; heatmap {self.heatmap}" if self.heatmap else ""))

    def as_dict(self) -> dict:
        return {"camera": self.camera, "resolution": list(self.resolution), "pixels": self.comparison.vertices,
                **{key: value for key, value in self.comparison.as_dict().items() if key != "vertices"},
                "cycles_time_s": self.cycles_time_s, "display_time_s": self.display_time_s, "light": self.light,
                "heatmap": self.heatmap, "notes": self.notes}


def validate_image(context, camera: str | None = None, samples: int = 64, passes: int = DEFAULT_PASSES,
                   resolution=DEFAULT_RESOLUTION, heatmap_path: str | None = None) -> ImageReport:
    """Renders both sides from the camera and compares them; the scene is put back as it was."""
    scene = context.scene
    camera_object = bpy.data.objects.get(camera) if camera else scene.camera
    if camera_object is None or camera_object.type != "CAMERA":
        raise InputError(f"no camera named {camera!r}" if camera else "the scene has no camera; give --camera")
    receivers = storage.baked_objects(context.view_layer.objects)
    if not receivers:
        raise InputError("no visible mesh has a PRT bake to validate")
    metas = [ob.data[storage.METADATA_KEY] for ob in receivers]
    orders = {storage.light_order(meta) for meta in metas}
    if len(orders) > 1:
        raise InputError(f"the receivers were baked at orders {sorted(orders)}; one light shows them all only at "
                         f"one order: rebake them alike")
    order = orders.pop()
    totals, from_scene = scene_light(context, [order])
    notes = [f"{ob.name!r} is baked unshadowed: Cycles shows its shadows" for ob, meta in zip(receivers, metas)
             if meta["mode"] == "unshadowed"]
    bounces = max((meta.get("bounces", 0) or 0 for meta in metas if meta["mode"] == "interreflected"), default=0)
    if bounces:
        notes.append("interreflected bakes: Cycles bounces light between white surfaces, the bake between its "
                     "materials' albedo; the two agree where that albedo is white")
    with tempfile.TemporaryDirectory(prefix="prt_validate_image_") as folder, \
            render_settings_restored(scene):
        scene.camera = camera_object
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
        shown, cycles, display_time, cycles_time = band_limited_renders(context, receivers, totals, order, samples,
                                                                        passes, bounces, folder)
        covered = _render_mask(context, receivers, os.path.join(folder, "mask.exr"))
    lit = _lit_pixels(covered, cycles.mean(axis=0))
    if not lit.any():
        raise InputError(f"camera {camera_object.name!r} sees no lit pixel of a baked mesh")
    comparison = compare("image", shown[lit], cycles[:, lit])
    if heatmap_path:
        _write_heatmap(heatmap_path, lit, comparison.errors, resolution)
    light = "scene light" if from_scene else "default light (the scene has no SH lights)"
    return ImageReport(camera_object.name, tuple(resolution), comparison, cycles_time, display_time, light,
                       heatmap_path, notes)


def band_limited_renders(context, receivers, totals, order, samples, passes, bounces, folder):
    """The camera's view (the scene's camera and resolution) twice under the band-limited light totals[order]
    ({order: (3, order²)}, as blender.validation.scene_light gives it): EEVEE showing the PRT display without
    albedo, (H·W, 3), and Cycles' `passes`, (passes, H·W, 3), every mesh white; linear radiance, rows from the
    bottom; then each one's seconds. Files go in `folder`; the caller puts the render settings back
    (render_settings_restored)."""
    start = time.perf_counter()
    shown = _render_display(context, totals, os.path.join(folder, "prt.exr"))
    display_time = time.perf_counter() - start
    start = time.perf_counter()
    environment = lobes.reconstruct_equirect(totals[order], *ENVIRONMENT_SIZE)
    cycles = _render_cycles(context, receivers, environment, samples, passes, bounces, folder)
    return shown, cycles, display_time, time.perf_counter() - start


@contextmanager
def render_settings_restored(scene):
    """Puts back what the renders below change beyond blender.cycles.scene_restored: the camera, resolution,
    output, view transform, EEVEE's and Workbench's settings, the PRT display switches and object colours."""
    render, shading, display = scene.render, scene.display.shading, scene.prt_display
    saved = [(render, key, getattr(render, key)) for key in
             ("engine", "film_transparent", "resolution_x", "resolution_y", "resolution_percentage", "filepath")]
    saved += [(scene.cycles, key, getattr(scene.cycles, key))
              for key in ("device", "samples", "seed", "use_denoising", "max_bounces", "diffuse_bounces")]
    saved += [(render.image_settings, key, getattr(render.image_settings, key)) for key in
              ("file_format", "color_depth")]
    saved += [(scene, "camera", scene.camera), (scene, "world", scene.world),
              (scene.view_settings, "view_transform", scene.view_settings.view_transform),
              (scene.eevee, "taa_render_samples", scene.eevee.taa_render_samples)]
    saved += [(shading, key, getattr(shading, key)) for key in ("light", "color_type")]
    saved += [(display, key, getattr(display, key)) for key in ("show_prt", "use_albedo", "mode")]
    saved += [(ob, "color", tuple(ob.color)) for ob in scene.objects]
    try:
        yield
    finally:
        for owner, key, value in saved:
            if getattr(owner, key) != value:
                setattr(owner, key, value)


def _render_exr(scene, path) -> np.ndarray:
    """Renders the camera's view to a 32-bit float EXR and reads it back: (H·W, 3) linear radiance, rows from the
    bottom as Blender stores pixels."""
    return _render_rgba(scene, path)[:, :3].astype(np.float64)


def _render_rgba(scene, path) -> np.ndarray:
    """(H·W, 4) float32 linear RGBA of the camera's view, through a 32-bit EXR at `path`."""
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path)
    try:
        pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    return pixels.reshape(-1, 4)


def _black_world():
    world = new_node_world("PRT validation black")
    world.color = (0.0, 0.0, 0.0)
    background = world.node_tree.nodes.new("ShaderNodeBackground")
    background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    world.node_tree.links.new(background.outputs["Background"],
                              world.node_tree.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])
    return world


def _render_display(context, totals, path) -> np.ndarray:
    """EEVEE showing the PRT display without albedo under the light Cycles gets (the scene's SH lights as the
    handlers sum them, or the default light), in front of a black world; the handlers show the display materials
    and put the objects' own back afterwards."""
    scene = context.scene
    world = _black_world()
    try:
        scene.world = world
        Relighter().shade_all(scene, totals)
        display = scene.prt_display
        display.show_prt, display.use_albedo, display.mode = True, False, heatmaps.SHADED
        context.view_layer.update()  # the handlers show the display materials
        scene.render.engine = eevee_engine_id()
        scene.eevee.taa_render_samples = 16
        scene.view_settings.view_transform = "Standard"
        shown = _render_exr(scene, path)
        display.show_prt = False
        context.view_layer.update()  # the handlers put the objects' own materials back
    finally:
        bpy.data.worlds.remove(world)
    return shown


def _render_mask(context, receivers, path) -> np.ndarray:
    """(H·W,) True where a baked receiver wholly covers the pixel and its neighbours: Workbench, flat, white
    receivers on black (a pixel at a silhouette blends the two and is left out, with the ring around it)."""
    scene = context.scene
    world = _black_world()
    try:
        scene.world = world
        scene.render.engine = "BLENDER_WORKBENCH"
        scene.display.shading.light = "FLAT"
        scene.display.shading.color_type = "OBJECT"
        names = {ob.name for ob in receivers}
        for ob in scene.objects:
            ob.color = (1.0, 1.0, 1.0, 1.0) if ob.name in names else (0.0, 0.0, 0.0, 1.0)
        scene.view_settings.view_transform = "Standard"
        whole = _render_exr(scene, path)[:, 0] > WHOLE_PIXEL
    finally:
        bpy.data.worlds.remove(world)
    height, width = scene.render.resolution_y, scene.render.resolution_x
    grid = np.pad(whole.reshape(height, width), 1)
    eroded = np.ones((height, width), dtype=bool)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            eroded &= grid[dy: dy + height, dx: dx + width]
    return eroded.ravel()


def _render_cycles(context, receivers, environment, samples, passes, bounces, folder) -> np.ndarray:
    """(passes, H·W, 3): Cycles on the CPU, every mesh a white Diffuse BSDF, the World the light's reconstruction,
    what the bake does not see hidden; direct light only unless the bake bounced light."""
    scene = context.scene
    with scene_restored(context, []) as created:
        world = new_node_world("PRT validation")
        created.append((bpy.data.worlds, world))
        nodes, links = world.node_tree.nodes, world.node_tree.links
        texture = nodes.new("ShaderNodeTexEnvironment")
        image = environment_image(environment)
        created.append((bpy.data.images, image))
        texture.image = image
        background = nodes.new("ShaderNodeBackground")
        links.new(texture.outputs["Color"], background.inputs["Color"])
        links.new(background.outputs["Background"], nodes.new("ShaderNodeOutputWorld").inputs["Surface"])
        scene.world = world
        white = _white_diffuse()
        created.append((bpy.data.materials, white))
        for ob in rendered_meshes(context, receivers):
            if not ob.material_slots:
                ob.data.materials.append(None)
            for slot in ob.material_slots:
                slot.material = white
        for ob in not_baked(context, receivers):
            ob.hide_render = True
        scene.render.engine = "CYCLES"
        cycles = scene.cycles
        cycles.device, cycles.samples = "CPU", samples
        cycles.max_bounces = cycles.diffuse_bounces = bounces
        cycles.sample_clamp_indirect = 0.0
        found = []
        for seed in range(passes):
            cycles.seed = seed
            found.append(_render_exr(scene, os.path.join(folder, f"cycles_{seed}.exr")))
    return np.stack(found)


def _white_diffuse():
    material = new_node_material("PRT validation white")
    nodes = material.node_tree.nodes
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    material.node_tree.links.new(diffuse.outputs["BSDF"], nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return material


def _lit_pixels(covered, cycles) -> np.ndarray:
    brightness = np.linalg.norm(cycles, axis=1)
    if not covered.any():
        return covered
    scale = np.sqrt(np.mean(brightness[covered] ** 2))
    return covered & (brightness > LIT_FRACTION * scale)


def _write_heatmap(path, lit, errors, resolution):
    """An image (in its suffix's format) of each lit pixel's error (viridis, 0 to the 99th percentile rounded up),
    grey where not compared."""
    width, height = resolution
    srgb = np.tile(np.array(UNLIT_SRGB), (width * height, 1))
    top = heatmap.scale_top(errors)
    srgb[lit] = heatmap.srgb_colours(errors, top)
    rgba = np.concatenate([srgb, np.ones((len(srgb), 1))], axis=1).astype(np.float32)
    image = bpy.data.images.new("PRT image error", width, height, alpha=True)
    try:
        image.pixels.foreach_set(rgba.ravel())
        image.file_format = outputs.image_format(path)
        outputs.save_image(image, path)
    finally:
        bpy.data.images.remove(image)
    return top


def compare_images(context, resolution=(160, 90), samples=LIGHT_SAMPLES, passes=DEFAULT_PASSES,
                   bounces: int = 0):
    """EEVEE's render of the PRT display (as the scene shows it now) against Cycles under the real light, with
    `bounces` diffuse bounces (0: direct light only, as a shadowed bake holds): a core.statistics.Comparison."""
    scene = context.scene
    if scene.camera is None:
        raise InputError("the scene has no camera to render from")
    if not scene.prt_display.show_prt:
        raise InputError("the PRT display is off: EEVEE would not show PRT")
    with tempfile.TemporaryDirectory(prefix="prt_compare_images_") as folder, \
            render_settings_restored(scene):
        scene.render.film_transparent = True
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
        scene.render.engine = eevee_engine_id()
        scene.eevee.taa_render_samples = samples[0]
        eevee = _render_rgba(scene, os.path.join(folder, "eevee.exr"))
        with paused(scene):
            cycles = np.stack([_real_light_cycles(context, samples[1], seed, bounces,
                                                  os.path.join(folder, f"cycles_{seed}.exr"))
                               for seed in range(passes)])
    covered = (eevee[:, 3] > COVERED) & np.all(cycles[..., 3] > COVERED, axis=0)
    return compare("image", eevee[covered][:, :3], cycles[:, covered][..., :3])


def _real_light_cycles(context, samples, seed, bounces, path):
    """Cycles under the scene's lights as they are, the display materials showing their diffuse term only."""
    scene = context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples, scene.cycles.seed = samples, seed
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = scene.cycles.diffuse_bounces = bounces
    created = []
    lamps = [entry.sun_lamp for entry in scene.prt_lights if entry.sun_lamp is not None]
    materials = {}
    slots = [(slot, slot.material) for ob in scene.objects if ob.type == "MESH" for slot in ob.material_slots
             if slot.material is not None and prt_display.DISPLAY_OF_KEY in slot.material]
    world, hidden = scene.world, {lamp: lamp.hide_render for lamp in lamps}
    try:
        scene.world = real_light_world(scene, created)
        for lamp in lamps:
            lamp.hide_render = True
        for slot, material in slots:
            if material not in materials:
                materials[material] = _diffuse_only(material)
            slot.material = materials[material]
        return _render_rgba(scene, path)
    finally:
        for slot, material in slots:
            slot.material = material
        for lamp, was in hidden.items():
            lamp.hide_render = was
        scene.world = world
        for material in materials.values():
            bpy.data.materials.remove(material)
        for collection, block in reversed(created):
            collection.remove(block)


def _diffuse_only(material):
    """A copy of a display material with the PRT emission off and the lamp's diffuse term on: a Diffuse BSDF of the
    same albedo, which Cycles lights with everything."""
    copy = material.copy()
    del copy[prt_display.DISPLAY_OF_KEY]  # not a display material: the display must not pick or switch it
    nodes = copy.node_tree.nodes
    nodes[prt_display.LAMP_SWITCH].inputs["Fac"].default_value = 1.0
    next(node for node in nodes if node.type == "EMISSION").inputs["Strength"].default_value = 0.0
    return copy
