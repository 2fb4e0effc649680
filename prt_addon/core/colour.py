"""Colour encodings: screens and 8-bit images hold sRGB-encoded values, Blender's float colours scene-linear ones."""

import numpy as np


def srgb_to_linear(values):
    """The sRGB transfer function undone (IEC 61966-2-1), for values in [0, 1]."""
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(values):
    """The sRGB transfer function (IEC 61966-2-1), for values in [0, 1]."""
    return np.where(values <= 0.0031308, values * 12.92, 1.055 * np.power(values, 1 / 2.4) - 0.055)
