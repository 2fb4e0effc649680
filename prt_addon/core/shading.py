"""Shading a vertex is one dot product: radiance = Σ_k L_k T_k (times albedo); and the sun's direction from the
light controls' angles and its coefficients."""

import math

import numpy as np

from . import lobes, rotation


def direction_from_angles(theta: float, phi: float) -> tuple[float, float, float]:
    """θ from +Z (the zenith), φ from +X towards +Y, as the original program's light controls.

    A tuple from scalar maths: the handler calls this for every sun on every update, and lights hash it."""
    sin_theta = math.sin(theta)
    return sin_theta * math.cos(phi), sin_theta * math.sin(phi), math.cos(theta)


def sun_coefficients(order: int, direction, angular_radius: float, irradiance: float = 1.0) -> np.ndarray:
    """A sun disc around `direction`: a zonal lobe placed in closed form, no rotation matrix."""
    direction = np.asarray(direction, dtype=np.float64)
    direction = direction / np.linalg.norm(direction)
    return rotation.zonal_to_sh(lobes.sun_disc_zonal(order, angular_radius, irradiance), direction)


def shade(transfer: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Radiance (V, channels) as contiguous float32 for light (channels, n²) and transfer (V, n²) (grey: every
    light channel meets the same transfer) or (V, C, n²) (coloured: light channel c meets transfer channel c;
    light channels beyond C come out zero)."""
    light = np.asarray(light, dtype=transfer.dtype)
    if transfer.ndim == 2:
        return np.ascontiguousarray(transfer @ light.T, dtype=np.float32)
    radiance = np.zeros((len(transfer), len(light)), dtype=np.float32)
    channels = transfer.shape[1]
    radiance[:, :channels] = np.einsum("vck,ck->vc", transfer, light[:channels])
    return radiance
