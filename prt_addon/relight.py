"""`prt relight`: open a baked file, change an SH light, and render what the PRT display shows.

EEVEE renders the display materials (PRT colour × albedo texture); Workbench renders the colour attribute alone.
Both use the Standard view transform, so a pixel is the sRGB encoding of the radiance, not a tone-mapped look.
"""

import math
import os
import time

import bpy

from . import display

ENGINES = ("EEVEE", "WORKBENCH")


class RelightError(Exception):
    pass


def ensure_registered():
    """With the bpy module the add-on is not enabled: register its properties and handlers for this process."""
    if not hasattr(bpy.types.Scene, "prt_lights"):
        from . import ui
        ui.register()


def relight_file(path, render_path, light_index=None, theta_deg=None, phi_deg=None, engine="EEVEE", samples=4,
                 resolution=None) -> dict:
    """Opens `path`, aims one light (default: the active one), renders `render_path`; returns what it did."""
    if not os.path.isfile(path):
        raise RelightError(f"no such file: {path}")
    ensure_registered()
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
    scene = bpy.context.scene
    if not scene.prt_lights:
        raise RelightError(f"{path} has no SH lights; add one in the sidebar's PRT tab")
    if theta_deg is not None or phi_deg is not None:
        aim_light(scene, scene.prt_active_light if light_index is None else light_index, theta_deg, phi_deg)
    scene.prt_display.show_prt = True
    start = time.perf_counter()
    refresh(scene)
    relight_s = time.perf_counter() - start
    render_s = render(scene, render_path, engine, samples, resolution)
    return {"file": os.path.abspath(path), "lights": [describe(light) for light in scene.prt_lights],
            "relight_s": relight_s, "engine": engine_id(engine), "samples": samples if engine == "EEVEE" else None,
            "resolution": [scene.render.resolution_x, scene.render.resolution_y],
            "path": os.path.abspath(render_path), "render_s": render_s}


def aim_light(scene, index, theta_deg=None, phi_deg=None):
    """Sets a light's θ and/or φ (degrees); a light that followed a Sun object stops following it."""
    if not 0 <= index < len(scene.prt_lights):
        raise RelightError(f"no SH light {index}: the file has {len(scene.prt_lights)} (0-{len(scene.prt_lights) - 1})")
    light = scene.prt_lights[index]
    if light.kind != "SUN":
        raise RelightError(f"SH light {index} ({light.name!r}) is a {light.kind.lower()}, not a sun: it has no θ, φ")
    if light.sun_object is not None:
        print(f"prt: SH light {light.name!r} no longer follows {light.sun_object.name!r}")
        light.angular_radius = light.sun_angular_radius()
        light.theta, light.phi = _angles_of(light.sun_direction())
        light.sun_object = None
    if theta_deg is not None:
        light.theta = math.radians(theta_deg)
    if phi_deg is not None:
        light.phi = math.radians(phi_deg)


def _angles_of(direction):
    x, y, z = direction
    return math.acos(max(-1.0, min(1.0, z))), math.atan2(y, x)


def refresh(scene):
    """Relights now, as the handler would after the next evaluation."""
    from .ui import handlers
    handlers.refresh(scene, bpy.context.evaluated_depsgraph_get())


def engine_id(engine: str) -> str:
    """Blender's id: EEVEE is BLENDER_EEVEE_NEXT in 4.2-4.4 and BLENDER_EEVEE from 5.0 on."""
    if engine == "WORKBENCH":
        return "BLENDER_WORKBENCH"
    ids = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in ids else "BLENDER_EEVEE"


def render(scene, path, engine="EEVEE", samples=4, resolution=None) -> float:
    """Renders the scene's camera view to a PNG; returns the seconds it took."""
    if engine not in ENGINES:
        raise RelightError(f"unknown engine {engine!r}: expected one of {', '.join(ENGINES)}")
    if scene.camera is None:
        raise RelightError("the scene has no camera to render from")
    scene.render.engine = engine_id(engine)
    if engine == "EEVEE":
        scene.eevee.taa_render_samples = samples
    else:  # the active colour attribute, made the PRT colour, as it is: unlit
        scene.display.shading.light = "FLAT"
        scene.display.shading.color_type = "VERTEX"
        for mesh in bpy.data.meshes:
            if display.DISPLAY_ATTRIBUTE in mesh.color_attributes:
                mesh.color_attributes.active_color = mesh.color_attributes[display.DISPLAY_ATTRIBUTE]
    scene.view_settings.view_transform = "Standard"
    if resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.abspath(path)
    os.makedirs(os.path.dirname(scene.render.filepath), exist_ok=True)
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - start


def describe(light) -> str:
    """One line for reports: what shines, from where, how strongly."""
    rgb = ", ".join(f"{c:g}" for c in light.rgb())
    state = "" if light.use else " (off)"
    if light.kind == "SUN":
        source = (f"following {light.sun_object.name!r}" if light.sun_object else
                  f"θ {math.degrees(light.theta):.1f}°, φ {math.degrees(light.phi):.1f}°")
        radius = math.degrees(light.sun_angular_radius())
        return f"sun {light.name!r}{state}: {source}, radius {radius:.2f}°, irradiance ({rgb})"
    if light.kind == "SKY":
        return f"sky {light.name!r}{state}: radiance ({rgb})"
    image = light.environment_image(bpy.context.scene)
    return f"environment {light.name!r}{state}: {image.name if image else 'no image'}, × ({rgb})"
