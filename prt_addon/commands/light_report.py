"""`prt light-report`: how well each SH order carries the scene's SH lights, from the lights alone (no bake, no
Cycles): the light's projection error and the predicted shading error per order through the display's window, the
order recommended for a target, and the suns found in environment images; optionally a plot."""

import math
import os

import bpy

from ..blender import lights
from ..core import light_fidelity
from ..core.errors import InputError
from ..core.settings import ORDER_TARGET
from ..core.outputs import check_suffix, replacing
from .common import check_outputs, log, open_file, write_json

COMMAND = "light-report"
PLOT_SUFFIXES = (".png", ".svg", ".pdf")  # the plot's format follows its suffix


def add_parser(commands):
    parser = commands.add_parser(COMMAND, help="the error of each SH order under the scene's lights, and the order "
                                               "to bake at")
    parser.add_argument("file", nargs="?", help=".blend file with SH lights (in Blender: defaults to the open file)")
    parser.add_argument("--target", type=float, default=ORDER_TARGET.default,
                        help=f"predicted shading error the recommended order meets ({ORDER_TARGET.range_text()})")
    parser.add_argument("--plot", help="write the two errors against the order here, as .png, .svg or .pdf (needs "
                                       "matplotlib, which Blender does not bundle: use the bpy module)")
    parser.add_argument("--report", help="write the figures as JSON here")


def run(args, in_blender: bool) -> int:
    if args.plot:
        check_suffix(args.plot, "--plot", PLOT_SUFFIXES)
        _pyplot()
    open_file(args.file, required=not in_blender)
    check_outputs([("--report", args.report), ("--plot", args.plot)])
    if not ORDER_TARGET.contains(args.target):
        raise InputError(f"--target must be {ORDER_TARGET.range_text()}, not {args.target}")
    scene = bpy.context.evaluated_depsgraph_get().scene_eval
    if not lights.scene_lights(scene):
        raise InputError("the file has no SH light that shines (Lights panel)")
    fidelity = lights.scene_fidelity(scene, args.target)
    log(f"PRT light report: {len(scene.prt_lights)} SH lights, window {scene.prt_display.window}, "
        f"target {100 * args.target:g} % predicted shading error")
    for entry in scene.prt_lights:
        log(f"  {lights.describe(entry, scene)}")
        found = lights.found_sun(entry, scene)
        if found is not None:
            log(f"    a sun in its image: radius {math.degrees(found.angular_radius):.2f}°, irradiance "
                f"({', '.join(f'{c:.3g}' for c in found.irradiance)}), {100 * found.share:.0f} % of its light"
                + ("; split off into a lamp" if entry.split_sun else "; Split Off Sun would give it to a lamp"))
    for line in fidelity.table():
        log(line)
    log(f"recommended: order {fidelity.recommended} (predicted {100 * fidelity.predicted[fidelity.recommended]:.1f} %)")
    if args.plot:
        plot(fidelity, args.plot)
    if args.report:
        write_json(args.report, {"target": args.target, "window": scene.prt_display.window,
                                 "recommended_order": fidelity.recommended,
                                 "projection_error": {str(n): e for n, e in fidelity.projection.items()},
                                 "predicted_error": {str(n): e for n, e in fidelity.predicted.items()}})
    return 0


def _pyplot():
    """matplotlib's pyplot drawing off screen; refused, naming how to get it, where it is not installed."""
    try:
        import matplotlib
    except ImportError:
        raise InputError("--plot needs matplotlib, which Blender does not bundle: run `python -m prt_addon "
                         "light-report FILE --plot OUT.png` with the bpy module and matplotlib installed") from None
    matplotlib.use("Agg")
    from matplotlib import pyplot
    return pyplot


def plot(fidelity: light_fidelity.LightFidelity, path: str):
    pyplot = _pyplot()
    orders = sorted(fidelity.predicted)
    figure, axes = pyplot.subplots(figsize=(6, 4))
    axes.plot(orders, [100 * fidelity.projection[n] for n in orders], "o-", label="light's projection (L2)")
    axes.plot(orders, [100 * fidelity.predicted[n] for n in orders], "s-", label="predicted shading")
    axes.axhline(100 * fidelity.target, color="grey", linestyle=":", label="target")
    axes.axvline(fidelity.recommended, color="grey", linestyle="--", label=f"recommended: {fidelity.recommended}")
    axes.set_xlabel("SH order (bands)")
    axes.set_ylabel("relative error (%)")
    axes.set_yscale("log")
    axes.legend()
    figure.tight_layout()
    with replacing(path) as temporary:
        figure.savefig(temporary, dpi=100, format=os.path.splitext(path)[1][1:].lower())
    pyplot.close(figure)
