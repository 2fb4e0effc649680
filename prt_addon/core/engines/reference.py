"""The reference engine: every ray against every triangle (Möller–Trumbore) and every point against every triangle,
in numpy, so the core bakes without Blender. Its cost grows with rays × triangles: it is for small scenes (tests,
and the truth the other engines are tested against), not for production.

Like a ray tree it holds the corners in float32, and it takes the rays' origins and directions in float32; its
arithmetic is float64."""

import numpy as np

from .. import arrays
from ..ray_engine import NearSurfaces, RayHits

PAIRS_AT_ONCE = 1 << 17  # ray-triangle or point-triangle pairs worked at once: float64 arrays of 1 MB


class ReferenceEngine:
    """Brute force over `triangles` (T, 3) of `vertices` (P, 3). Möller–Trumbore's determinant and numerators are
    linear in a ray's direction d once its origin o is fixed: with the edges e1, e2 from corner p0, n = e1 × e2 and
    w = o − p0, det = −d·n, u·det = d·(e2 × w), v·det = d·(w × e1) and t·det = w·n. So the rays from one origin meet
    every triangle in three matrix products."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, max_distance: float):
        self.max_distance = max_distance
        self.corners = _single(vertices)[np.asarray(triangles, dtype=np.int64)].reshape(-1, 3, 3)  # (T, 3, 3)
        self.edges = self.corners[:, 1] - self.corners[:, 0], self.corners[:, 2] - self.corners[:, 0]
        self.normals = np.cross(*self.edges)  # (T, 3), |n| = twice the area

    def occluded(self, origins, directions, live=None) -> np.ndarray:
        """See core.ray_engine.RayEngine."""
        return self.hits(origins, directions, live).found

    def hits(self, origins, directions, live=None) -> RayHits:
        """See core.ray_engine.RayEngine: the nearest of the triangles each ray crosses at 0 ≤ t < max_distance
        (the one listed first of those at one distance). Every ray is traced; those `live` leaves out are then
        dropped."""
        c, k = directions.shape[:2]
        origins, directions = _single(origins), _single(directions)
        triangle = np.full((c, k), -1, dtype=np.int64)
        distance = np.full((c, k), np.nan)
        barycentric = np.full((c, k, 3), np.nan)
        rays = max(1, PAIRS_AT_ONCE // max(1, len(self.corners)))  # rays of one origin at once
        for group in range(c if len(self.corners) else 0):
            for first in range(0, k, rays):
                part = slice(first, first + rays)
                self._first_hits(origins[group], directions[group, part], triangle[group, part],
                                 distance[group, part], barycentric[group, part])
        if live is not None:
            triangle[~live], distance[~live], barycentric[~live] = -1, np.nan, np.nan
        return RayHits(triangle, distance, barycentric)

    def _first_hits(self, origin, directions, triangle, distance, barycentric):
        """Writes the nearest hit of each ray from `origin` (3,) along `directions` (r, 3) into `triangle` (r,),
        `distance` (r,) and `barycentric` (r, 3), where there is one."""
        w = origin - self.corners[:, 0]  # (T, 3)
        det, u, v = (arrays.one_thread_product(directions, form.T)
                     for form in (-self.normals, np.cross(self.edges[1], w), np.cross(w, self.edges[0])))
        with np.errstate(divide="ignore", invalid="ignore"):  # det = 0: no hit, as NaN and ±inf compare below
            u /= det
            v /= det
            t = np.einsum("td,td->t", w, self.normals) / det
        crossed = (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t >= 0.0) & (t < self.max_distance)
        t = np.where(crossed, t, np.inf)
        nearest = np.argmin(t, axis=1)
        ray = np.flatnonzero(crossed[np.arange(len(directions)), nearest])
        face = nearest[ray]
        u, v = u[ray, face], v[ray, face]
        triangle[ray], distance[ray] = face, t[ray, face]
        barycentric[ray] = np.stack([1.0 - u - v, u, v], axis=1)

    def nearest(self, points, radius) -> NearSurfaces:
        """See core.ray_engine.RayEngine: each point's triangles in the order of their indices."""
        points = _single(points)
        found = [(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))]
        if len(self.corners):
            step = max(1, PAIRS_AT_ONCE // len(self.corners))
            found += [self._near(points[first:first + step], first, radius) for first in range(0, len(points), step)]
        point, triangle, location = (np.concatenate(column) for column in zip(*found))
        length = np.linalg.norm(self.normals, axis=1, keepdims=True)
        unit = np.divide(self.normals, length, out=np.zeros_like(self.normals), where=length > 0.0)
        return NearSurfaces(point, triangle, location, unit[triangle], np.linalg.norm(points[point] - location, axis=1))

    def _near(self, points, first, radius):
        """(point, triangle, location) of the triangles nearer than `radius` to `points` (numbered from `first`)."""
        count = len(self.corners)
        repeated = np.repeat(points, count, axis=0)
        location = closest_points(repeated, np.tile(self.corners, (len(points), 1, 1)))
        close = np.flatnonzero(((repeated - location) ** 2).sum(1) < radius * radius)
        return first + close // count, close % count, location[close]


def closest_points(points, corners) -> np.ndarray:
    """(n, 3) the point of each triangle (corners (n, 3, 3)) nearest to each of `points` (n, 3), by the region of
    the triangle's plane the point projects into (Ericson, Real-Time Collision Detection, 5.1.5); the nearest
    corner for a degenerate triangle."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    ab, ac = b - a, c - a

    def dot(x, y):
        return (x * y).sum(1)

    d1, d2 = dot(ab, points - a), dot(ac, points - a)
    d3, d4 = dot(ab, points - b), dot(ac, points - b)
    d5, d6 = dot(ab, points - c), dot(ac, points - c)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        on_ab, on_ac = d1 / (d1 - d3), d2 / (d2 - d6)
        on_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        total = va + vb + vc
        inside = a + ab * (vb / total)[:, None] + ac * (vc / total)[:, None]
    regions = [(d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3), (vc <= 0) & (d1 >= 0) & (d3 <= 0),
               (d6 >= 0) & (d5 <= d6), (vb <= 0) & (d2 >= 0) & (d6 <= 0),
               (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)]
    choices = [a, b, a + on_ab[:, None] * ab, c, a + on_ac[:, None] * ac, b + on_bc[:, None] * (c - b)]
    region = np.select(regions, np.arange(1, 7), 0)
    nearest = np.where((region == 0)[:, None], inside, 0.0)
    for index, choice in enumerate(choices, start=1):
        nearest = np.where((region == index)[:, None], choice, nearest)
    broken = ~np.isfinite(nearest).all(axis=1)
    if broken.any():  # a degenerate triangle: its nearest corner
        distances = ((corners[broken] - points[broken, None]) ** 2).sum(-1)
        nearest[broken] = corners[broken, np.argmin(distances, axis=1)]
    return nearest


def _single(values) -> np.ndarray:
    """float64 values rounded to float32, as a ray tree holds and reads them."""
    return np.asarray(values, dtype=np.float32).astype(np.float64)
