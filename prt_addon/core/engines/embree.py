"""The Embree engine: Intel's Embree 4 (float32, watertight, no back-face culling) through embreex, trimesh's
binding, behind core.ray_engine's interface. A batch of rays is one call that traces every ray in C, where the
BVHTree engine makes one Python call per ray. Only this module imports embreex, and only when the engine is chosen.

The contact search (`nearest`) is the BVHTree engine's, over the same triangles: a point query is not in embreex,
and the search is a small share of a bake's time. Every shadowed bake searches, so its tree is built with the scene,
before any worker forks: forked workers share it rather than each build its own on Blender's task threads, which
a forked child does not have."""

from functools import cache
from importlib.metadata import version

import numpy as np
from embreex import mesh_construction, rtcore, rtcore_scene

from ..ray_engine import NearSurfaces, RayHits, hits_at, scattered

_NO_RAYS = np.zeros((0, 3), dtype=np.float32)


@cache  # a device of its own tells the version: made once
def describe() -> str:
    """Embree's version and its binding's, as the report names the engine: 'Embree 4.4.0 via embreex 4.4.0.post1'."""
    embree = repr(rtcore.EmbreeDevice()).rsplit(" ", 1)[-1]  # 'Embree version:  4.4.0'
    return f"Embree {embree} via embreex {version('embreex')}"


class EmbreeEngine:
    """An Embree scene of the triangles, its BVH built here (embreex builds it at the first query otherwise): a
    process forked afterwards shares it and only traces rays, which start no thread. Embree's builder runs on
    threads, which a forked child does not have."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, max_distance: float):
        self.vertices, self.triangles, self.max_distance = vertices, triangles, max_distance
        self.scene = rtcore_scene.EmbreeScene()
        if len(triangles):
            mesh_construction.TriangleMesh(self.scene, np.ascontiguousarray(vertices, dtype=np.float32),
                                           np.ascontiguousarray(triangles, dtype=np.int32))
        self.scene.run(_NO_RAYS, _NO_RAYS, query="OCCLUDED")  # commits the scene: builds its BVH
        from .bvhtree import BVHTreeEngine  # mathutils: importing this module needs only embreex
        self.near = BVHTreeEngine(vertices, triangles, max_distance)

    def occluded(self, origins, directions, live=None) -> np.ndarray:
        """See core.ray_engine.RayEngine."""
        c, k = directions.shape[:2]
        found = self.scene.run(*_rays(origins, directions, live), dists=self.max_distance, query="OCCLUDED") >= 0
        return scattered(found, live, False).reshape(c, k)

    def hits(self, origins, directions, live=None) -> RayHits:
        """See core.ray_engine.RayEngine. The barycentric weights are those of origin + distance · direction, in
        float64 in the float64 triangles (core.ray_engine.hits_at), as the BVHTree engine gives them."""
        c, k = directions.shape[:2]
        found = self.scene.run(*_rays(origins, directions, live), dists=self.max_distance, query="INTERSECT",
                               output=True)
        triangle = found["primID"].astype(np.int64)  # −1 for a miss
        distance = np.where(triangle >= 0, found["tfar"].astype(np.float64), np.nan)
        return hits_at(origins, directions, scattered(triangle, live, -1).reshape(c, k),
                       scattered(distance, live, np.nan).reshape(c, k), self.vertices, self.triangles)

    def nearest(self, points, radius) -> NearSurfaces:
        """See core.ray_engine.RayEngine: the BVHTree engine's search."""
        return self.near.nearest(points, radius)


def _rays(origins, directions, live):
    """(origins, directions) (n, 3) float32 of the rays to trace, one row per ray: every ray, or the `live` ones."""
    k = directions.shape[1]
    flat = directions.reshape(-1, 3)
    if live is None:
        per_origin = k
    else:
        flat = flat[live.ravel()]
        per_origin = np.count_nonzero(live, axis=1)
    return (np.repeat(origins.astype(np.float32), per_origin, axis=0),
            np.ascontiguousarray(flat, dtype=np.float32))
