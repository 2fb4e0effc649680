"""The occluders as the bake's rays meet them: recentred on their bounding box, so that float32 precision does not
depend on where the scene is, with the offset rays start at off a surface and the ray engine (core.ray_engine)
built over them once."""

import numpy as np

from . import engines
from .ray_engine import RayEngine

# Ray origins sit this fraction of the scene's diagonal above the surface: scale-free, and far above
# float32 rounding because the geometry is recentred on the scene's bounding box before the engine is built.
OFFSET_FRACTION = 1e-5


class RayCaster:
    """Occluders (core.bake.Occluders) in the frame of their bounding box's centre: every position the bake
    gives the engine is in this frame."""

    def __init__(self, occluders):
        self.center, diagonal = occluders.center, occluders.diagonal  # each takes the vertices' bounds
        self.offset = OFFSET_FRACTION * diagonal
        self.hull = occluders.hull - self.center
        self.vertices = occluders.vertices - self.center
        self.single_vertices = self.vertices.astype(np.float32)  # as an engine holds them
        self.triangles = occluders.triangles
        self.against = occluders.against  # (P,) bool or None: core.bake.Occluders'
        self.polygons = [polygon - self.center for polygon in occluders.polygons]
        self.engine: RayEngine = engines.build(occluders.engine, self.vertices, self.triangles, 2.0 * diagonal)
