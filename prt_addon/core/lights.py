"""SH lights: each projected once, then only turned when it moves; the scene's light is their sum.

Radiance convention: a vertex shows albedo · Σ_k L_k T_k, the transfer already holding 1/π. A sun of irradiance
E straight above an unoccluded upward vertex shows E/π in the limit of high order; at order n it shows the
band-limited value E/π · Σ_l (2l+1)/(4π)·Â_l·q_l (17/16 of E/π for a point sun at orders 3 and 4), which is
the ringing that windowing trades for sharpness.

Lights are frozen dataclasses, so a light that did not change is equal to its previous self and its
coefficients come from the cache: moving one light of eight recomputes one.
"""

import functools
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import lobes, rotation, shading

RGB = tuple[float, float, float]

# The light validation uses when a scene has none: a sun where a new SH sun starts, Hanning-windowed, over a sky.
# Its reconstruction is nowhere negative at any order (minimum 0.25 at order 4, 0.21 at order 10), so Cycles is
# lit by exactly the light PRT uses.
DEFAULT_SUN = {"theta": math.radians(35.0), "phi": math.radians(-60.0), "angular_radius": 0.2, "irradiance": 2.0}
DEFAULT_SKY = 0.3
DEFAULT_LIGHT = ("a Hanning-windowed sun (θ 35°, φ -60°, radius 0.2 rad, irradiance 2) over a sky of "
                 "radiance 0.3")


@dataclass(frozen=True)
class Sun:
    """A disc of constant radiance; rgb is its irradiance on a surface facing it (Blender's Sun strength)."""
    direction: tuple[float, float, float]  # towards the sun, world space
    angular_radius: float
    rgb: RGB


@dataclass(frozen=True)
class Environment:
    """An equirectangular image (Blender's world mapping), turned by `rotation`: g(ω) = f(Rᵀω)."""
    image: tuple  # (name, width, height): what identifies the projection in the cache
    rotation: tuple  # 3×3 matrix, row-major
    rgb: RGB  # multiplies the image
    pixels: Callable[[], np.ndarray] = field(compare=False, repr=False)  # (H, W, ≥3); read on a cache miss only


@dataclass(frozen=True)
class Sky:
    """Constant radiance from every direction."""
    rgb: RGB


class LightCache:
    """Projections kept between updates, so an update costs one rotation per light that moved."""

    def __init__(self):
        self._environments = {}  # (image key, order) → unrotated (3, n²)
        self._placed = {}  # (light, order) → (3, n²), for the lights of the latest update only

    def totals(self, lights, orders, window="none") -> dict:
        """{order: (3, order²) sum over `lights`} for every order asked for, windowed."""
        placed, totals = {}, {}
        for order in orders:
            missing = []
            for light in lights:
                key = (light, order)
                if key not in placed:
                    cached = self._placed.get(key)
                    if cached is None:
                        missing.append(light)
                    else:
                        placed[key] = cached
            placed.update(self._place(list(dict.fromkeys(missing)), order))
            summed = (np.sum([placed[light, order] for light in lights], axis=0) if lights
                      else np.zeros((3, order * order)))
            totals[order] = _windowed(summed, order, window)
        self._placed = placed  # forget lights that are gone, so animating one does not grow the cache
        return totals

    def _place(self, lights, order) -> dict:
        """{(light, order): (3, n²)} for lights not in the cache; the suns share one SH evaluation."""
        suns = [light for light in lights if isinstance(light, Sun)]
        placed = {}
        if suns:
            zonal = np.array([_sun_disc(order, sun.angular_radius) for sun in suns])
            directions = np.array([_unit(sun.direction) for sun in suns])
            for sun, coeffs in zip(suns, rotation.zonal_to_sh(zonal, directions)):
                placed[sun, order] = _column(sun.rgb) * coeffs
        for light in lights:
            if isinstance(light, Environment):
                matrix = np.asarray(light.rotation, dtype=np.float64).reshape(3, 3)
                placed[light, order] = _column(light.rgb) * rotation.rotate(self._environment(light, order), matrix)
            elif isinstance(light, Sky):
                placed[light, order] = _column(light.rgb) * lobes.constant_sky(order)
            elif not isinstance(light, Sun):
                raise TypeError(f"not an SH light: {light!r}")
        return placed

    def _environment(self, light, order):
        key = (light.image, order)
        if key not in self._environments:
            self._environments[key] = lobes.project_equirect(light.pixels(), order)
        return self._environments[key]


@functools.lru_cache(maxsize=64)  # bounded: an animated angular radius asks for a new disc every frame
def _sun_disc(order, angular_radius):
    """Zonal z_l of a disc of unit irradiance."""
    zonal = lobes.sun_disc_zonal(order, angular_radius)
    zonal.flags.writeable = False  # shared by every caller through the cache
    return zonal


def _column(rgb):
    return np.asarray(rgb, dtype=np.float64)[:, None]


def _unit(direction):
    direction = np.asarray(direction, dtype=np.float64)
    length = np.linalg.norm(direction)
    if not length > 0:
        raise ValueError("a sun needs a direction")
    return direction / length


def _windowed(coeffs, order, window):
    if window == "none":
        return coeffs
    return lobes.apply_window(coeffs, lobes.window(order, window))


def default_light(order: int) -> np.ndarray:
    """DEFAULT_LIGHT as grey (3, order²) coefficients."""
    direction = shading.direction_from_angles(DEFAULT_SUN["theta"], DEFAULT_SUN["phi"])
    sun = shading.sun_coefficients(order, direction, DEFAULT_SUN["angular_radius"], DEFAULT_SUN["irradiance"])
    grey = lobes.constant_sky(order, DEFAULT_SKY) + lobes.apply_window(sun, lobes.window(order, "hanning"))
    return np.tile(grey, (3, 1))
