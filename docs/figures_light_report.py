"""light_report.png: `prt light-report` on an HDRI that Blender bundles (its studio light "sunrise", the Lights
page's example): the image as an SH environment light (the Lights panel's Environment, as the image) beside its SH
reconstruction at the order the report recommends, band-limited and windowed as the PRT display shows it
(blender.validation.scene_light); below them the command's --plot and the figures it prints. The image's sun is
sharp: no order meets the target, so the report recommends the highest and names the sun to split off.

Printed, and read back by tests/test_figures.py: the command's lines (its table of the light's projection error and
the predicted shading error per order, and the order recommended), and the projection error at that order measured
on the image itself, independently of the command's band powers: ‖image − its projection‖ ÷ ‖image‖ over the
sphere (core.lobes, each pixel weighted by its solid angle).
"""

import contextlib
import io
import json
import os
import textwrap

import bpy
import numpy as np

from figures_common import exposure, new_figure, read_png, save, show_image, to_srgb
from prt_addon.blender.outputs import save_blend
from prt_addon.blender.schema import add_light
from prt_addon.blender.validation import scene_light
from prt_addon.commands import cli
from prt_addon.core import lobes

NAME = "light_report.png"
HDRI = "sunrise.exr"
TEXT_COLUMNS = 84  # the printed lines wrap here, to fit beside the plot
SHOWN_ROWS = {"full": 256, "quick": 64}  # the panels' equirect height


def make(run) -> str:
    blend, plot, report = (os.path.join(run.scratch, name) for name in
                           ("light_report.blend", "light_report_plot.png", "light_report.json"))
    bpy.ops.wm.read_homefile(use_empty=True)
    image = bpy.data.images.load(os.path.join(bpy.utils.system_resource("DATAFILES"), "studiolights", "world", HDRI))
    add_light(bpy.context.scene, "ENVIRONMENT").image = image
    save_blend(blend)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        status = cli.main(["light-report", blend, "--plot", plot, "--report", report])
    print(printed.getvalue(), end="")
    if status:
        raise RuntimeError(f"prt light-report failed with status {status}")
    with open(report, encoding="utf-8") as handle:
        order = json.load(handle)["recommended_order"]

    image = bpy.data.images[HDRI]  # the file the command opened holds it
    pixels = image_pixels(image)
    residual = pixels - lobes.reconstruct_equirect(lobes.project_equirect(pixels, order), *pixels.shape[:2])
    weights = lobes.equirect_solid_angles(*pixels.shape[:2])[..., None]
    measured = np.sqrt(np.sum(weights * residual ** 2) / np.sum(weights * pixels ** 2))
    print(f"light report: measured on the image at order {order}: projection error {100 * measured:.1f} %")

    rows = run.pick(SHOWN_ROWS)
    shown = lobes.box_filtered(pixels, rows)
    totals, _ = scene_light(bpy.context, [order])
    reconstruction = lobes.reconstruct_equirect(totals[order], *shown.shape[:2])
    scale = exposure(shown)
    lines = [line for line in printed.getvalue().splitlines() if line.strip()]

    figure = new_figure(1200, 820)
    grid = figure.add_gridspec(2, 2, height_ratios=(1.0, 1.3))
    show_image(figure.add_subplot(grid[0, 0]), to_srgb(shown[::-1], scale), f"{HDRI}, bundled with Blender")
    show_image(figure.add_subplot(grid[0, 1]), to_srgb(reconstruction[::-1], scale),
               f"its SH light at order {order}, as the display shows it (window {bpy.context.scene.prt_display.window})")
    plotted = figure.add_subplot(grid[1, 0])
    show_image(plotted, read_png(plot))
    plotted.set_axis_off()  # the plot has its own frame
    text = figure.add_subplot(grid[1, 1])
    text.set_axis_off()
    wrapped = [part for line in lines for part in textwrap.wrap(line, TEXT_COLUMNS, subsequent_indent="      ")]
    text.text(0.0, 1.0, "$ prt light-report FILE --plot PLOT.png\n" + "\n".join(wrapped), va="top",
              family="monospace", fontsize=8.5, transform=text.transAxes).set_in_layout(False)
    return save(figure, run.path(NAME))


def image_pixels(image) -> np.ndarray:
    """(H, W, 3) float64 linear RGB, row 0 at the bottom (Blender's layout, as core.lobes takes it)."""
    width, height = image.size
    flat = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(height, width, image.channels)[..., :3].astype(np.float64)

