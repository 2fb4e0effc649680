"""SH projections of lighting: the clamped cosine (with the exact unshadowed transfer it gives a vertex), a sun
disc, a constant sky and equirectangular HDRIs.

Zonal lobes are returned as z_l, the projection onto Y_l0 of the lobe pointing at +Z; rotation.zonal_to_sh
turns them into full coefficient vectors pointing anywhere.

Equirectangular images use Cycles' world mapping (intern/cycles/kernel/camera/projection.h,
direction_to_equirectangular, range (-2π, π, -π, π)):
    u = (atan2(y, x) - π) / (-2π),   v = (acos(z) - π) / (-π)
    φ = π - 2π·u,   θ = π - π·v,   ω = (sinθ·cosφ, sinθ·sinφ, cosθ)
v = 0 is the first row of Blender's `image.pixels` (the bottom of the image) and looks down (-Z); the top row
looks up (+Z). The image centre (u = 0.5) looks along +X, u = 0.25 along +Y, the left/right seam along -X.
"""

import math

import numpy as np

from . import sh

# Basis values held at once by the equirect loops (float64): 4M values = 32 MB, whatever the image size.
_CHUNK_VALUES = 1 << 22
_RGB = 3  # colour channels projected; alpha is not light


def _per_coefficient(band_values):
    """Repeats a per-band value for each of the band's 2l+1 coefficients."""
    band_values = np.asarray(band_values, dtype=np.float64)
    return np.repeat(band_values, 2 * np.arange(len(band_values)) + 1)


def _zonal_normalisation(order):
    """sqrt((2l+1)/4π): Y_l0 = this · P_l(cos θ)."""
    return np.sqrt((2 * np.arange(order) + 1) / (4 * np.pi))


def _clamped_cosine_eigenvalues(order):
    """Â_l = 2π ∫_0^1 t·P_l(t) dt: π, 2π/3, zero for odd l > 1, and for even l
    2π·(-1)^(l/2+1) / ((l+2)(l-1)) · C(l, l/2)/2^l. The central binomial over 2^l is carried by its ratio
    (l+1)/(l+2) between even l, so nothing overflows at high order."""
    eigenvalues = np.zeros(order)
    central_binomial = 1.0  # C(l, l/2) / 2^l
    for l in range(0, order, 2):
        sign = -1.0 if (l // 2) % 2 == 0 else 1.0
        eigenvalues[l] = 2 * np.pi * sign * central_binomial / ((l + 2) * (l - 1))
        central_binomial *= (l + 1) / (l + 2)
    if order > 1:
        eigenvalues[1] = 2 * np.pi / 3
    return eigenvalues


def clamped_cosine_zonal(order):
    """z_l of max(cos θ, 0): Â_l·sqrt((2l+1)/4π)."""
    return _clamped_cosine_eigenvalues(order) * _zonal_normalisation(order)


def cosine_transfer(order, normals):
    """Unshadowed diffuse transfer T_lm = (Â_l/π)·Y_lm(n) for unit normals (N, 3) → (N, order²)."""
    band_factors = _clamped_cosine_eigenvalues(order) / np.pi
    return sh.evaluate(order, normals) * _per_coefficient(band_factors)


def unshadowed_transfer(order: int, normals: np.ndarray) -> np.ndarray:
    """Exact, noise-free: the clamped cosine rotated to each normal; zero where the normal is zero."""
    return cosine_transfer(order, normals) * (np.abs(normals).sum(-1, keepdims=True) > 0)


def unshadowed_norm(order: int) -> float:
    """‖T_unshadowed‖, the same for every unit normal (addition theorem: Σ_m Y_lm(n)² = (2l+1)/4π):
    the scale of each vertex's relative error."""
    return float(np.linalg.norm(clamped_cosine_zonal(order)) / np.pi)


def _legendre_slope_ratios(order, x):
    """q_l = 2·P_l'(x) / (l(l+1)) for l ≥ 1 and q_0 = 2/(1+x); every q_l is 1 at x = 1.

    P_l' comes from P'_{l+1} = P'_{l-1} + (2l+1)·P_l with Bonnet's recurrence for P_l: both are stable on
    [0, 1] and neither subtracts nearly equal numbers near x = 1."""
    ratios = np.empty(order)
    ratios[0] = 2.0 / (1.0 + x)
    legendre_prev, legendre = 1.0, x            # P_{l-1}, P_l
    slope_prev, slope = 0.0, 1.0                # P'_{l-1}, P'_l
    for l in range(1, order):
        ratios[l] = 2.0 * slope / (l * (l + 1))
        legendre_next = ((2 * l + 1) * x * legendre - l * legendre_prev) / (l + 1)
        slope_prev, slope = slope, slope_prev + (2 * l + 1) * legendre
        legendre_prev, legendre = legendre, legendre_next
    return ratios


def sun_disc_zonal(order, angular_radius, irradiance=1.0):
    """z_l of a disc of constant radiance around +Z, angular radius α ∈ [0, π/2], whose irradiance on a
    surface facing it is `irradiance` (radiance = irradiance / (π·sin²α)); α = 0 is the delta.

    z_l = radiance·2π·sqrt((2l+1)/4π)·∫_{cos α}^1 P_l. Integrating Legendre's equation gives
    ∫_x^1 P_l = (1-x²)·P_l'(x) / (l(l+1)), and 1-x² = sin²α cancels the radiance's 1/sin²α exactly:
    z_l = irradiance·sqrt((2l+1)/4π)·q_l(cos α), with no cancellation and no special case at α = 0."""
    angular_radius = float(angular_radius)
    if not 0.0 <= angular_radius <= np.pi / 2:
        raise ValueError(f"sun angular radius must be in [0, π/2], got {angular_radius}")
    ratios = _legendre_slope_ratios(order, np.cos(angular_radius))
    return irradiance * ratios * _zonal_normalisation(order)


def constant_sky(order, radiance=1.0):
    """SH coefficients (order²,) of a constant radiance over the whole sphere."""
    coeffs = np.zeros(order * order)
    coeffs[0] = radiance * np.sqrt(4 * np.pi)
    return coeffs


def _row_polar_angles(height):
    """θ of each row's centre; row 0 is v ∈ [0, 1/H], the bottom."""
    return np.pi * (1.0 - (np.arange(height) + 0.5) / height)


def _column_azimuths(width):
    """φ of each column's centre: u = 0 at φ = π, decreasing to -π at u = 1."""
    return np.pi * (1.0 - 2.0 * (np.arange(width) + 0.5) / width)


def _directions(polar_angles, azimuths):
    """Unit directions (len(θ), len(φ), 3) on the grid of polar angles × azimuths."""
    sin_theta = np.sin(polar_angles)[:, None]
    x = sin_theta * np.cos(azimuths)
    y = sin_theta * np.sin(azimuths)
    z = np.broadcast_to(np.cos(polar_angles)[:, None], x.shape)
    return np.stack([x, y, z], axis=-1)


def equirect_directions(height, width):
    """Unit directions (H, W, 3) of the pixel centres of an equirect image in Blender's layout."""
    return _directions(_row_polar_angles(height), _column_azimuths(width))


def equirect_solid_angles(height, width):
    """Exact solid angle (H, 1) of the pixels in each row: (2π/W)·Δz, Δz the row's extent in z = cos θ.

    Δz = cos(πi/H) - cos(π(i+1)/H) is evaluated as 2·sin(π(2i+1)/(2H))·sin(π/(2H)), which keeps full
    relative precision at the poles where the difference form cancels."""
    rows = np.arange(height)
    band_heights = 2.0 * np.sin(np.pi * (2 * rows + 1) / (2 * height)) * np.sin(np.pi / (2 * height))
    return (2.0 * np.pi / width * band_heights)[:, None]


def _row_chunks(height, width, order):
    """Row ranges small enough that a chunk's SH basis stays within _CHUNK_VALUES."""
    rows = max(1, _CHUNK_VALUES // (width * order * order))
    return [(start, min(start + rows, height)) for start in range(0, height, rows)]


def project_equirect(pixels, order):
    """∫ L(ω)·Y_k(ω) dω for an equirect image (H, W, C ≥ 3) → (3, order²) for its RGB (alpha is ignored), each
    pixel taken as its centre's value times its exact solid angle. Accumulates in float64, a few rows at a time."""
    height, width = pixels.shape[:2]
    polar_angles, azimuths = _row_polar_angles(height), _column_azimuths(width)
    solid_angles = equirect_solid_angles(height, width)
    coeffs = np.zeros((_RGB, order * order))
    for start, stop in _row_chunks(height, width, order):
        basis = sh.evaluate(order, _directions(polar_angles[start:stop], azimuths))
        weighted = np.asarray(pixels[start:stop, :, :_RGB], dtype=np.float64) * solid_angles[start:stop, :, None]
        coeffs += weighted.reshape(-1, _RGB).T @ basis.reshape(-1, order * order)
    return coeffs


def reconstruct_equirect(coeffs, height, width):
    """Evaluates SH coefficients (channels, order²), or (order²,) for one channel, at the pixel centres of an
    equirect grid → (H, W, channels)."""
    coeffs = np.atleast_2d(np.asarray(coeffs, dtype=np.float64))
    order = math.isqrt(coeffs.shape[-1])
    polar_angles, azimuths = _row_polar_angles(height), _column_azimuths(width)
    image = np.empty((height, width, coeffs.shape[0]))
    for start, stop in _row_chunks(height, width, order):
        image[start:stop] = sh.evaluate(order, _directions(polar_angles[start:stop], azimuths)) @ coeffs.T
    return image


def window(order, kind, strength=1.0):
    """Per-band factors (order,) that taper high bands to reduce ringing; the window spans `order` bands,
    so the first band not stored would get 0. kind: "none", "hanning" (1 + cos(πl/order))/2,
    "lanczos" sinc(l/order), "tapered": Hanning's factors to the power `strength` (0: none, 1: Hanning)."""
    bands = np.arange(order) / order
    if kind == "tapered":
        return window(order, "hanning") ** strength
    if kind == "none":
        return np.ones(order)
    if kind == "hanning":
        return 0.5 * (1.0 + np.cos(np.pi * bands))
    if kind == "lanczos":
        return np.sinc(bands)
    raise ValueError(f"unknown window {kind!r}: expected 'none', 'hanning', 'lanczos' or 'tapered'")


def apply_window(coeffs, factors):
    """Multiplies every m of band l in coeffs (..., order²) by factors[l]."""
    scale = _per_coefficient(factors)
    if np.shape(coeffs)[-1] != len(scale):
        raise ValueError(f"{np.shape(coeffs)[-1]} coefficients do not match a window of {len(factors)} bands")
    return np.asarray(coeffs) * scale



def box_filtered(pixels, rows):
    """An equirect image's RGB averaged over square blocks to at most `rows` rows (float64)."""
    rgb = np.asarray(pixels[..., :_RGB], dtype=np.float64)
    factor = max(1, rgb.shape[0] // rows)
    height, width = rgb.shape[0] // factor, rgb.shape[1] // factor
    trimmed = rgb[:height * factor, :width * factor]
    return trimmed.reshape(height, factor, width, factor, _RGB).mean(axis=(1, 3))
