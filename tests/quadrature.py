"""Reference integration on the sphere for the tests: independent of the code under test."""

import numpy as np


def random_directions(count, seed=0):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def sphere_quadrature(order):
    """Gauss-Legendre in cos θ × uniform φ: exact for products of two order-`order` SH."""
    cos_theta, gl_weights = np.polynomial.legendre.leggauss(order)
    count_phi = 2 * order  # > 2(order-1): azimuthal frequencies of a product do not alias to 0
    phi = 2 * np.pi * (np.arange(count_phi) + 0.5) / count_phi
    sin_theta = np.sqrt(1 - cos_theta**2)[:, None]
    directions = np.stack(np.broadcast_arrays(
        sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta[:, None]), axis=-1)
    weights = np.repeat(gl_weights, count_phi) * (2 * np.pi / count_phi)
    return directions.reshape(-1, 3), weights
