"""The ray engine: the one interface through which the bake asks questions of its occluders' triangles. Engines
(core.engines) implement it; a bake builds one, chosen by name, once per occluders (core.ray_caster).

Three questions, each asked of a whole batch in numpy arrays, so that an engine which traces rays in bulk needs no
Python per ray: is each ray blocked (occluded), which triangle does each ray hit first and where (hits), and which
triangles lie near each point (nearest). Engines take the triangles recentred on the occluders' bounding box
(float64, which they may hold in float32, as a ray tree does) and rays in the same frame; every answer is an array.
"""

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass
class RayHits:
    """The first triangle each ray of a batch (c, k) hits: its index (c, k), −1 for none; the distance along the
    ray (c, k), NaN for none; and the barycentric weights of the hit point in that triangle's corners (c, k, 3),
    NaN for none."""
    triangle: np.ndarray
    distance: np.ndarray
    barycentric: np.ndarray

    @property
    def found(self) -> np.ndarray:
        """(c, k) bool: the rays that hit a triangle."""
        return ~np.isnan(self.distance)


@dataclass
class NearSurfaces:
    """The triangles nearer than a radius to each of n points, listed point by point: the point (F,) int64 in
    ascending order, each point's triangles in the engine's order; the triangle (F,); its point nearest to the
    point (F, 3); its unit normal (F, 3), by its corners' winding, zero for a degenerate triangle; and the
    distance (F,)."""
    point: np.ndarray
    triangle: np.ndarray
    location: np.ndarray
    normal: np.ndarray
    distance: np.ndarray


class RayEngine(Protocol):
    """Ray queries against fixed triangles. A batch of rays is origins (c, 3) float64 with k unit directions each
    (c, k, 3), float64 or float32; a ray meets a triangle from either side, up to the engine's `max_distance`.
    `live` (c, k) bool, when given, picks the rays to trace: the others count as missing everything."""

    max_distance: float

    def occluded(self, origins: np.ndarray, directions: np.ndarray, live: np.ndarray | None = None) -> np.ndarray:
        """(c, k) bool: does the ray hit any triangle."""

    def hits(self, origins: np.ndarray, directions: np.ndarray, live: np.ndarray | None = None) -> RayHits:
        """Each ray's first hit."""

    def nearest(self, points: np.ndarray, radius: float) -> NearSurfaces:
        """Every triangle nearer than `radius` to each of `points` (n, 3)."""


def hits_at(origins, directions, triangle, distance, vertices, triangles) -> RayHits:
    """The hits of rays (origins (c, 3), directions (c, k, 3)) on `triangle` (c, k) (−1 for none) at `distance`
    (c, k) (NaN for none), with the barycentric weights of origin + distance · direction in the hit triangle of
    `triangles` (T, 3) over `vertices` (P, 3), in float64: every engine that gives the same triangle and distance
    gives the same weights."""
    c, k = distance.shape
    group, ray = np.nonzero(~np.isnan(distance))
    points = origins[group] + distance[group, ray][:, None] * directions[group, ray]
    barycentric = np.full((c, k, 3), np.nan)
    barycentric[group, ray] = _barycentric(points, vertices[triangles[triangle[group, ray]]])
    return RayHits(triangle, distance, barycentric)


def _barycentric(points, corners) -> np.ndarray:
    """(H, 3) weights of `points` (H, 3) in triangles `corners` (H, 3, 3); degenerate triangles get 1/3 each."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    denominator = d00 * d11 - d01 * d01
    safe = np.where(np.abs(denominator) > 0, denominator, 1.0)
    v = np.clip((d11 * d20 - d01 * d21) / safe, 0.0, 1.0)
    w = np.clip((d00 * d21 - d01 * d20) / safe, 0.0, 1.0 - v)
    weights = np.stack([1.0 - v - w, v, w], axis=1)
    return np.where((np.abs(denominator) > 0)[:, None], weights, 1.0 / 3.0)


def scattered(values, live, missing):
    """`values` (n, ...) of the live rays as the values of every ray (`live`'s size, ...), `missing` for the
    others; `values` itself without a mask."""
    if live is None:
        return values
    every = np.full((live.size,) + values.shape[1:], missing, dtype=values.dtype)
    every[live.ravel()] = values
    return every
