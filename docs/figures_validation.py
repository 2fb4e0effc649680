"""validation.png: `prt validate --image` on the demo bake: the PRT display (EEVEE) | Cycles | their difference, with
the RMS error printed on it. The command (blender.image_validation.validate_image) renders both sides under the
scene's SH lights band-limited to the bake's order, every surface white, compares the lit pixels and writes the
difference as its --heatmap; it keeps its renders to itself, so the PRT and Cycles panels are a render of each
side made the same way (image_validation.band_limited_renders, one Cycles pass) at the same size.

Printed, and read back by tests/test_figures.py: the command's own line, with the RMS error over the lit pixels.
"""

import os

import bpy

from figures_common import (band_limited_pair, colour_scale, exposure, new_figure, read_png, save, show_image,
                            to_srgb)
from prt_addon.blender import storage
from prt_addon.blender.image_validation import validate_image
from prt_addon.commands.common import open_file
from prt_addon.core import heatmap

NAME = "validation.png"
RESOLUTION = {"full": (400, 300), "quick": (160, 120)}
CYCLES = {"full": (32, 2), "quick": (8, 2)}  # samples per pass, passes


def make(run) -> str:
    open_file(run.demo_blend(), required=True)
    context = bpy.context
    resolution = run.pick(RESOLUTION)
    samples, passes = run.pick(CYCLES)
    difference_path = os.path.join(run.scratch, "validation_heatmap.png")
    report = validate_image(context, None, samples, passes, resolution, difference_path)
    print(report.line())
    comparison = report.comparison
    top = heatmap.scale_top(comparison.errors)  # the --heatmap's scale
    order = storage.baked_objects(context.view_layer.objects)[0].data[storage.METADATA_KEY]["order"]
    scene = context.scene
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    prt, cycles = band_limited_pair(context, order, samples, run.scratch)
    cycles[prt.max(axis=2) == 0.0] = 0.0  # the background as EEVEE's (black) rather than the light's image
    scale = exposure(cycles)

    width, height = resolution
    figure = new_figure(3 * width + 80, height + 150)
    axes = figure.subplots(2, 3, height_ratios=(height, 30))
    show_image(axes[0, 0], to_srgb(prt, scale), f"PRT (EEVEE), order {order}")
    show_image(axes[0, 1], to_srgb(cycles, scale), "Cycles, the same light")
    show_image(axes[0, 2], read_png(difference_path), f"Difference: RMS {100 * comparison.error:.2f} %")
    for ax in axes[1, :2]:
        ax.set_axis_off()
    colour_scale(axes[1, 2], top, "error, % of Cycles' RMS; grey: not compared")
    figure.suptitle(f"prt validate --image: {comparison.vertices} lit pixels, error {100 * comparison.error:.2f} % "
                    f"RMS (Cycles' noise {100 * comparison.cycles_noise:.2f} % taken out), p99 "
                    f"{100 * comparison.p99:.1f} %", fontsize=10)
    return save(figure, run.path(NAME))
