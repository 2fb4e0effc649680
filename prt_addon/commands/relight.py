"""`prt relight`: open a baked file, aim an SH light, and render what the PRT display shows (blender.render)."""

import argparse
import os
import time

import bpy

from ..blender import lights
from ..blender.relighting import Relighter
from ..blender.render import ENGINES, engine_id, render
from ..core.errors import InputError
from . import light_options
from ..blender.outputs import IMAGE_FORMATS
from ..core.outputs import check_suffix
from .common import check_outputs, open_file, whole_number


def add_parser(commands):
    parser = commands.add_parser("relight", help="re-render a baked .blend file under changed SH lights")
    parser.add_argument("file", help=".blend file with a bake and SH lights")
    parser.add_argument("--light", type=whole_number("--light", 0),
                        help="index of the SH light to aim (default: the active one)")
    parser.add_argument("--light-theta", type=float, metavar="DEGREES", help="angle from the zenith; a light that "
                        "follows a Sun object stops following it")
    parser.add_argument("--light-phi", type=float, metavar="DEGREES", help="azimuth, from +X towards +Y")
    parser.add_argument("--engine", choices=ENGINES, default="EEVEE",
                        help="EEVEE: PRT colour × albedo texture; WORKBENCH: the PRT colour alone, faster")
    parser.add_argument("--samples", type=whole_number("--samples", 1), default=4, help="EEVEE render samples")
    parser.add_argument("--resolution", type=_resolution, metavar="WxH", help="default: the file's")
    parser.add_argument("--render", required=True, metavar="OUT.png",
                        help="where to write the image, as PNG or JPEG after its suffix (.png, .jpg)")
    light_options.add_arguments(parser)


def _resolution(text):
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, e.g. 640x480, got {text!r}") from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"resolution must be positive, got {text!r}")
    return width, height


def run(args, in_blender: bool) -> int:
    done = relight_file(args.file, args.render, args.light, args.light_theta, args.light_phi,
                        engine=args.engine, samples=args.samples, resolution=args.resolution,
                        add_lights=lambda scene: light_options.add_lights(scene, args), inputs=[("--env", args.env)])
    width, height = done["resolution"]
    print(f"prt: rendered {done['path']} with {done['engine']} at {width}×{height} in {done['render_s']:.1f} s "
          f"(relit in {1000 * done['relight_s']:.0f} ms)")
    for line in done["lights"]:
        print(f"prt:   {line}")
    return 0


def relight_file(path, render_path, light_index=None, theta_deg=None, phi_deg=None, engine="EEVEE", samples=4,
                 resolution=None, add_lights=None, inputs=()) -> dict:
    """Opens `path`, adds SH lights (`add_lights(scene)`), aims one light (default: the active one), renders
    `render_path`, which is refused before any work where it would replace the file, a file it uses or one of the
    other `inputs` ((what, path) pairs); returns what it did."""
    check_suffix(render_path, "--render", list(IMAGE_FORMATS))
    open_file(path, required=True)
    check_outputs([("--render", render_path)], inputs)
    scene = bpy.context.scene
    if add_lights:
        add_lights(scene)
    if not scene.prt_lights:
        raise InputError(f"{path} has no SH lights; give --sun, --env or --sky, or add one in the sidebar's PRT tab")
    if theta_deg is not None or phi_deg is not None:
        said = lights.aim_sun(scene, scene.prt_active_light if light_index is None else light_index, theta_deg,
                              phi_deg)
        if said:
            print(f"prt: {said}")
    scene.prt_display.show_prt = True
    start = time.perf_counter()
    Relighter().refresh(scene, bpy.context.evaluated_depsgraph_get())  # now, as the handler would after evaluation
    relight_s = time.perf_counter() - start
    render_s = render(scene, render_path, engine, samples, resolution)
    return {"file": os.path.abspath(path), "lights": [lights.describe(entry, scene) for entry in scene.prt_lights],
            "relight_s": relight_s, "engine": engine_id(engine), "samples": samples if engine == "EEVEE" else None,
            "resolution": [scene.render.resolution_x, scene.render.resolution_y],
            "path": os.path.abspath(render_path), "render_s": render_s}
