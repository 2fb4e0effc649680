"""heatmap.png: the demo bake's error heatmaps, the Display panel's Show menu (blender.schema's DISPLAY_MODES) at
Estimated Error (the bake's own) and at Difference from Cycles (after the Validation panel's Validate with Cycles
has stored its per-vertex errors: blender.validation), each with the legend the panel draws (its colour scale and
range, core.heatmap). Each is the display colour attribute the relighting engine paints (blender.heatmaps),
rendered by `prt relight --engine WORKBENCH`'s renderer (blender.render), which shows that attribute as it is. The
menu's Decided by Rule is left out: no rule decides a point of the demo (nothing in it touches a surface), so it
would be grey all over.

Printed, and read back by tests/test_figures.py: per mode its scale's top and the RMS of the values over every
vertex, so the bake's estimated error and its measured difference from Cycles can be set side by side.
"""

import os

import bpy
import numpy as np

from figures_common import colour_scale, new_figure, read_png, save, show_image
from prt_addon.blender import heatmaps, storage
from prt_addon.blender.relighting import Relighter
from prt_addon.blender.render import render
from prt_addon.blender.schema import DISPLAY_MODES
from prt_addon.blender.validation import Validation
from prt_addon.commands.common import open_file
from prt_addon.core import heatmap

NAME = "heatmap.png"
RESOLUTION = {"full": (560, 420), "quick": (240, 180)}
VALIDATION = {"full": (64, 2), "quick": (16, 2)}  # Cycles samples per pass, passes
MODES = ("ERROR", "DIFFERENCE")
TITLES = {mode: name for mode, name, _ in DISPLAY_MODES}
SCALES = {"ERROR": "estimated relative error", "DIFFERENCE": "error against Cycles"}


def make(run) -> str:
    open_file(run.demo_blend(), required=True)
    context, scene = bpy.context, bpy.context.scene
    validation = Validation(context, *run.pick(VALIDATION))
    comparisons = validation.run(log=lambda line: None)
    validation.store_errors(comparisons)  # as the Validation panel's button does: the Difference heatmap's values
    print("heatmap: validated: " + validation.lines(comparisons)[0])
    receivers = storage.baked_objects(context.view_layer.objects)
    panels = []
    for mode in MODES:
        scene.prt_display.mode = mode  # switches the PRT display on, as choosing it in the panel does
        relighter = Relighter()
        relighter.refresh(scene, context.evaluated_depsgraph_get())
        path = os.path.join(run.scratch, f"heatmap_{mode.lower()}.png")
        render(scene, path, "WORKBENCH", resolution=run.pick(RESOLUTION))
        values = np.concatenate([rows for rows, _ in filter(None, heatmaps.read(receivers, mode).values())])
        top = relighter.legend.top
        print(f"heatmap {TITLES[mode]}: scale {heatmap.range_label(top)}, RMS "
              f"{100 * np.sqrt(np.mean(np.square(values))):.2f} % over {len(values)} points")
        panels.append((mode, read_png(path), top))

    height, width = panels[0][1].shape[:2]
    figure = new_figure(len(panels) * width + 40, height + 120)
    axes = figure.subplots(2, len(panels), height_ratios=(height, 30))
    for column, (mode, image, top) in enumerate(panels):
        show_image(axes[0, column], image, f"Show: {TITLES[mode]}")
        colour_scale(axes[1, column], top, f"{SCALES[mode]} (%); above {100 * top:.4g} %: the top colour")
    return save(figure, run.path(NAME))

