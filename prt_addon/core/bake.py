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
import math
import zlib

import numpy as np

from . import lobes, sampling, sh

MODES = ("unshadowed", "shadowed")
MAX_ORDER = 10
MIN_SAMPLES = 8
MAX_SAMPLES = 1 << 20
MAX_REPLICATES = 32
# Random streams per vertex (rounds × replicates): doubling from 8 to MAX_SAMPLES takes under 18 rounds.
STREAMS_PER_VERTEX = 1024
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
    replicates: int = 8
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
        cast = self.tree.ray_cast
        distance = self.max_distance
        count = directions.shape[0] * directions.shape[1]
        hits = ((cast(o, d, distance)[3] or -1.0)
                for o, ds in zip(origins.tolist(), directions.tolist()) for d in ds)
        hit_distance = np.fromiter(hits, dtype=np.float64, count=count).reshape(directions.shape[:2])
        touching = np.nonzero((hit_distance >= 0.0) & (hit_distance < self.offset))
        if len(touching[0]):
            beyond = origins[touching[0]] + 2.0 * self.offset * directions[touching]
            hit_distance[touching] = [cast(o, d, distance)[3] or -1.0
                                      for o, d in zip(beyond.tolist(), directions[touching].tolist())]
        return hit_distance >= 0.0


def shadowed_chunk(caster: RayCaster, positions, normals, inward, keys, settings: BakeSettings):
    """Generator: bakes one chunk, yielding the rays cast after each round; returns a ChunkResult."""
    order, replicates = settings.order, settings.replicates
    positions = positions - caster.center
    count = len(positions)
    unshadowed = unshadowed_transfer(order, normals)
    has_surface = np.abs(normals).sum(-1) > 0
    skipped = has_surface & provably_unoccluded(positions, normals, caster.hull, caster.offset)
    blocked_sum = np.zeros((count, order * order))   # Σ over rounds of weight · blocked estimate
    variance_sum = np.zeros((count, order * order))  # Σ over rounds of weight² · variance of that estimate
    rays = np.zeros(count, dtype=np.int64)
    active = np.flatnonzero(has_surface & ~skipped)
    tangents, bitangents = sampling.orthonormal_basis(np.where(has_surface[:, None], normals, [0.0, 0.0, 1.0]))
    origins = positions + caster.offset * (normals + inward)
    round_index, per_replicate = 0, settings.points_per_replicate
    rounds = []  # (vertices, rays per vertex, blocked mean, blocked variance) per round, combined below
    while len(active):
        blocked_mean, blocked_var = _blocked_round(
            caster, origins[active], normals[active], tangents[active], bitangents[active],
            keys[active], round_index, per_replicate, settings)
        rounds.append((active, replicates * per_replicate, blocked_mean, blocked_var))
        rays[active] += replicates * per_replicate
        yield int(len(active) * replicates * per_replicate)
        if settings.target_error <= 0.0:
            break
        blocked, error = _combine(rounds, rays, count, order)
        done = error[active] <= settings.target_error * unshadowed_norm(order)
        within_budget = rays[active] + 2 * replicates * per_replicate <= settings.max_samples
        active = active[~done & within_budget]
        round_index += 1
        per_replicate *= 2
    blocked, error = _combine(rounds, rays, count, order)
    return ChunkResult(unshadowed - blocked, error, rays, skipped)


def _combine(rounds, rays, count, order):
    """Weights rounds by their share of each vertex's rays: unbiased, optimal at the Monte Carlo rate."""
    blocked = np.zeros((count, order * order))
    variance = np.zeros((count, order * order))
    for vertices, round_rays, mean, var in rounds:
        weight = (round_rays / rays[vertices])[:, None]
        blocked[vertices] += weight * mean
        variance[vertices] += weight * weight * var
    return blocked, np.sqrt(variance.sum(1))


def _blocked_round(caster, origins, normals, tangents, bitangents, keys, round_index, per_replicate, settings):
    """One round: R replicates of a shifted lattice per vertex; mean and variance of (1/π)∫(1−V)cos·Y."""
    replicates, order = settings.replicates, settings.order
    stream = keys[:, None] * STREAMS_PER_VERTEX + round_index * replicates + np.arange(replicates)[None, :]
    shifts = sampling.hash_uniform(settings.seed, stream.reshape(-1), 2).reshape(len(keys), replicates, 2)
    local = sampling.square_to_cosine_hemisphere(
        sampling.cranley_patterson(sampling.fibonacci_lattice(per_replicate), shifts))  # (c, R, k, 3)
    world = (local[..., 0:1] * tangents[:, None, None, :] + local[..., 1:2] * bitangents[:, None, None, :]
             + local[..., 2:3] * normals[:, None, None, :])
    c = len(keys)
    occluded = caster.occluded(origins, world.reshape(c, replicates * per_replicate, 3))
    occluded = occluded.reshape(c, replicates, per_replicate)
    per_replicate_blocked = np.zeros((c, replicates, order * order))
    where = np.nonzero(occluded)
    if len(where[0]):
        basis = sh.evaluate(order, world[where])
        np.add.at(per_replicate_blocked, (where[0], where[1]), basis)
    per_replicate_blocked /= per_replicate
    mean = per_replicate_blocked.mean(1)
    variance = per_replicate_blocked.var(1, ddof=1) / replicates
    return mean, variance


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
