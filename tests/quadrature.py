"""References for the tests, independent of the code under test: integration on the sphere and scipy's SH."""

import numpy as np
from scipy.special import sph_harm_y


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


def reference_sh(order, directions):
    """Real SH in the project's convention (Condon-Shortley phase, k = l(l+1)+m), built from scipy's complex
    sph_harm_y: m > 0 → √2·Re, m < 0 → √2·Im of Y_l^|m|."""
    directions = np.asarray(directions, dtype=np.float64)
    theta = np.arccos(np.clip(directions[..., 2], -1.0, 1.0))
    phi = np.arctan2(directions[..., 1], directions[..., 0])
    values = np.empty(directions.shape[:-1] + (order * order,))
    for l in range(order):
        for m in range(-l, l + 1):
            y = sph_harm_y(l, abs(m), theta, phi)
            part = y.real if m >= 0 else y.imag
            values[..., l * (l + 1) + m] = part if m == 0 else np.sqrt(2.0) * part
    return values


def polygon_directions(apex, polygon, nodes=48):
    """Directions from `apex` to a flat convex polygon (m, 3), with solid-angle weights: a fan of triangles,
    each by collapsed Gauss-Legendre (Duffy), dω = h dA / |x|³ with h the apex's distance to the plane. Smooth
    and accurate when the apex is not close to the polygon's plane."""
    s, ws = np.polynomial.legendre.leggauss(nodes)
    s, ws = 0.5 * (s + 1.0), 0.5 * ws
    u, v = np.meshgrid(s, s, indexing="ij")
    weight = np.outer(ws, ws) * u
    directions, weights = [], []
    for b, c in zip(polygon[1:-1], polygon[2:]):
        a = polygon[0]
        points = a + u[..., None] * (b - a) + (u * v)[..., None] * (c - b)
        area_vector = np.cross(b - a, c - a)
        x = points - apex
        distance = np.linalg.norm(x, axis=-1)
        height = abs(np.dot(area_vector, a - apex)) / np.linalg.norm(area_vector)
        directions.append((x / distance[..., None]).reshape(-1, 3))
        weights.append((weight * np.linalg.norm(area_vector) * height / distance**3).ravel())
    return np.concatenate(directions), np.concatenate(weights)


def clip_below(polygon, apex, normal):
    """The flat polygon's part above the plane through `apex` with `normal` (the test's own clipping)."""
    kept = []
    for p, q in zip(polygon, np.roll(polygon, -1, axis=0)):
        hp, hq = np.dot(p - apex, normal), np.dot(q - apex, normal)
        if hp >= 0:
            kept.append(p)
        if (hp >= 0) != (hq >= 0):
            kept.append(p + hp / (hp - hq) * (q - p))
    return np.array(kept)


def polygon_transfer(order, apex, normal, polygon):
    """(1/π) ∫ (n·ω)₊ Y_k dω over the polygon's directions, with scipy's SH."""
    part = clip_below(polygon, apex, normal)
    if len(part) < 3:
        return np.zeros(order * order)
    directions, weights = polygon_directions(apex, part)
    return (weights * (directions @ normal)) @ reference_sh(order, directions) / np.pi
