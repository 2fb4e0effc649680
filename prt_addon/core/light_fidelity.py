"""How well each SH order carries a light, from the light alone (no bake, no Cycles): the relative L2 error of its
projection, a predicted shading error, and the order to recommend.

Projection error at order n: sqrt(Σ_{l≥n} P_l / ‖L‖²) for the light's band powers P_l = Σ_{c,m} L_clm² (Parseval)
and its true norm ‖L‖² (an image's from its pixels, a disc's in closed form), so a sharp sun's error stays near 1 at
every order: no order carries it.

Predicted shading error at order n: a vertex shows Σ_k L_k T_k, and for a transfer turned at random the bands do
not mix, so E[(shading error)²] = Σ_l (1 − h_l)²·P_l·w_l / (2l+1), w_l the transfer's band power and h_l the
window's factor (0 from band n on: the bands not stored); relative to Σ_l P_l·w_l / (2l+1), the shading's own mean
square. The window is the display's (Auto: found for the light at each order), so the order recommended is the
one that meets the target as the light is shown. w_l is the mean over a few model vertices: the clamped cosine
cut by an occluding plane through the vertex tilted 0° (unshadowed), 30°, 60° and 90° (a wall at its foot) from
its normal; what shadows add at high bands is what makes order 4 miss a sharp light. Bands up to REFERENCE_ORDER
are summed; an image is projected for it at ANALYSIS_ROWS rows (box-filtered), which holds those bands.
"""

from dataclasses import dataclass
import functools
import math

import numpy as np

from . import lobes, sh
from .lights import Environment, LightCache, Sky, Sun, auto_window_strength
from .settings import ORDER_TARGET

REFERENCE_ORDER = 32
ANALYSIS_ROWS = 128
OCCLUDER_TILTS = tuple(math.radians(tilt) for tilt in (0.0, 30.0, 60.0, 90.0))
DEFAULT_TARGET = ORDER_TARGET.default  # predicted shading error the recommended order meets


@dataclass(frozen=True)
class LightFidelity:
    """What each order makes of a light: {order: relative error}, and the order meeting `target`."""
    projection: dict
    predicted: dict
    target: float
    recommended: int

    def table(self) -> list[str]:
        """One line per order: the light's projection error and the predicted shading error."""
        return [f"order {n:2d}: light {100 * self.projection[n]:5.1f} %, shading {100 * self.predicted[n]:5.1f} %"
                + ("  <- recommended" if n == self.recommended else "") for n in sorted(self.predicted)]


def analyse(lights, orders, target: float = DEFAULT_TARGET, window: str = "none") -> LightFidelity:
    """The fidelity of the sum of `lights` (core.lights' lights) at each of `orders` (at most REFERENCE_ORDER),
    shown through `window`."""
    each = LightCache(image_rows=ANALYSIS_ROWS).each(lights, REFERENCE_ORDER)
    total = np.sum(each, axis=0) if lights else np.zeros((3, REFERENCE_ORDER ** 2))
    powers = band_powers(total)
    # ‖Σ L_i‖² = Σ ‖L_i‖² + the cross terms, which the bands up to REFERENCE_ORDER hold
    cross = float(np.sum(np.square(total))) - sum(float(np.sum(np.square(c))) for c in each)
    norm_squared = sum(norm_squared_of(light) for light in lights) + cross
    predicted = {n: predicted_errors(powers, [n], _window_factors(total, n, window))[n] for n in orders}
    return LightFidelity(projection_errors(powers, norm_squared, orders), predicted, target,
                         recommended_order(predicted, target))


def norm_squared_of(light) -> float:
    """‖L‖² = Σ_c ∫ L_c² dω of one light, exactly (infinite for a point sun)."""
    rgb_squared = np.square(np.asarray(light.rgb, dtype=np.float64))
    if isinstance(light, Sun):
        return disc_norm_squared(light.rgb, light.angular_radius)
    if isinstance(light, Sky):
        return float(rgb_squared.sum()) * 4 * math.pi
    if isinstance(light, Environment):
        return float(rgb_squared @ image_norm_squared(light.pixels()))
    raise TypeError(f"not an SH light: {light!r}")


def band_powers(coeffs: np.ndarray) -> np.ndarray:
    """P_l = Σ over channels and m of c_lm², for coefficients (channels, n²) → (n,)."""
    coeffs = np.atleast_2d(coeffs)
    order = math.isqrt(coeffs.shape[-1])
    squares = np.square(coeffs).sum(axis=0)
    return np.bincount(sh.coefficient_bands(order), weights=squares, minlength=order)


def projection_errors(powers: np.ndarray, norm_squared: float, orders) -> dict:
    """{n: relative L2 error of the light projected to order n}; 1 for a light of infinite norm (a point)."""
    kept = np.concatenate([[0.0], np.cumsum(powers)])
    if math.isinf(norm_squared):
        return {n: 1.0 for n in orders}
    return {n: math.sqrt(max(norm_squared - kept[n], 0.0) / norm_squared) if norm_squared > 0 else 0.0
            for n in orders}


def predicted_errors(powers: np.ndarray, orders, window_factors=None) -> dict:
    """{n: predicted relative RMS shading error at order n} (module docstring); `window_factors` (n,) the window
    at order n (one order only), default none."""
    bands = np.arange(len(powers))
    shaded = powers * transfer_band_powers(len(powers)) / (2 * bands + 1)
    total = shaded.sum()
    errors = {}
    for n in orders:
        kept = np.zeros(len(powers))
        kept[:n] = 1.0 if window_factors is None else window_factors
        errors[n] = math.sqrt(np.sum(np.square(1.0 - kept) * shaded) / total) if total > 0 else 0.0
    return errors


def _window_factors(total, order, window):
    """The display's window at `order` for the light whose coefficients (3, ≥ order²) are `total`."""
    coeffs = total[:, :order * order]
    if window == "auto":
        return lobes.window(order, "tapered", auto_window_strength(coeffs))
    return lobes.window(order, window)


def recommended_order(predicted: dict, target: float = DEFAULT_TARGET) -> int:
    """The lowest order whose predicted error is at most `target`, else the highest offered."""
    return next((n for n in sorted(predicted) if predicted[n] <= target), max(predicted))


@functools.lru_cache(maxsize=4)
def transfer_band_powers(order: int, tilts: tuple = OCCLUDER_TILTS) -> np.ndarray:
    """w_l of the model transfer (module docstring), (order,): the mean band power of the clamped cosine / π cut
    by an occluding plane through the vertex at each of `tilts` from the normal, on a fine equirect grid."""
    rows = max(4 * order, 64)
    directions = lobes.equirect_directions(rows, 2 * rows).reshape(-1, 3)
    weights = np.broadcast_to(lobes.equirect_solid_angles(rows, 2 * rows), (rows, 2 * rows)).ravel()
    cosine = np.maximum(directions[:, 2], 0.0) / np.pi
    tilts = np.asarray(tilts)
    occluders = np.stack([np.sin(tilts), np.zeros_like(tilts), np.cos(tilts)], axis=1)
    visible = (directions @ occluders.T >= 0.0).T  # (tilts, directions)
    transfers = (visible * cosine * weights) @ sh.evaluate(order, directions)
    return band_powers(transfers) / len(tilts)


def image_norm_squared(pixels: np.ndarray) -> np.ndarray:
    """(3,): ∫ L_c² dω of each of an equirect image's RGB channels."""
    rgb = np.asarray(pixels[..., :3], dtype=np.float64)
    weights = lobes.equirect_solid_angles(*rgb.shape[:2])[..., None]
    return (np.square(rgb) * weights).sum(axis=(0, 1))


def disc_norm_squared(irradiance_rgb, angular_radius: float) -> float:
    """‖L‖² of a disc of constant radiance E/(π sin²α) over its solid angle 2π(1 − cos α): infinite for a point."""
    if angular_radius <= 0.0:
        return math.inf if np.any(irradiance_rgb) else 0.0
    sin_squared = math.sin(angular_radius) ** 2
    solid_angle = 2 * math.pi * (1 - math.cos(angular_radius))
    return float(np.sum(np.square(irradiance_rgb))) / (math.pi * sin_squared) ** 2 * solid_angle
