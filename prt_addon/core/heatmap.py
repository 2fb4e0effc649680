"""Heatmaps: per-point errors as colours, for the viewport's error displays, and their legend.

The colour map is matplotlib's viridis at nine stops (8-bit sRGB): even in lightness, readable by colour-blind
eyes, dark for small errors and bright yellow where the error is large. Values interpolate between the stops in
sRGB, as a screen shows them, and come out scene-linear, as a FLOAT_COLOR attribute holds them: under the
Standard view transform the viewport shows exactly the stops.

One scale for everything shown, so colours compare across objects: 0 to the 99th percentile of the values,
rounded up to 1, 2 or 5 × 10^k so the legend reads cleanly; values above it take the top colour, so a few
outliers do not wash out the rest.

"Decided by rule" is categorical: one colour per rule (core.rules) from Okabe and Ito's colour-blind-safe palette,
bright where a rule decided, dark grey where rays measured, so the eye goes where a rule may be wrong.
"""

import math

import numpy as np

from . import rules
from .colour import srgb_to_linear
from .statistics import percentile

VIRIDIS_SRGB = np.array([(68, 1, 84), (71, 45, 123), (59, 82, 139), (44, 114, 142), (33, 145, 140),
                         (40, 174, 128), (94, 201, 98), (173, 220, 48), (253, 231, 37)]) / 255.0
MISSING_SRGB = (0.5, 0.5, 0.5)  # a mesh without the values (not validated): neutral grey, outside the map
SMALLEST_TOP = 1e-4  # the scale of values that are all zero (an exact bake): 0.01 %
NICE_MANTISSAS = (1.0, 2.0, 5.0, 10.0)
RULE_SRGB = np.zeros((rules.LARGEST + 1, 3))  # by rule code
RULE_SRGB[rules.MEASURED] = (0.25, 0.25, 0.25)
RULE_SRGB[rules.LYING] = (213 / 255, 94 / 255, 0.0)             # vermillion
RULE_SRGB[rules.TOUCHING] = (86 / 255, 180 / 255, 233 / 255)    # sky blue
RULE_SRGB[rules.AGAINST] = (204 / 255, 121 / 255, 167 / 255)    # reddish purple


def scale_top(values: np.ndarray) -> float:
    """The top of the scale for these values: their 99th percentile rounded up to 1, 2 or 5 × 10^k."""
    return nice_ceiling(percentile(np.asarray(values, dtype=np.float64)))


def nice_ceiling(value: float) -> float:
    """The smallest 1, 2 or 5 × 10^k at or above `value` (SMALLEST_TOP at least)."""
    if value <= SMALLEST_TOP:
        return SMALLEST_TOP
    exponent = math.floor(math.log10(value))
    mantissa = value / 10.0 ** exponent
    # 1e-9: a value that is already nice (0.02) must not round up through floating-point noise
    return next(m for m in NICE_MANTISSAS if mantissa <= m * (1 + 1e-9)) * 10.0 ** exponent


def srgb_colours(values: np.ndarray, top: float) -> np.ndarray:
    """(N, 3) sRGB colours of the values on the scale 0..top, linear between the stops; outside it clamped."""
    position = np.clip(np.asarray(values, dtype=np.float64) / top, 0.0, 1.0) * (len(VIRIDIS_SRGB) - 1)
    below = np.minimum(position.astype(int), len(VIRIDIS_SRGB) - 2)
    fraction = (position - below)[:, None]
    return (1.0 - fraction) * VIRIDIS_SRGB[below] + fraction * VIRIDIS_SRGB[below + 1]


def heatmap_rgba(values: np.ndarray, top: float) -> np.ndarray:
    """(N, 4) float32 scene-linear RGBA, alpha 1: the display colour attribute's rows for these values."""
    return _linear_rgba(srgb_colours(values, top))


def rule_rgba(codes: np.ndarray) -> np.ndarray:
    """(N, 4) float32 scene-linear RGBA, alpha 1, of each point's rule code (core.rules)."""
    return _linear_rgba(RULE_SRGB[np.asarray(codes, dtype=np.int64)])


def missing_rgba(count: int) -> np.ndarray:
    """(count, 4) float32 scene-linear RGBA of a mesh without the values."""
    return _linear_rgba(np.tile(MISSING_SRGB, (count, 1)))


def legend_srgb(swatches: int) -> np.ndarray:
    """(swatches, 3) sRGB colours evenly spaced from the bottom of the scale to its top."""
    return srgb_colours(np.linspace(0.0, 1.0, swatches), 1.0)


def range_label(top: float) -> str:
    """The scale's range as the legend prints it, in percent: "0 – 2 %"."""
    return f"0 – {100 * top:.4g} %"


def _linear_rgba(srgb: np.ndarray) -> np.ndarray:
    rgba = np.ones((len(srgb), 4), dtype=np.float32)
    rgba[:, :3] = srgb_to_linear(srgb)
    return rgba
