"""The ray engines (core.ray_engine.RayEngine), one module each, and `build`, which makes the one a bake names.

'bvhtree': mathutils' BVHTree, Blender's own ray tree, the default; its module is the only one of the core that
imports mathutils, and only when it is chosen. 'reference': numpy alone, every ray against every triangle; for
small scenes, tests without Blender, and as the truth the other engines are tested against."""

from typing import NamedTuple

from ..ray_engine import RayEngine

NAMES = ("bvhtree", "reference")
DEFAULT = "bvhtree"


class Rate(NamedTuple):
    """An engine's typical speed in one process: a bake's rays per second (the estimator's work around the casts
    included) and the triangles its ray tree is built over per second."""
    rays_per_s: float
    triangles_per_s: float


# The time check's rates, as checking casts no ray: BVHTree's from a one-process bake of the demo (order 4, 256
# samples: 0.41 M rays/s) and building its tree over an 817 k-triangle grid (0.66 s); the reference engine's, which
# tests every triangle, on 2,000 triangles (it has no tree to build).
RATES = {"bvhtree": Rate(400_000, 1_200_000), "reference": Rate(40_000, 1e9)}


def build(name: str, vertices, triangles, max_distance: float) -> RayEngine:
    """The engine `name` over triangles (T, 3) of vertices (P, 3) float64, its rays reaching `max_distance`."""
    if name == "bvhtree":
        from .bvhtree import BVHTreeEngine as engine
    elif name == "reference":
        from .reference import ReferenceEngine as engine
    else:
        raise ValueError(f"no ray engine {name!r}: the engines are {', '.join(NAMES)}")
    return engine(vertices, triangles, max_distance)
