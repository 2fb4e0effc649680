"""Auto storage's measure: how much vertex storage loses between vertices. Probe points inside the faces (a fixed
number per object, spread over the triangles in proportion to their area) are baked like vertices; each one's
transfer is compared with what its triangle's corners interpolate there. The Monte Carlo noise of both sides is
taken out (independent, so squares add), leaving the interpolation error alone.

Kept apart from the vertex bake's own interpolation estimate so either can serve Auto's choice.
"""

from dataclasses import dataclass

import numpy as np

from . import sampling

PROBE_POINTS = 1024   # per object: enough to find a shadow crossing a one-quad floor
PROBE_SEED_KEY = 0x7E1  # the probes' own random stream, apart from any vertex's
AUTO_TARGET = 0.01    # Auto's target where the bake has no target error


@dataclass
class Probes:
    triangles: np.ndarray    # (M,) the triangle each probe lies in
    barycentric: np.ndarray  # (M, 3) its weights on the triangle's corners


def probe_points(areas: np.ndarray, count: int = PROBE_POINTS, seed: int = 0) -> Probes:
    """`count` points over triangles of `areas` (T,): stratified in cumulative area (so each triangle gets its
    share, a large one several) and uniform within each triangle."""
    total = areas.sum()
    if total <= 0 or count <= 0:
        return Probes(np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
    uniform = sampling.hash_uniform(seed, np.array([PROBE_SEED_KEY], dtype=np.int64), 3 * count).reshape(3, count)
    positions = (np.arange(count) + uniform[0]) / count * total
    triangles = np.minimum(np.searchsorted(np.cumsum(areas), positions, side="right"), len(areas) - 1)
    root = np.sqrt(uniform[1])  # uniform over a triangle
    barycentric = np.stack([1.0 - root, root * (1.0 - uniform[2]), root * uniform[2]], axis=1)
    return Probes(triangles, barycentric)


@dataclass
class InterpolationError:
    rms: float          # RMS over probes of ‖T − interpolated‖ ÷ ‖T_unshadowed‖, noise taken out
    max: float          # the largest probe's, noise taken out
    probes: int


def interpolation_error(probe_transfer, probe_std, corner_transfer, corner_std, barycentric, scale) -> InterpolationError:
    """probe_transfer (M, n²) and its standard error (M,); corner_transfer (M, 3, n²) and standard errors (M, 3) of
    each probe's triangle corners; `scale` the norm of unshadowed transfer."""
    interpolated = np.einsum("mc,mck->mk", barycentric, corner_transfer)
    difference = np.linalg.norm(probe_transfer - interpolated, axis=1)
    noise = probe_std ** 2 + np.einsum("mc,mc->m", barycentric ** 2, corner_std ** 2)
    own = np.sqrt(np.maximum(difference ** 2 - noise, 0.0)) / scale
    rms = np.sqrt(max(np.mean(difference ** 2) - np.mean(noise), 0.0)) / scale if len(own) else 0.0
    return InterpolationError(float(rms), float(own.max(initial=0.0)), len(own))
