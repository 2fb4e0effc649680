"""Validation in image space: what EEVEE shows (the PRT display, with a split-off sun's lamp adding its diffuse
light and sharp shadows) against Cycles under the scene's lights as they are (the raw HDRI), from the same camera.

Cycles renders the same display materials with the PRT emission off and the diffuse term on, so both see the same
albedo (textures through the same UV maps) and geometry; the lamps of split-off suns are hidden from it (the raw
image holds their suns). Both render with a transparent film, and only pixels covered in both are compared, as
core.statistics compares vertices: relative to the RMS of ‖Cycles‖, with Cycles' noise (from the spread of its
passes) taken out.
"""

from contextlib import contextmanager
import os
import tempfile

import bpy
import numpy as np

from ..core.errors import InputError
from ..core.statistics import Comparison, compare
from . import display
from .compat import eevee_engine_id
from .cycles import real_light_world
from .relighting import paused

COVERED = 0.999  # alpha above which a pixel shows an object in both renders
DEFAULT_SAMPLES = (16, 64)  # EEVEE's, Cycles' per pass
DEFAULT_PASSES = 2


def compare_images(context, resolution=(160, 90), samples=DEFAULT_SAMPLES, passes=DEFAULT_PASSES,
                   bounces: int = 0) -> Comparison:
    """EEVEE's render of the PRT display (as the scene shows it now) against Cycles under the real light, with
    `bounces` diffuse bounces (0: direct light only, as a shadowed bake holds)."""
    scene = context.scene
    if scene.camera is None:
        raise InputError("the scene has no camera to render from")
    if not scene.prt_display.show_prt:
        raise InputError("the PRT display is off: EEVEE would not show PRT")
    with _render_settings(scene, resolution):
        eevee = _eevee(scene, samples[0])
        with paused(scene):
            cycles = np.stack([_cycles(context, samples[1], seed, bounces) for seed in range(passes)])
    covered = (eevee[..., 3] > COVERED) & np.all(cycles[..., 3] > COVERED, axis=0)
    return compare("image", eevee[covered][:, :3], cycles[:, covered][..., :3])


def _eevee(scene, samples):
    scene.render.engine = eevee_engine_id()
    scene.eevee.taa_render_samples = samples
    return _rendered(scene)


def _cycles(context, samples, seed, bounces):
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
             if slot.material is not None and display.DISPLAY_OF_KEY in slot.material]
    world, hidden = scene.world, {lamp: lamp.hide_render for lamp in lamps}
    try:
        scene.world = real_light_world(scene, created)
        for lamp in lamps:
            lamp.hide_render = True
        for slot, material in slots:
            if material not in materials:
                materials[material] = _diffuse_only(material)
            slot.material = materials[material]
        return _rendered(scene)
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
    del copy[display.DISPLAY_OF_KEY]  # not a display material: the display must not pick or switch it
    nodes = copy.node_tree.nodes
    nodes[display.LAMP_SWITCH].inputs["Fac"].default_value = 1.0
    next(node for node in nodes if node.type == "EMISSION").inputs["Strength"].default_value = 0.0
    return copy


def _rendered(scene) -> np.ndarray:
    """The camera's view as linear RGBA (H, W, 4), through an OpenEXR file."""
    with tempfile.TemporaryDirectory() as folder:
        scene.render.filepath = os.path.join(folder, "render.exr")
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(scene.render.filepath)
        try:
            width, height = image.size
            pixels = np.empty(width * height * 4, dtype=np.float32)
            image.pixels.foreach_get(pixels)
        finally:
            bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)


@contextmanager
def _render_settings(scene, resolution):
    render, cycles = scene.render, scene.cycles
    saved = [(render, name, getattr(render, name)) for name in
             ("engine", "film_transparent", "resolution_x", "resolution_y", "resolution_percentage", "filepath")]
    saved += [(cycles, name, getattr(cycles, name))
              for name in ("device", "samples", "seed", "use_denoising", "max_bounces", "diffuse_bounces")]
    saved += [(scene.eevee, "taa_render_samples", scene.eevee.taa_render_samples)]
    saved += [(render.image_settings, name, getattr(render.image_settings, name))
              for name in ("file_format", "color_depth")]
    try:
        render.film_transparent = True
        render.resolution_x, render.resolution_y = resolution
        render.resolution_percentage = 100
        render.image_settings.file_format = "OPEN_EXR"
        render.image_settings.color_depth = "32"
        yield
    finally:
        for owner, name, value in saved:
            setattr(owner, name, value)
