"""The Display panel's legend for its heatmap modes (blender.schema's DISPLAY_MODES): swatches of the colour scale
and its range, or a swatch per rule with the points it decided, as the relighting engine last painted it
(blender.heatmaps)."""

import bpy.utils.previews
import numpy as np

from ..blender.heatmaps import RULE, SHADED
from ..core import heatmap, rules
from ..blender.handlers import engine

TITLES = {"ERROR": "Estimated relative error", "DIFFERENCE": "Error against Cycles"}
MISSING = {"ERROR": "no stored error", "DIFFERENCE": "not validated", RULE: "baked before rules were stored"}
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
    if mode == RULE:
        _draw_rules(column, dict(legend.decided))
    else:
        _draw_scale(column, mode, legend.top)
    if legend.missing:
        column.label(text=f"Grey, {MISSING[mode]}: {', '.join(legend.missing)}", icon="INFO")


def _draw_rules(column, decided: dict):
    """A swatch per rule, with the points it decided over every mesh shown."""
    icons = _swatch_icons()
    column.label(text="Decided by rule instead of rays:")
    for code, key in rules.KEYS.items():
        column.label(text=f"{rules.WORDS[code].capitalize()}: {decided.get(key, 0)} points", icon_value=icons[key])
    column.label(text="Measured by rays", icon_value=icons["measured"])


def _draw_scale(column, mode, top):
    row = column.row(align=True)
    for icon in _swatch_icons()["scale"]:
        row.label(text="", icon_value=icon)
    column.label(text=f"{TITLES[mode]}: {heatmap.range_label(top)}")
    column.label(text=f"Above {100 * top:.4g} %: the top colour")


def _swatch_icons() -> dict:
    """Icon ids: "scale", the colour scale's swatches in order; each rule's key and "measured", its colour."""
    global _swatches
    if _swatches is None:
        _swatches = bpy.utils.previews.new()
        named = [(f"prt_heatmap_{i}", colour) for i, colour in enumerate(heatmap.legend_srgb(SWATCHES))]
        named += [(f"prt_rule_{code}", heatmap.RULE_SRGB[code]) for code in range(rules.LARGEST + 1)]
        for name, colour in named:
            swatch = _swatches.new(name)
            swatch.icon_size = (SWATCH_PIXELS, SWATCH_PIXELS)
            swatch.icon_pixels_float = np.tile([*colour, 1.0], SWATCH_PIXELS * SWATCH_PIXELS)
    icons = {"scale": [_swatches[f"prt_heatmap_{i}"].icon_id for i in range(SWATCHES)],
             "measured": _swatches[f"prt_rule_{rules.MEASURED}"].icon_id}
    icons.update({key: _swatches[f"prt_rule_{code}"].icon_id for code, key in rules.KEYS.items()})
    return icons


def register():
    """Nothing to register: the swatches are made when the legend is first drawn."""


def unregister():
    global _swatches
    if _swatches is not None:
        bpy.utils.previews.remove(_swatches)
        _swatches = None
