"""Real orthonormal spherical harmonics with the Condon-Shortley phase.

Coefficient k = l(l+1) + m; "order n" means bands l = 0..n-1, i.e. n² coefficients.
  m > 0: Y_lm = sqrt(2) K_lm P_l^m(cos θ) cos(mφ)
  m < 0: Y_lm = sqrt(2) K_l|m| P_l^|m|(cos θ) sin(|m|φ)
  m = 0: Y_l0 = K_l0 P_l(cos θ)
with P_l^m carrying the (-1)^m phase, so Y_1,-1 ∝ -y, Y_1,0 ∝ z, Y_1,1 ∝ -x.
"""
import math

import numpy as np

MAX_ORDER = 64
_BLOCK_VALUES = 1 << 19  # values per evaluate() block: 4 MB stays in cache


def index(l, m):
    """Coefficient index of band l, degree m."""
    return l * (l + 1) + m


def coefficient_bands(order):
    """Band l of every coefficient k < order², for scaling whole bands at once."""
    bands = np.arange(order)
    return np.repeat(bands, 2 * bands + 1)


def fitted(coefficients, count):
    """(..., count) the SH coefficients (..., m) cut to their first `count`, or followed by zeros up to it: the same
    function band-limited to order √count, where it holds nothing above its own order."""
    coefficients = np.asarray(coefficients)
    if coefficients.shape[-1] >= count:
        return coefficients[..., :count]
    padding = np.zeros(coefficients.shape[:-1] + (count - coefficients.shape[-1],), dtype=coefficients.dtype)
    return np.concatenate([coefficients, padding], axis=-1)


def evaluate(order, directions):
    """Y_k(d) for all k < order²: directions (..., 3) unit vectors -> (..., order²) float64.

    Uses sin^m θ · e^{imφ} = (x + iy)^m and normalised Legendre recurrences in z, so no
    angles, no factorials and exact values at the poles.
    """
    _check_order(order)
    directions = np.asarray(directions, dtype=np.float64)
    flat = directions.reshape(-1, 3)
    values = np.empty((len(flat), order * order))
    # Coefficients are written with a stride; blocks that stay in cache are ~2.5x faster.
    rows = max(256, _BLOCK_VALUES // max(1, order * order))
    for start in range(0, len(flat), rows):
        _evaluate_into(values[start:start + rows], order, flat[start:start + rows])
    return values.reshape(directions.shape[:-1] + (order * order,))


def evaluate_components(order, directions, dtype=np.float64):
    """Y_k(d) as (order², N) for directions (N, 3): a contiguous row per coefficient, written without stride,
    so about 1.5× faster than evaluate() for the many directions of a bake round; its transpose equals
    evaluate()'s (N, order²) exactly. With dtype float32 the arithmetic is float32 too: within 1e-6 of float64
    at order 4 (see tests)."""
    _check_order(order)
    directions = np.asarray(directions, dtype=dtype).reshape(-1, 3)
    values = np.empty((order * order, len(directions)), dtype=dtype)
    _evaluate_into(values.T, order, directions)
    return values


def _check_order(order):
    if not 0 <= order <= MAX_ORDER:
        raise ValueError(f"order must be in [0, {MAX_ORDER}], got {order}")


def _evaluate_into(values, order, directions):
    """Fill values (N, order²) with Y_k of directions (N, 3). Every term is a pass over N values written into an
    array made once per call: a fresh array per term cost as much as the arithmetic. Computes in values' dtype."""
    x, y, z = directions[:, 0], directions[:, 1], directions[:, 2]
    count, dtype = len(z), values.dtype
    power_re, power_im = np.ones(count, dtype=dtype), np.zeros(count, dtype=dtype)  # (x + iy)^m
    next_re, next_im, scratch, cos_part, sin_part = np.empty((5, count), dtype=dtype)
    legendre = np.empty((3, count), dtype=dtype)  # the recurrence's three terms, reused in turn
    sectoral = 1.0 / math.sqrt(4.0 * math.pi)  # K_mm P_m^m / sin^m θ, a constant
    for m in range(order):
        if m > 0:
            np.multiply(x, power_re, out=next_re)
            next_re -= np.multiply(y, power_im, out=scratch)
            np.multiply(x, power_im, out=next_im)
            next_im += np.multiply(y, power_re, out=scratch)
            power_re, next_re, power_im, next_im = next_re, power_re, next_im, power_im
            sectoral *= -math.sqrt((2 * m + 1) / (2 * m))
            np.multiply(power_re, math.sqrt(2.0), out=cos_part)
            np.multiply(power_im, math.sqrt(2.0), out=sin_part)
        for l, term in _legendre_over_sine_power(order, m, z, sectoral, legendre, scratch):
            if m == 0:
                values[..., index(l, 0)] = term
            else:
                np.multiply(term, cos_part, out=values[..., index(l, m)])
                np.multiply(term, sin_part, out=values[..., index(l, -m)])


def _legendre_over_sine_power(order, m, z, sectoral, buffers, scratch):
    """Yield (l, K_lm P_l^m(z) / sin^m θ) for l = m..order-1: the constant `sectoral` for l = m, then arrays in
    `buffers` (3, N), each valid until the next but one is yielded; `scratch` (N,) is overwritten.

    Dividing out sin^m θ leaves a polynomial in z, so the standard normalised three-term
    recurrence in l applies unchanged; magnitudes stay below 1e13 up to order 64.
    """
    older = sectoral
    yield m, older
    if m + 1 >= order:
        return
    old, new, spare = buffers
    np.multiply(z, math.sqrt(2 * m + 3), out=old)
    old *= sectoral
    yield m + 1, old
    for l in range(m + 2, order):
        a = math.sqrt((4 * l * l - 1) / (l * l - m * m))
        b = math.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
        np.multiply(z, old, out=new)
        new -= b * older if l == m + 2 else np.multiply(older, b, out=scratch)  # l = m + 2: older is a number
        new *= a
        yield l, new
        older, old, new = old, new, (spare if l == m + 2 else older)
