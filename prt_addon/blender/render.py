"""Rendering what the PRT display shows, from the scene's camera, to an image (.png or .jpg: blender.outputs).

EEVEE renders the display materials (PRT colour × albedo texture); Workbench renders the colour attribute alone.
Both use the Standard view transform, so a pixel is the sRGB encoding of the radiance, not a tone-mapped look.
"""

import time

import bpy

from ..core.errors import InputError
from .compat import eevee_engine_id
from .display import DISPLAY_ATTRIBUTE
from .outputs import image_format, writing_image

ENGINES = ("EEVEE", "WORKBENCH")


def engine_id(engine: str) -> str:
    return "BLENDER_WORKBENCH" if engine == "WORKBENCH" else eevee_engine_id()


def render(scene, path, engine="EEVEE", samples=4, resolution=None) -> float:
    """Renders the scene's camera view to `path` in its suffix's format, whole or not at all; returns the seconds
    it took."""
    if engine not in ENGINES:
        raise InputError(f"unknown engine {engine!r}: expected one of {', '.join(ENGINES)}")
    if scene.camera is None:
        raise InputError("the scene has no camera to render from")
    scene.render.engine = engine_id(engine)
    if engine == "EEVEE":
        scene.eevee.taa_render_samples = samples
    else:  # the active colour attribute, made the PRT colour, as it is: unlit
        scene.display.shading.light = "FLAT"
        scene.display.shading.color_type = "VERTEX"
        for mesh in bpy.data.meshes:
            if DISPLAY_ATTRIBUTE in mesh.color_attributes:
                mesh.color_attributes.active_color = mesh.color_attributes[DISPLAY_ATTRIBUTE]
    scene.view_settings.view_transform = "Standard"
    if resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = image_format(path)
    start = time.perf_counter()
    with writing_image(path) as temporary:
        bpy.ops.render.render(scene=scene.name)
        # At exactly the path given (a still's output would get its format's suffix), through the scene's view
        # transform and image settings as a still's.
        bpy.data.images["Render Result"].save_render(filepath=temporary, scene=scene)
    return time.perf_counter() - start
