"""`prt demo`: build the seed's demo scene, bake it, relight it under a sun and sky, render a PNG, write a report.

It reports only what it did: the display here is Workbench showing the PRT colour attribute.
"""

import json
import os
import time

import bpy
import numpy as np

from . import baking, mesh_data, scenes
from .core import bake, lobes, shading

DISPLAY_ATTRIBUTE = "prt_color"


def run(output: str, workers: int = 2, samples: int = 256) -> int:
    os.makedirs(output, exist_ok=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    objects = scenes.build_demo_scene()
    print(f"prt demo: built the demo scene ({', '.join(sorted(o.name for o in objects.values() if o))})")

    settings = bake.BakeSettings(order=4, mode="shadowed", samples=samples)
    scene_bake = baking.SceneBake(bpy.context, settings, workers=workers)
    summary = scene_bake.run(log=lambda line: print(line, flush=True))
    print(summary.line(), flush=True)

    sun = bpy.data.objects["Sun"]
    sun_direction = np.array(sun.matrix_world.to_3x3().col[2])  # a Sun light shines along its local -Z
    light = (shading.sun_coefficients(4, sun_direction, sun.data.angle / 2, irradiance=2.0)
             + lobes.constant_sky(4, radiance=0.15))
    start = time.perf_counter()
    for ob in scene_bake.objects:
        transfer, _ = mesh_data.read_transfer(ob.data)
        write_display_colours(ob.data, np.maximum(shading.shade(transfer, light[None, :]), 0.0))
    relight_s = time.perf_counter() - start

    image_path = os.path.abspath(os.path.join(output, "demo.png"))
    render_s = render_workbench(image_path)
    blend_path = os.path.abspath(os.path.join(output, "demo_baked.blend"))
    bpy.ops.wm.save_as_mainfile(filepath=blend_path)
    report = {
        "bake": scene_bake.report_dict(),
        "relight": {"light": "sun (irradiance 2, from the Sun object) + constant sky 0.15",
                    "time_s": relight_s},
        "render": {"engine": "BLENDER_WORKBENCH", "display": f"colour attribute {DISPLAY_ATTRIBUTE!r}",
                   "path": image_path, "time_s": render_s},
        "blend": blend_path,
    }
    with open(os.path.join(output, "demo_report.json"), "w", encoding="utf-8") as handle:
        json.dump(report, handle, indent=2)
    print(f"prt demo: wrote {image_path}, {blend_path} and {os.path.join(output, 'demo_report.json')}")
    return 0


def write_display_colours(mesh, rgb: np.ndarray):
    """(V, 3) linear radiance into a FLOAT_COLOR point attribute, alpha 1."""
    if DISPLAY_ATTRIBUTE not in mesh.color_attributes:
        mesh.color_attributes.new(DISPLAY_ATTRIBUTE, "FLOAT_COLOR", "POINT")
    rgba = np.ones((len(mesh.vertices), 4), dtype=np.float32)
    rgba[:, :3] = rgb if rgb.shape[1] == 3 else rgb[:, :1]
    mesh.color_attributes[DISPLAY_ATTRIBUTE].data.foreach_set("color", rgba.ravel())
    mesh.color_attributes.active_color = mesh.color_attributes[DISPLAY_ATTRIBUTE]
    mesh.update()


def render_workbench(path: str) -> float:
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "FLAT"
    scene.display.shading.color_type = "VERTEX"
    scene.view_settings.view_transform = "Standard"
    scene.render.filepath = path
    scene.render.image_settings.file_format = "PNG"
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - start
