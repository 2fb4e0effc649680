"""Pictures for the viewer's tests: PNGs read as Blender reads them, and their difference over the pixels an object
covers."""

import bpy
import numpy as np


def read_png(path) -> np.ndarray:
    """(H, W, 4) floats, top row first, as Blender reads the PNG."""
    image = bpy.data.images.load(str(path))
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1]


def inner_pixels(covered: np.ndarray) -> np.ndarray:
    """The covered pixels (H, W) bool less their outer ring (anti-aliased edges against the background differ
    between any two rasterisers)."""
    inside = covered.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inside &= np.roll(np.roll(covered, dy, axis=0), dx, axis=1)
    return inside


def rms_over_objects(reference, shot, covered=None) -> float:
    """RMS of the RGB difference over the pixels the reference covers (or `covered`, (H, W) bool), less their outer
    ring."""
    inside = inner_pixels(reference[..., 3] > 0.99 if covered is None else covered)
    difference = reference[..., :3][inside] - shot[..., :3][inside]
    return float(np.sqrt(np.mean(difference ** 2)))


def shot(page, path) -> np.ndarray:
    page.screenshot(path=str(path))
    return read_png(path)
