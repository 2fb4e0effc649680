"""Blender's equirectangular images for the tests, written from Cycles rather than from prt_addon.core.lobes.

Cycles maps image coordinates (u, v) ∈ [0, 1]² to a direction with the world range (-2π, π, -π, π)
(intern/cycles/kernel/camera/projection.h, equirectangular_range_to_direction):
    φ = -2π·u + π,   θ = -π·v + π,   ω = (sinθ·cosφ, sinθ·sinφ, cosθ)
and Blender's `image.pixels` start with the bottom row, so pixel (row i, column j) of an H × W image has its
centre at u = (j + ½)/W, v = (i + ½)/H.
"""

import numpy as np

CYCLES_WORLD_RANGE = (-2 * np.pi, np.pi, -np.pi, np.pi)


def equirectangular_range_to_direction(u, v, mapping_range=CYCLES_WORLD_RANGE):
    """Unit directions (..., 3) that Cycles looks up at image coordinates u, v (arrays of one shape)."""
    phi = mapping_range[0] * np.asarray(u, dtype=np.float64) + mapping_range[1]
    theta = mapping_range[2] * np.asarray(v, dtype=np.float64) + mapping_range[3]
    sin_theta = np.sin(theta)
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), np.cos(theta)], axis=-1)


def equirect_directions(height, width):
    """The direction (H, W, 3) of every pixel centre of an H × W image, row 0 at the bottom as in image.pixels."""
    rows, columns = np.mgrid[0:height, 0:width]
    return equirectangular_range_to_direction((columns + 0.5) / width, (rows + 0.5) / height)
