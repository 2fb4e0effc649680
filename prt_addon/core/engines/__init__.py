"""The ray engines (core.ray_engine.RayEngine), one module each, and `build`, which makes the one a bake names.

'bvhtree': mathutils' BVHTree, Blender's own ray tree, the default; its module is the only one of the core that
imports mathutils, and only when it is chosen. 'reference': numpy alone, every ray against every triangle; for
small scenes, tests without Blender, and as the truth the other engines are tested against."""

from ..ray_engine import RayEngine

NAMES = ("bvhtree", "reference")
DEFAULT = "bvhtree"


def build(name: str, vertices, triangles, max_distance: float) -> RayEngine:
    """The engine `name` over triangles (T, 3) of vertices (P, 3) float64, its rays reaching `max_distance`."""
    if name == "bvhtree":
        from .bvhtree import BVHTreeEngine as engine
    elif name == "reference":
        from .reference import ReferenceEngine as engine
    else:
        raise ValueError(f"no ray engine {name!r}: the engines are {', '.join(NAMES)}")
    return engine(vertices, triangles, max_distance)
