"""The Display panel's legend for its heatmap modes (blender.schema's DISPLAY_MODES): swatches of the colour scale
and its range, as the relighting engine last painted it (blender.heatmaps)."""

import bpy.utils.previews
import numpy as np

from ..blender.heatmaps import SHADED
from ..core import heatmap
from ..blender.handlers import engine

TITLES = {"ERROR": "Estimated relative error", "DIFFERENCE": "Error against Cycles"}
MISSING = {"ERROR": "no stored error", "DIFFERENCE": "not validated"}  # why a mesh is grey
SWATCHES = 8
SWATCH_PIXELS = 16

_swatches = None  # a bpy.utils.previews collection, made at the first draw: never in background mode


def draw_legend(layout, mode):
    if mode == SHADED:
        return
    column = layout.column(align=True)
    legend = engine.legend
    if legend is None or legend.mode != mode:
        column.label(text="The legend shows after the next update", icon="INFO")
        return
    row = column.row(align=True)
    for icon in _swatch_icons():
        row.label(text="", icon_value=icon)
    column.label(text=f"{TITLES[mode]}: {heatmap.range_label(legend.top)}")
    column.label(text=f"Above {100 * legend.top:.4g} %: the top colour")
    if legend.missing:
        column.label(text=f"Grey, {MISSING[mode]}: {', '.join(legend.missing)}", icon="INFO")


def _swatch_icons() -> list[int]:
    global _swatches
    if _swatches is None:
        _swatches = bpy.utils.previews.new()
        for i, colour in enumerate(heatmap.legend_srgb(SWATCHES)):
            swatch = _swatches.new(f"prt_heatmap_{i}")
            swatch.icon_size = (SWATCH_PIXELS, SWATCH_PIXELS)
            swatch.icon_pixels_float = np.tile([*colour, 1.0], SWATCH_PIXELS * SWATCH_PIXELS)
    return [swatch.icon_id for swatch in _swatches.values()]


def register():
    """Nothing to register: the swatches are made when the legend is first drawn."""


def unregister():
    global _swatches
    if _swatches is not None:
        bpy.utils.previews.remove(_swatches)
        _swatches = None
