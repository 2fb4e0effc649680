"""The BVHTree engine: mathutils' BVHTree (Blender's own ray tree, float32) behind core.ray_engine's interface.
With it the core needs Blender's mathutils; nothing else of the core imports it."""

from itertools import chain, repeat
from operator import is_not, itemgetter

import numpy as np
from mathutils import Vector
from mathutils.bvhtree import BVHTree

from ..ray_engine import NearSurfaces, RayHits, hits_at, scattered


class BVHTreeEngine:
    """A BVHTree over the triangles. Rays are cast one by one in C (map over the tree's ray_cast): a blocked ray is
    one whose nearest hit the tree finds."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, max_distance: float):
        self.vertices, self.triangles, self.max_distance = vertices, triangles, max_distance
        self.tree = BVHTree.FromPolygons(vertices.tolist(), triangles.tolist(), all_triangles=True)

    def occluded(self, origins, directions, live=None) -> np.ndarray:
        """See core.ray_engine.RayEngine."""
        c, k = directions.shape[:2]
        casts = self._casts(origins, directions, live)
        # a miss returns (None, None, None, None); bytes() collects the flags fastest
        found = np.frombuffer(bytes(map(is_not, map(itemgetter(3), casts), repeat(None))), dtype=bool)
        return scattered(found, live, False).reshape(c, k)

    def hits(self, origins, directions, live=None) -> RayHits:
        """See core.ray_engine.RayEngine. The barycentric weights are those of origin + distance · direction, in
        float64 in the float64 triangles (core.ray_engine.hits_at)."""
        c, k = directions.shape[:2]
        found = np.array(list(map(itemgetter(2, 3), self._casts(origins, directions, live))),
                         dtype=np.float64).reshape(-1, 2)
        triangle = np.nan_to_num(found[:, 0], nan=-1.0).astype(np.int64)  # both NaN on a miss
        return hits_at(origins, directions, scattered(triangle, live, -1).reshape(c, k),
                       scattered(found[:, 1], live, np.nan).reshape(c, k), self.vertices, self.triangles)

    def nearest(self, points, radius) -> NearSurfaces:
        """See core.ray_engine.RayEngine. The normals are the tree's own, computed here from the triangles."""
        near = list(map(self.tree.find_nearest_range, map(tuple, points.tolist()), repeat(radius)))
        counts = np.fromiter(map(len, near), dtype=np.int64, count=len(near))
        found = list(chain.from_iterable(near))  # (location, normal, index, distance) per triangle, point by point
        triangle = np.fromiter(map(itemgetter(2), found), dtype=np.int64, count=len(found))
        return NearSurfaces(np.repeat(np.arange(len(points)), counts), triangle,
                            _vectors(map(itemgetter(0), found), len(found)),
                            _tree_normals(self.vertices[self.triangles[triangle]]),
                            np.fromiter(map(itemgetter(3), found), dtype=np.float64, count=len(found)))

    def _casts(self, origins, directions, live):
        """ray_cast results of the rays (see occluded), the live ones only, lazily, looped in C by map(). Directions
        are read one coordinate at a time through memoryviews, which make each float as the loop reaches it: 4 % of
        a bake's time less than building lists of them first. Each origin is a Vector, which ray_cast reads with a
        copy where a tuple is parsed float by float for every ray: 1.5 % of a ray's cost, and the same float32
        values."""
        k = directions.shape[1]
        coordinates = directions.reshape(-1, 3).T  # (3, c·k): rows contiguous for component-major directions
        if live is None:
            per_origin = repeat(k)
        else:  # row by row: a boolean index on the second axis of the (3, c·k) view is 5× slower
            mask = live.ravel()
            coordinates = [row[mask] for row in coordinates]
            per_origin = np.count_nonzero(live, axis=1).tolist()
        xs, ys, zs = map(memoryview, map(np.ascontiguousarray, coordinates))
        per_ray_origins = chain.from_iterable(map(repeat, map(Vector, origins.tolist()), per_origin))
        return map(self.tree.ray_cast, per_ray_origins, zip(xs, ys, zs), repeat(self.max_distance))


def _tree_normals(corners) -> np.ndarray:
    """(F, 3) the unit normals the tree gives for triangles (F, 3, 3), bit for bit: its float32 arithmetic
    (Blender's normal_tri_v3 on the float32 corners), which costs less than reading them from its results."""
    a, b, c = (corners[:, i].astype(np.float32) for i in range(3))
    first, second = a - b, b - c
    normal = np.stack([first[:, 1] * second[:, 2] - first[:, 2] * second[:, 1],
                       first[:, 2] * second[:, 0] - first[:, 0] * second[:, 2],
                       first[:, 0] * second[:, 1] - first[:, 1] * second[:, 0]], axis=1)
    length = np.sqrt((normal[:, 0] * normal[:, 0] + normal[:, 1] * normal[:, 1]) + normal[:, 2] * normal[:, 2])
    normal *= np.divide(np.float32(1.0), length, out=np.zeros_like(length), where=length > 1e-35 ** 0.5)[:, None]
    return normal.astype(np.float64)


def _vectors(vectors, count) -> np.ndarray:
    """(count, 3) float64 from an iterable of mathutils Vectors (float32: exact in float64)."""
    return np.fromiter(chain.from_iterable(vectors), dtype=np.float64, count=3 * count).reshape(count, 3)
