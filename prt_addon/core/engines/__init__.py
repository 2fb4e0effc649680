"""The ray engines (core.ray_engine.RayEngine), one module each; `choose`, which resolves the Ray Engine setting, and
`build`, which makes the one a bake names.

'embree': Intel's Embree through the embreex package, where it is installed (its wheels: CPython 3.11 and 3.13 on
Linux x86-64, Windows x64 and macOS); the fastest, chosen by Auto. 'bvhtree': mathutils' BVHTree, Blender's own ray
tree, everywhere Blender runs; the reference implementation the bake's own tests hold to. Each engine's module is
the only one of the core that imports its package, and only when it is chosen. 'reference': numpy alone, every ray
against every triangle; for small scenes, tests without Blender, and as the truth the other engines are tested
against."""

from typing import NamedTuple

from ..errors import InputError
from ..ray_engine import RayEngine

NAMES = ("embree", "bvhtree", "reference")
DEFAULT = "bvhtree"
EMBREE_MISSING = ("Embree (the embreex package) is not installed for this Python; it has wheels for CPython 3.11 "
                  "and 3.13 on Linux x86-64, Windows x64 and macOS")
AUTO_FALLBACK = f"Ray Engine Auto casts with Blender's BVHTree, several times slower: {EMBREE_MISSING}"


def embree_installed() -> bool:
    """Whether the Embree engine imports here (embreex and the Embree library it loads)."""
    try:
        from . import embree  # noqa: F401
    except ImportError:
        return False
    return True


def choose(setting: str) -> tuple[str, str | None]:
    """The engine a Ray Engine setting (core.settings.RAY_ENGINE, or an engine's name) names here, and a note to
    tell once where Auto falls back to BVHTree. Raises InputError, naming the problem, for Embree where it is not
    installed."""
    if setting == "auto":
        if embree_installed():
            return "embree", None
        return "bvhtree", AUTO_FALLBACK
    if setting == "embree" and not embree_installed():
        raise InputError(f"Ray Engine Embree: {EMBREE_MISSING}; choose Auto or BVHTree")
    if setting not in NAMES:
        raise InputError(f"no ray engine {setting!r}: the engines are {', '.join(NAMES)}")
    return setting, None


def label(name: str, host: str = "") -> str:
    """The engine as a report names it, with its version: 'Embree 4.4.0 via embreex 4.4.0.post1'; BVHTree's is the
    Blender it comes with, `host` ('Blender 5.3.0')."""
    if name == "embree":
        if not embree_installed():
            return "Embree"
        from .embree import describe
        return describe()
    if name == "bvhtree":
        return f"BVHTree of {host}" if host else "BVHTree"
    return name


class Rate(NamedTuple):
    """An engine's typical speed in one process: a bake's rays per second (the estimator's work around the casts
    included) and the triangles its ray tree is built over per second."""
    rays_per_s: float
    triangles_per_s: float


# The time check's rates, as checking casts no ray: BVHTree's from a one-process bake of the demo (order 4, 256
# samples: 0.41 M rays/s) and building its tree over an 817 k-triangle grid (0.66 s); Embree's from the same bake
# (1.6 M rays/s, benchmarks/engines.py) and building its scene and the contact search's BVHTree over an 819 k-triangle
# grid (2.15 × BVHTree's time, side by side); the reference engine's, which tests every triangle, on 2,000 triangles
# (it has no tree to build).
RATES = {"embree": Rate(1_600_000, 560_000), "bvhtree": Rate(400_000, 1_200_000), "reference": Rate(40_000, 1e9)}


def build(name: str, vertices, triangles, max_distance: float) -> RayEngine:
    """The engine `name` over triangles (T, 3) of vertices (P, 3) float64, its rays reaching `max_distance`. Raises
    InputError where the engine a job names is not installed in this process (a worker, a farm shard)."""
    if name == "embree":
        if not embree_installed():
            raise InputError(f"the bake's ray engine is Embree: {EMBREE_MISSING}; install embreex here, or bake "
                             f"with Ray Engine BVHTree")
        from .embree import EmbreeEngine as engine
    elif name == "bvhtree":
        from .bvhtree import BVHTreeEngine as engine
    elif name == "reference":
        from .reference import ReferenceEngine as engine
    else:
        raise ValueError(f"no ray engine {name!r}: the engines are {', '.join(NAMES)}")
    return engine(vertices, triangles, max_distance)
