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


def scattered(values, live, missing):
    """`values` (n, ...) of the live rays as the values of every ray (`live`'s size, ...), `missing` for the
    others; `values` itself without a mask."""
    if live is None:
        return values
    every = np.full((live.size,) + values.shape[1:], missing, dtype=values.dtype)
    every[live.ravel()] = values
    return every
