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

from . import lobes, rotation, shading, sh
from .statistics import clamped_fraction

RGB = tuple[float, float, float]

# The light validation uses when a scene has none: a sun where a new SH sun starts, Hanning-windowed, over a sky.
# Its reconstruction is nowhere negative at any order (minimum 0.25 at order 4, 0.21 at order 10), so Cycles is
# lit by exactly the light PRT uses.
DEFAULT_SUN = {"theta": math.radians(35.0), "phi": math.radians(-60.0), "angular_radius": 0.2, "irradiance": 2.0}
DEFAULT_SKY = 0.3
DEFAULT_LIGHT = ("a Hanning-windowed sun (θ 35°, φ -60°, radius 0.2 rad, irradiance 2) over a sky of "
                 "radiance 0.3")

# Window "auto": the gentlest taper between none and Hanning whose light has at most this share of its magnitude
# negative (the share validation reports as clamped), found per light sum by bisection on the strength.
AUTO_CLAMPED_SHARE = 0.01
_AUTO_STEPS = 12  # bisection steps: the strength to 1/4096, far finer than any visible change


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
    """Projections kept between updates, so an update costs one rotation per light that moved. With `image_rows`,
    images are box-filtered to at most that many rows before projection (for an analysis at high order)."""

    def __init__(self, image_rows: int | None = None):
        self.image_rows = image_rows
        self._environments = {}  # (image key, order) → unrotated (3, n²)
        self._placed = {}  # (light, order) → (3, n²), for the lights of the latest update only
        self.auto_strengths = {}  # order → the Auto window's strength in the latest totals

    def totals(self, lights, orders, window="none") -> dict:
        """{order: (3, order²) sum over `lights`} for every order asked for, windowed."""
        placed, totals = {}, {}
        for order in orders:
            each = self._each(lights, order, placed)
            summed = np.sum(each, axis=0) if lights else np.zeros((3, order * order))
            if window == "auto":
                self.auto_strengths[order] = auto_window_strength(summed)
            totals[order] = windowed(summed, window, self.auto_strengths.get(order))
        self._placed = placed  # forget lights that are gone, so animating one does not grow the cache
        return totals

    def each(self, lights, order) -> list:
        """Each light's (3, order²) coefficients, unwindowed, in the order given."""
        placed = {}
        found = self._each(lights, order, placed)
        self._placed = placed
        return found

    def _each(self, lights, order, placed) -> list:
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
        return [placed[light, order] for light in lights]

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
            pixels = light.pixels()
            if self.image_rows is not None:
                pixels = lobes.box_filtered(pixels, self.image_rows)
            self._environments[key] = lobes.project_equirect(pixels, order)
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


def windowed(coeffs, window, strength=None):
    """coeffs (channels, n²) under a window kind; "auto" takes `strength`, else finds it for these coefficients."""
    if window == "none":
        return coeffs
    order = math.isqrt(coeffs.shape[-1])
    if window == "auto":
        strength = auto_window_strength(coeffs) if strength is None else strength
        return lobes.apply_window(coeffs, lobes.window(order, "tapered", strength))
    return lobes.apply_window(coeffs, lobes.window(order, window))


def auto_window_strength(coeffs) -> float:
    """The Auto window's strength for coefficients (channels, n²): the smallest "tapered" strength (0: none,
    1: Hanning) whose reconstruction has at most AUTO_CLAMPED_SHARE of its magnitude negative, or 1 where even
    Hanning leaves more (a stronger taper would cost more than Hanning against the real light)."""
    coeffs = np.atleast_2d(np.asarray(coeffs, dtype=np.float64))
    order = math.isqrt(coeffs.shape[-1])
    bands = _band_images(coeffs)  # a taper only reweighs them: each step is a weighted sum, not a reconstruction

    def keeps(strength):
        factors = lobes.window(order, "tapered", strength)[:, None, None, None]
        return clamped_fraction((factors * bands).sum(axis=0)) <= AUTO_CLAMPED_SHARE

    if keeps(0.0):
        return 0.0
    if not keeps(1.0):
        return 1.0
    low, high = 0.0, 1.0
    for _ in range(_AUTO_STEPS):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if keeps(middle) else (middle, high)
    return high


def negative_share(coeffs) -> float:
    """statistics.clamped_fraction of the reconstruction of coeffs (channels, n²) on a grid of about 4 pixels to
    the order's shortest wavelength."""
    return clamped_fraction(_band_images(np.atleast_2d(coeffs)).sum(axis=0))


def _band_images(coeffs):
    """(n, rows, 2·rows, channels): band l's part of the reconstruction of coeffs (channels, n²) on the grid."""
    order = math.isqrt(coeffs.shape[-1])
    basis, rows = _negativity_grid(order)
    images = [basis[:, l * l:(l + 1) ** 2] @ coeffs[:, l * l:(l + 1) ** 2].T for l in range(order)]
    return np.stack(images).reshape(order, rows, 2 * rows, len(coeffs))


@functools.lru_cache(maxsize=8)
def _negativity_grid(order):
    """(the SH basis at the grid's pixel centres (pixels, n²), its rows); kept per order for the handler."""
    rows = 2 * order + 4
    basis = sh.evaluate(order, lobes.equirect_directions(rows, 2 * rows)).reshape(-1, order * order)
    basis.flags.writeable = False
    return basis, rows


def default_light(order: int) -> np.ndarray:
    """DEFAULT_LIGHT as grey (3, order²) coefficients."""
    direction = shading.direction_from_angles(DEFAULT_SUN["theta"], DEFAULT_SUN["phi"])
    sun = shading.sun_coefficients(order, direction, DEFAULT_SUN["angular_radius"], DEFAULT_SUN["irradiance"])
    grey = lobes.constant_sky(order, DEFAULT_SKY) + lobes.apply_window(sun, lobes.window(order, "hanning"))
    return np.tile(grey, (3, 1))
