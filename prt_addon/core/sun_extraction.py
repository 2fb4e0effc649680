"""The sun split off an equirectangular HDRI: found, measured and painted out, so that a real lamp draws its sharp
light and shadows while PRT carries the soft rest, which low orders represent well.

The sun is the region connected to the brightest pixel whose luminance is above EDGE_FRACTION of it. Over the local
background (the median of a ring around the region) it has a direction (its power-weighted mean), an irradiance
(RGB, on a surface facing it: Σ (L − background)·cos·dω) and an angular radius: that of the disc of constant
radiance with the same power and the same ∫L²: Ω = (∫L dω)² / ∫L² dω, so soft edges a threshold would cut or
keep do not change it. It counts as a sun only when compact (radius at most MAX_RADIUS) and strong (at least
MIN_SHARE of the image's power): windows and softboxes stay in the image, where PRT carries them.
Images are in Blender's layout and Cycles' world mapping (core.lobes).
"""

from dataclasses import dataclass
import math

import numpy as np

from . import lobes

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709, Blender's default
EDGE_FRACTION = 0.01
MAX_RADIUS = math.radians(5.0)
MIN_SHARE = 0.1
RING_PIXELS = 3  # width of the ring whose median is the background the sun shines over


@dataclass(frozen=True)
class FoundSun:
    direction: tuple  # unit vector towards the sun, in the image's own frame (before any rotation)
    angular_radius: float
    irradiance: tuple  # RGB, on a surface facing the sun
    share: float  # of the image's power (luminance × solid angle)


def find_sun(pixels: np.ndarray) -> tuple[FoundSun | None, np.ndarray]:
    """(the sun, the image without it), or (None, the image) when it holds no compact strong sun."""
    rgb = np.asarray(pixels[..., :3], dtype=np.float64)
    height, width = rgb.shape[:2]
    luminance = rgb @ LUMINANCE
    solid_angles = np.broadcast_to(lobes.equirect_solid_angles(height, width), (height, width))
    region = _bright_region(luminance, max_steps=math.ceil(MAX_RADIUS / (math.pi / height)) + 1)
    if region is None:
        return None, pixels
    background = np.median(rgb[_ring(region) & ~region], axis=0)
    excess = np.maximum(rgb[region] - background, 0.0)
    excess_luminance = excess @ LUMINANCE
    weights = solid_angles[region]
    directions = lobes.equirect_directions(height, width)[region]
    direction = _unit((excess_luminance * weights) @ directions)
    power = excess_luminance @ weights
    if not power > 0:
        return None, pixels
    radius = _equivalent_radius(power, np.square(excess_luminance) @ weights)
    share = power / float(np.sum(luminance * solid_angles))
    if radius > MAX_RADIUS or share < MIN_SHARE:
        return None, pixels
    irradiance = (excess * (weights * np.maximum(directions @ direction, 0.0))[:, None]).sum(axis=0)
    without = np.array(pixels, dtype=np.float32, copy=True)
    without[region, :3] = background
    return FoundSun(tuple(direction), radius, tuple(float(c) for c in irradiance), float(share)), without


def _bright_region(luminance, max_steps):
    """The pixels connected (8-neighbours, wrapping around in azimuth) to the brightest one whose luminance is
    above EDGE_FRACTION of it; None when it still grows after `max_steps` steps (too large for a sun)."""
    peak = np.unravel_index(np.argmax(luminance), luminance.shape)
    bright = luminance >= EDGE_FRACTION * luminance[peak]
    region = np.zeros_like(bright)
    region[peak] = True
    for _ in range(max_steps):
        grown = _dilated(region) & bright
        if np.array_equal(grown, region):
            return region
        region = grown
    return None


def _dilated(mask):
    """One step of 8-neighbour growth: wraps in azimuth (columns), not over the poles (rows)."""
    grown = mask | np.roll(mask, 1, axis=1) | np.roll(mask, -1, axis=1)
    grown[1:] |= grown[:-1].copy()
    grown[:-1] |= grown[1:].copy()
    return grown


def _ring(region):
    ring = region
    for _ in range(RING_PIXELS):
        ring = _dilated(ring)
    return ring


def _equivalent_radius(power, power_squared):
    """The radius of the cap of solid angle Ω = (∫L)² / ∫L², the disc of constant radiance with this power."""
    solid_angle = power * power / power_squared
    return math.acos(max(-1.0, 1.0 - solid_angle / (2 * math.pi)))


def _unit(vector):
    return vector / np.linalg.norm(vector)
