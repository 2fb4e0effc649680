"""Diffuse SH transfer per vertex: the exact unshadowed transfer and the shadowed estimator.

Transfer convention: T_k = (1/π) ∫ V(ω) max(n·ω, 0) Y_k(ω) dω, so radiance = albedo · Σ_k L_k T_k.

Shadowed estimator (what makes it cheap compared with the seed's uniform-sphere Monte Carlo):
- the unshadowed part is exact (closed form), only the *blocked* light is sampled:
  T = T_unshadowed − (1/π) ∫ (1 − V) cos Y  ≈  T_unshadowed − mean over cosine-distributed rays of (1 − V)·Y;
  a vertex that sees nothing costs rays but adds no noise, and one that provably sees nothing casts none;
- directions are a rank-1 lattice, Cranley-Patterson rotated per vertex and replicate, so R independent
  replicates give an honest standard error;
- with a target error, rounds double the rays per replicate until each vertex meets the target.
"""

from dataclasses import dataclass
from itertools import chain, repeat
import math
from operator import itemgetter
import zlib

import numpy as np

from . import lobes, sampling, sh

MODES = ("unshadowed", "shadowed")
MAX_ORDER = 10
MIN_SAMPLES = 8
MAX_SAMPLES = 1 << 20
MAX_REPLICATES = 16
# Random streams per vertex (rounds × replicates): MAX_ROUNDS rounds of at most 40 lattice sizes each.
STREAMS_PER_VERTEX = 4096
MAX_ROUNDS = 6
# Target-error schedule: this estimator's error falls about as rays^-0.85 (benchmarks/bake.py), and a round is
# sized for the target ÷ 1.15 so most vertices finish in one extra round.
CONVERGENCE_RATE = 0.85
TARGET_MARGIN = 1.15
# Fixed chunk size: any split of chunks over workers does exactly the same arithmetic per chunk.
CHUNK_VERTICES = 64
# Ray origins sit this fraction of the scene's diagonal above the surface: scale-free, and far above
# float32 rounding because the geometry is recentred on the scene's bounding box before the BVH is built.
OFFSET_FRACTION = 1e-5
# Version of the stored layout and conventions; bump when either changes (2: surfaces touching a vertex
# no longer occlude it, as in Cycles).
CONVENTION_VERSION = 2


@dataclass
class BakeSettings:
    order: int = 4
    mode: str = "shadowed"
    samples: int = 256
    target_error: float = 0.0
    max_samples: int = 16384
    # 4 replicates: error 1.4x smaller than 8 at 256 rays (each replicate's lattice is denser) and still an
    # honest estimate (benchmarks/bake.py); 2 under-reports.
    replicates: int = 4
    seed: int = 0

    def problems(self) -> list[str]:
        """Every reason these settings cannot bake, as sentences for the user."""
        found = []
        if self.mode not in MODES:
            found.append(f"mode must be one of {', '.join(MODES)}, not {self.mode!r}")
        if not 1 <= self.order <= MAX_ORDER:
            found.append(f"order must be 1-{MAX_ORDER} bands, not {self.order}")
        if not MIN_SAMPLES <= self.samples <= MAX_SAMPLES:
            found.append(f"samples must be {MIN_SAMPLES}-{MAX_SAMPLES} rays per vertex, not {self.samples}")
        if not (self.target_error >= 0.0 and math.isfinite(self.target_error)):
            found.append(f"target error must be a finite number >= 0, not {self.target_error}")
        if self.max_samples < self.samples:
            found.append(f"max samples ({self.max_samples}) must be at least samples ({self.samples})")
        most_replicates = min(MAX_REPLICATES, max(self.samples, MIN_SAMPLES))  # each replicate needs a ray
        if not 2 <= self.replicates <= most_replicates:
            found.append(f"replicates must be 2-{most_replicates}, not {self.replicates}")
        return found

    @property
    def points_per_replicate(self) -> int:
        return max(1, self.samples // self.replicates)


@dataclass
class Receiver:
    """One object's vertices in world space; `key` makes its random streams independent of other objects."""
    name: str
    positions: np.ndarray  # (V, 3) float64
    normals: np.ndarray    # (V, 3) float64, unit; zero rows are vertices without a surface
    key: int
    # (V, 3) unit tangents from each vertex towards the inside of its faces, zero where there is no inside:
    # a vertex on a seam where another surface stands is baked as seen from its own faces' side.
    inward: np.ndarray | None = None

    @staticmethod
    def key_for(name: str) -> int:
        return zlib.crc32(name.encode("utf-8"))


@dataclass
class Occluders:
    """Triangles that cast shadows, in world space, and the points whose hull bounds them."""
    vertices: np.ndarray   # (P, 3) float64
    triangles: np.ndarray  # (T, 3) int
    hull: np.ndarray       # (H, 3) float64: any superset of the convex hull's vertices

    @property
    def center(self) -> np.ndarray:
        if len(self.vertices) == 0:
            return np.zeros(3)
        return 0.5 * (self.vertices.min(0) + self.vertices.max(0))

    @property
    def diagonal(self) -> float:
        if len(self.vertices) == 0:
            return 1.0
        return float(np.linalg.norm(self.vertices.max(0) - self.vertices.min(0))) or 1.0


@dataclass
class ChunkResult:
    transfer: np.ndarray   # (c, n²) float64
    std_error: np.ndarray  # (c,) norm of the coefficients' standard error
    rays: np.ndarray       # (c,) rays cast per vertex
    skipped: np.ndarray    # (c,) bool: provably unoccluded, no rays


def unshadowed_transfer(order: int, normals: np.ndarray) -> np.ndarray:
    """Exact, noise-free: the clamped cosine rotated to each normal; zero where the normal is zero."""
    return lobes.cosine_transfer(order, normals) * (np.abs(normals).sum(-1, keepdims=True) > 0)


def unshadowed_norm(order: int) -> float:
    """‖T_unshadowed‖, the same for every unit normal (addition theorem: Σ_m Y_lm(n)² = (2l+1)/4π):
    the scale of each vertex's relative error."""
    return float(np.linalg.norm(lobes.clamped_cosine_zonal(order)) / np.pi)


def provably_unoccluded(positions, normals, hull, offset) -> np.ndarray:
    """True where every occluder lies below the ray origins' plane, so no ray into the hemisphere can hit.

    The origin is `offset` above the tangent plane and every ray climbs away from it; the highest occluder
    point in the normal's direction is attained at a vertex of the occluders' convex hull.
    """
    if len(hull) == 0:
        return np.ones(len(positions), dtype=bool)
    highest = np.max(normals @ hull.T, axis=1)
    return highest - np.einsum("ij,ij->i", normals, positions) < 0.5 * offset


class RayCaster:
    """A BVHTree over the occluders, recentred so float32 precision does not depend on where the scene is."""

    def __init__(self, occluders: Occluders):
        from mathutils.bvhtree import BVHTree  # the only non-numpy dependency of the core
        self.center = occluders.center
        self.offset = OFFSET_FRACTION * occluders.diagonal
        self.max_distance = 2.0 * occluders.diagonal
        self.hull = occluders.hull - self.center
        local = occluders.vertices - self.center
        self.tree = BVHTree.FromPolygons(local.tolist(), occluders.triangles.tolist(), all_triangles=True)

    def occluded(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """origins (c, 3), directions (c, k, 3) → (c, k) bool: did the ray hit anything.

        A hit closer than the origin offset is a surface passing through the vertex itself (a floor vertex on
        the line where a wall stands): like Cycles, the ray goes on past it instead of counting it."""
        hit_distance = self._cast(map(tuple, origins.tolist()), directions)
        touching = np.nonzero(hit_distance < self.offset)  # NaN (a miss) compares False
        if len(touching[0]):
            beyond = origins[touching[0]] + 2.0 * self.offset * directions[touching]
            hit_distance[touching] = self._cast(map(tuple, beyond.tolist()), directions[touching][:, None, :])[:, 0]
        return ~np.isnan(hit_distance)

    def _cast(self, origins, directions: np.ndarray) -> np.ndarray:
        """Hit distances (NaN for a miss) of directions (c, k, 3) from c origins, looped in C by map()."""
        c, k = directions.shape[:2]
        xs, ys, zs = directions.reshape(-1, 3).T.tolist()
        per_ray_origins = chain.from_iterable(repeat(origin, k) for origin in origins)
        casts = map(self.tree.ray_cast, per_ray_origins, zip(xs, ys, zs), repeat(self.max_distance))
        return np.array(list(map(itemgetter(3), casts)), dtype=np.float64).reshape(c, k)


def shadowed_chunk(caster: RayCaster, positions, normals, inward, keys, settings: BakeSettings):
    """Generator: bakes one chunk, yielding the rays cast after each round; returns a ChunkResult."""
    order, replicates = settings.order, settings.replicates
    positions = positions - caster.center
    count = len(positions)
    unshadowed = unshadowed_transfer(order, normals)
    has_surface = np.abs(normals).sum(-1) > 0
    skipped = has_surface & provably_unoccluded(positions, normals, caster.hull, caster.offset)
    rays = np.zeros(count, dtype=np.int64)
    tangents, bitangents = sampling.orthonormal_basis(np.where(has_surface[:, None], normals, [0.0, 0.0, 1.0]))
    frames = np.stack([tangents, bitangents, normals], axis=1)
    origins = positions + caster.offset * (normals + inward)
    rounds = []  # (vertices, rays per vertex, blocked mean, blocked variance), combined below
    groups = [(settings.points_per_replicate, np.flatnonzero(has_surface & ~skipped))]
    round_index = 0
    for _ in range(MAX_ROUNDS):
        for per_replicate, vertices in groups:
            if not len(vertices):
                continue
            mean, variance = _blocked_round(caster, origins[vertices], frames[vertices], keys[vertices],
                                            round_index, per_replicate, settings)
            rounds.append((vertices, replicates * per_replicate, mean, variance))
            rays[vertices] += replicates * per_replicate
            round_index += 1
            yield int(len(vertices) * replicates * per_replicate)
        if settings.target_error <= 0.0:
            break
        _, error = _combine(rounds, rays, count, order)
        groups = _next_rounds(error, rays, settings)
        if not groups:
            break
    blocked, error = _combine(rounds, rays, count, order)
    return ChunkResult(unshadowed - blocked, error, rays, skipped)


def _next_rounds(error, rays, settings: BakeSettings):
    """(points per replicate, vertices) for vertices still above the target: each gets one round sized so that
    its predicted combined error meets the target (error ∝ rays^-0.85, measured for this estimator), from a
    √2-spaced ladder of lattice sizes, capped by the ray budget. Doubling instead overshot by about 1.5×."""
    target = settings.target_error * unshadowed_norm(settings.order) / TARGET_MARGIN
    budget = settings.max_samples - rays
    missing = np.flatnonzero((error > target) & (budget >= settings.replicates))
    if not len(missing):
        return []
    base = settings.points_per_replicate
    ladder = np.unique(np.round(base * 2.0 ** (np.arange(1, 2 * 20) / 2)).astype(np.int64))
    now_rays, now_error = rays[missing][:, None], error[missing][:, None]
    new_rays = settings.replicates * ladder[None, :]
    new_error = now_error * (now_rays / new_rays) ** CONVERGENCE_RATE
    predicted = np.sqrt((now_rays * now_error) ** 2 + (new_rays * new_error) ** 2) / (now_rays + new_rays)
    fits = (predicted <= target) | (new_rays >= budget[missing][:, None])
    choice = np.minimum(np.argmax(fits, axis=1), np.searchsorted(ladder, budget[missing] // settings.replicates,
                                                                 side="right") - 1)
    valid = choice >= 0
    sizes = ladder[np.maximum(choice, 0)]
    return [(int(size), missing[valid & (sizes == size)]) for size in np.unique(sizes[valid])]


def _combine(rounds, rays, count, order):
    """Weights rounds by their share of each vertex's rays: unbiased, optimal at the Monte Carlo rate."""
    blocked = np.zeros((count, order * order))
    variance = np.zeros((count, order * order))
    for vertices, round_rays, mean, var in rounds:
        weight = (round_rays / rays[vertices])[:, None]
        blocked[vertices] += weight * mean
        variance[vertices] += weight * weight * var
    return blocked, np.sqrt(variance.sum(1))


def _blocked_round(caster, origins, frames, keys, round_index, per_replicate, settings):
    """One round: R replicates of a shifted lattice per vertex; mean and variance of (1/π)∫(1−V)cos·Y."""
    replicates, order = settings.replicates, settings.order
    c, rays = len(keys), replicates * per_replicate
    stream = keys[:, None] * STREAMS_PER_VERTEX + round_index * replicates + np.arange(replicates)[None, :]
    shifts = sampling.hash_uniform(settings.seed, stream.reshape(-1), 2).reshape(c, replicates, 2)
    local = sampling.square_to_cosine_hemisphere(
        sampling.cranley_patterson(sampling.fibonacci_lattice(per_replicate), shifts))  # (c, R, k, 3)
    world = local.reshape(c, rays, 3) @ frames  # rows of each frame: tangent, bitangent, normal
    blocked_rays = np.flatnonzero(caster.occluded(origins, world))
    sums = np.zeros((c * replicates, order * order))
    if len(blocked_rays):
        # Blocked rays arrive sorted, so each (vertex, replicate) is one contiguous segment to sum.
        replicate_of_ray = blocked_rays // per_replicate
        starts = np.flatnonzero(np.diff(replicate_of_ray, prepend=-1))
        basis = sh.evaluate(order, world.reshape(-1, 3)[blocked_rays])
        sums[replicate_of_ray[starts]] = np.add.reduceat(basis, starts, axis=0)
    per_replicate_blocked = sums.reshape(c, replicates, order * order) / per_replicate
    return per_replicate_blocked.mean(1), per_replicate_blocked.var(1, ddof=1) / replicates


def vertex_keys(receiver: Receiver, start: int, stop: int) -> np.ndarray:
    """Per-vertex random stream ids: 20 bits of the object's key above 30 bits of vertex index."""
    return (np.int64(receiver.key & 0xFFFFF) << np.int64(30)) + np.arange(start, stop, dtype=np.int64)


def chunk_ranges(vertex_counts: list[int]) -> list[tuple[int, int, int]]:
    """(receiver index, start, stop) for fixed-size chunks over every receiver."""
    return [(index, start, min(start + CHUNK_VERTICES, count))
            for index, count in enumerate(vertex_counts)
            for start in range(0, count, CHUNK_VERTICES)]


def bake_chunk(caster, receiver: Receiver, start: int, stop: int, settings: BakeSettings):
    """Generator over one chunk in either mode; yields rays cast, returns a ChunkResult."""
    normals = receiver.normals[start:stop]
    if settings.mode == "unshadowed" or caster is None:
        count = stop - start
        return ChunkResult(unshadowed_transfer(settings.order, normals), np.zeros(count),
                           np.zeros(count, dtype=np.int64), np.zeros(count, dtype=bool))
    keys = vertex_keys(receiver, start, stop)
    inward = np.zeros_like(normals) if receiver.inward is None else receiver.inward[start:stop]
    return (yield from shadowed_chunk(caster, receiver.positions[start:stop], normals, inward, keys, settings))
