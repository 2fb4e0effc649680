"""What vertex storage loses between vertices: transfer baked at a few points inside faces, compared with what the
faces' stored corners interpolate there (Blender interpolates colour attributes linearly over each triangle).

The points are drawn in proportion to area, so their mean is a mean over the surface; each point's difference
holds Monte Carlo noise as well (its own and its corners'), whose estimated variance is taken out.
"""

from dataclasses import dataclass

import numpy as np

from . import sampling

# Points per object: one per POINTS_PER_PROBE vertices, within these bounds. At 1/16 the probes add about 6 % to a
# smooth bake's rays and estimate the RMS to about ±10 % (≥ 32 points).
POINTS_PER_PROBE = 16
FEWEST_PROBES, MOST_PROBES = 32, 1024
# Storage Auto decides from its probes before the bake, so it takes the most: a shadow crossing a one-quad floor
# must be found. Its target where the bake has none:
AUTO_PROBES = MOST_PROBES
AUTO_TARGET = 0.01


@dataclass
class Probes:
    positions: np.ndarray  # (S, 3) points inside faces
    normals: np.ndarray    # (S, 3) the interpolated shading normal there
    corners: np.ndarray    # (S, 3) the shading points of the triangle's corners
    weights: np.ndarray    # (S, 3) barycentric weights of the point in its triangle


def probe_count(points: int) -> int:
    return int(np.clip(points // POINTS_PER_PROBE, FEWEST_PROBES, MOST_PROBES))


def face_probes(triangles, positions, normals, count: int, seed: int) -> Probes:
    """`count` points drawn uniformly over the surface of `triangles` (T, 3) indexing shading points with world
    `positions` and `normals` (P, 3); none where the surface has no area."""
    corners = positions[triangles]
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    usable = areas > 0
    if not usable.any() or count <= 0:
        return Probes(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)))
    uniforms = sampling.hash_uniform(seed, np.arange(count), 3)
    cumulative = np.cumsum(np.where(usable, areas, 0.0))
    chosen = np.minimum(np.searchsorted(cumulative, uniforms[:, 0] * cumulative[-1], side="right"),
                        len(triangles) - 1)
    # Uniform on a triangle: fold the unit square's upper half back onto the lower one.
    u, v = uniforms[:, 1], uniforms[:, 2]
    folded = u + v > 1.0
    u, v = np.where(folded, 1.0 - u, u), np.where(folded, 1.0 - v, v)
    weights = np.stack([1.0 - u - v, u, v], axis=1)
    points = triangles[chosen]
    blended = sampling.unit_or_zero(np.einsum("sk,skd->sd", weights, normals[points]))
    return Probes(np.einsum("sk,skd->sd", weights, positions[points]), blended, points, weights)


def interpolation_errors(probes: Probes, probe_transfer, probe_std_error, transfer, std_error, scale: float):
    """(S,) squared relative interpolation error at each probe, noise taken out (may be negative where noise
    dominates): |T(probe) − Σ w T(corner)|² − (σ²(probe) + Σ w² σ²(corner)), ÷ scale². Transfer (P, ..., n²)."""
    interpolated = np.einsum("sk,sk...->s...", probes.weights, transfer[probes.corners])
    difference = (probe_transfer - interpolated).reshape(len(probe_transfer), -1)
    noise = probe_std_error ** 2 + np.einsum("sk,sk->s", probes.weights ** 2, std_error[probes.corners] ** 2)
    return (np.einsum("sj,sj->s", difference, difference) - noise) / scale ** 2


def summarise(squared_errors) -> tuple[float, float]:
    """(RMS, max) relative interpolation error from probes' noise-free squared errors; (0, 0) without probes."""
    if len(squared_errors) == 0:
        return 0.0, 0.0
    clipped = np.maximum(squared_errors, 0.0)
    return float(np.sqrt(max(float(np.mean(squared_errors)), 0.0))), float(np.sqrt(clipped.max()))
