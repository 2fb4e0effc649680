"""`prt demo`: build the original program's demo scene, bake it, light it with SH lights, render it with EEVEE,
write a report.

The lights are the add-on's own: a sun following the scene's Sun object plus a constant sky. The renders go
through `prt relight` (commands.relight.relight_file): EEVEE showing PRT colour × albedo texture, once as saved and
once with the sun moved round to the back, so the shadows visibly follow. The report says what was done and measured.
"""

import os
import time

import bpy

from ..blender import lights, sample_scenes
from ..blender.execute import execute, local_executor
from ..blender.outputs import save_blend
from ..blender.plan import plan_bake
from ..blender.relighting import Relighter
from ..blender.request import read_request
from ..blender.schema import add_light
from ..blender.store import store
from ..core import bake
from ..core.settings import worker_count
from .common import check_outputs, log, write_json
from .relight import relight_file

SUN_IRRADIANCE = 2.0
SKY_RADIANCE = 0.15
MOVED_SUN = (40.0, 120.0)  # θ, φ in degrees: behind and to the left, so the torus's shadow falls forward
RENDER_SAMPLES = 8
BLEND, RENDERS, REPORT = "demo_baked.blend", ("demo.png", "demo_moved.png"), "demo_report.json"  # in --output


def add_parser(commands):
    parser = commands.add_parser("demo", help="build the sample scene, bake, relight, render a PNG and a report")
    parser.add_argument("--output", default="demo_output", help="folder for the PNG, report and .blend")
    parser.add_argument("--workers", type=int, default=2, help="bake worker processes")
    parser.add_argument("--samples", type=int, default=256, help="rays per vertex of the demo's bake")


def run(args, in_blender: bool) -> int:
    return demo(args.output, workers=args.workers, samples=args.samples)


def demo(output: str, workers: int = 2, samples: int = 256) -> int:
    blend_path, report_path = (os.path.abspath(os.path.join(output, name)) for name in (BLEND, REPORT))
    check_outputs([(f"the demo's {name}", os.path.join(output, name)) for name in (BLEND, *RENDERS, REPORT)])
    baked = save_baked_demo(blend_path, workers, samples)
    renders = [
        relight_file(blend_path, os.path.join(output, RENDERS[0]), samples=RENDER_SAMPLES),
        relight_file(blend_path, os.path.join(output, RENDERS[1]), light_index=0,
                     theta_deg=MOVED_SUN[0], phi_deg=MOVED_SUN[1], samples=RENDER_SAMPLES),
    ]
    for done in renders:
        log(f"prt demo: rendered {done['path']} with {done['engine']} in {done['render_s']:.1f} s")
    report = {**baked, "renders": renders, "blend": blend_path}
    write_json(report_path, report)
    print(f"prt demo: wrote {', '.join(done['path'] for done in renders)}, {blend_path} and {report_path}")
    return 0


def save_baked_demo(blend_path: str, workers: int, samples: int) -> dict:
    """Builds the demo scene, bakes it, lights it, switches the PRT display on and saves it to `blend_path`;
    returns the report's bake and relight sections."""
    bpy.ops.wm.read_homefile(use_empty=True)
    objects = sample_scenes.build_demo_scene()
    print(f"prt demo: built the demo scene ({', '.join(sorted(o.name for o in objects.values() if o))})")

    settings = bake.BakeSettings(order=4, mode="shadowed", samples=samples)
    plan = plan_bake(read_request(bpy.context, settings))
    stored = store(plan, execute(plan, local_executor(worker_count(workers))).run(log=log))
    log(stored.summary.line())
    log(stored.summary.curve_line())
    bake_report = stored.as_dict()  # before the file is reopened and these objects go

    scene = bpy.context.scene
    add_lights(scene, objects["sun"])
    scene.prt_display.show_prt = True
    start = time.perf_counter()
    Relighter().refresh(scene, bpy.context.evaluated_depsgraph_get())
    relight_s = time.perf_counter() - start
    save_blend(blend_path)
    return {"bake": bake_report,
            "relight": {"lights": [lights.describe(entry, scene) for entry in scene.prt_lights],
                        "display": "PRT colour attribute × albedo texture (display materials)",
                        "time_s": relight_s, "timed": "lights set → every mesh's colours written, including the "
                                                      "first read of its transfer"}}


def add_lights(scene, sun_object):
    """A sun that follows the scene's Sun object, and a dim sky so that shadows are not black."""
    sun = add_light(scene, "SUN")
    sun.sun_object = sun_object
    sun.strength = SUN_IRRADIANCE
    add_light(scene, "SKY").strength = SKY_RADIANCE
    scene.prt_active_light = 0
