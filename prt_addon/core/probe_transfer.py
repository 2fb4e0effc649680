"""PRT probes: at a point in space, the transfer matrix T (N² × n²) that maps the distant SH light L of order n to
the SH, to order N, of the radiance arriving at that point, so that the static scene's shadows (and its bounced
light) reach objects that move through it, relit with the SH lights like every baked surface (core.probe_grid
interpolates them).

    T_ij = ∫ y_i(ω) V(ω) y_j(ω) dω  +  ∫ y_i(ω) (1 − V(ω)) E_j(q(ω)) dω,   i < N², j < n²

The arriving light is kept to a higher order than the distant light (received_order): an object lit from it is
shaded by the product of two truncated series, its own transfer's and the arriving light's, and that product loses
whatever both hold above the order they were cut at; the shadows of nearby objects put much of the arriving light
there.

V(ω) = 1 where the ray from the probe along ω escapes; q(ω) is the point it hits, and E(q) the exitant transfer of
the surface there: the radiance leaving q towards the probe is Σ_j E_j(q) L_j, E = ρ·T_total of the bake's solved
vertices (core.interreflect), interpolated with the hit's barycentric weights. Without E (a shadowed bake, whose
surfaces reflect nothing), T is the direct part alone. Hits on a triangle's back face, or on a triangle with a
corner outside the solved vertices, bring no light: the bake knows only the front side of the surfaces it solved.

Rays are uniform on the sphere: R replicates of one Fibonacci lattice (z = 1 − 2u, φ = 2πv), each shifted by its own
hashed Cranley-Patterson offset (core.sampling), so each replicate's T is unbiased and their spread is the standard
error, as for a vertex's transfer.

Inside static geometry: a probe more than INSIDE_SHARE of whose rays first meet a back face is inside a closed
object (from inside, every face of a closed, outward-facing mesh is a back face; from outside, at most the open
surfaces' backs are seen, e.g. below a one-sided floor, where no moving object is lit either). Such probes are
marked `inside`, and the interpolation leaves them out, so light does not leak through walls.
"""

from dataclasses import dataclass
import time

import numpy as np

from . import sampling, sh
from .progress import Job, Progress

# More than this share of its rays meeting back faces puts a probe inside geometry. Inside a closed mesh every ray
# does (1.0); a probe in the open above a floor sees none; just below a one-sided plane, half.
INSIDE_SHARE = 0.25
PROBES_AT_ONCE = 32
# The arriving light's order above the distant light's. Suzanne in the demo's torus shadow under its order-4 light,
# per vertex against the exact integral of light × visibility × cosine: the product of the order-n series is 9.5 %
# RMS off, of order n+1 5.9 %, n+2 3.5 %, n+4 1.7 %; n+2 costs a dynamic object 36 coefficients a vertex, not 16.
RECEIVED_ORDERS_ABOVE = 2


def received_order(order: int) -> int:
    """The SH order to which the probes keep the light arriving under a distant light of `order`, and to which a
    dynamic object, lit from them, bakes its own transfer."""
    return order + RECEIVED_ORDERS_ABOVE  # probes whose rays, SH values and hit transfers are held at once


@dataclass
class ProbeTransfer:
    """Each probe's transfer matrix (P, C, N², n²) (C = 1, or 3 where the exitant transfer is coloured), the
    Frobenius norm of its standard error (P,) (its own rays' noise: the exitant transfer's own error is not in it),
    the share of its rays that met a back face (P,) and whether that puts it inside geometry (P,)."""
    matrices: np.ndarray
    std_error: np.ndarray
    back_share: np.ndarray
    inside: np.ndarray
    rays: int


def sphere_directions(count: int, shifts: np.ndarray) -> np.ndarray:
    """(..., count, 3) unit directions, uniform on the sphere: a Fibonacci lattice of `count` points under each
    Cranley-Patterson shift (..., 2)."""
    points = sampling.cranley_patterson(sampling.fibonacci_lattice(count), shifts)
    z = 1.0 - 2.0 * points[..., 0]
    radius = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    azimuth = 2.0 * np.pi * points[..., 1]
    return np.stack([radius * np.cos(azimuth), radius * np.sin(azimuth), z], axis=-1)


class ProbeJob(Job):
    """The transfer at each of `positions` (P, 3) in world space, through `caster` (core.ray_caster.RayCaster) with
    `samples` rays per probe (rounded down to a multiple of `replicates`), PROBES_AT_ONCE probes a step, mapping a
    distant light of `order` to the arriving light to received_order(order) (N² × n² matrices). `exitant`
    (S, C, n²): the exitant transfer of the caster's first S vertices (the bake's solved ones), or None for the
    direct part alone. `keys` (P,): each probe's random stream (core.scheduling.stream_keys), by default its index.
    Its outcome is a ProbeTransfer."""

    def __init__(self, caster, positions, order: int, samples: int, replicates: int = 4, seed: int = 0,
                 exitant=None, keys=None):
        self.caster, self.order, self.replicates, self.seed, self.exitant = caster, order, replicates, seed, exitant
        self.positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        self.keys = np.arange(len(self.positions)) if keys is None else np.asarray(keys, dtype=np.int64)
        self.per_replicate = max(1, samples // replicates)
        self.rays = self.per_replicate * replicates
        channels = 1 if exitant is None else exitant.shape[1]
        self.matrices = np.zeros((len(self.positions), channels, received_order(order) ** 2, order * order))
        self.std_error, self.back_share = np.zeros(len(self.positions)), np.zeros(len(self.positions))
        self.normals = _face_normals(caster.vertices, caster.triangles)
        self.done = 0
        self.progress = Progress("PRT probes")

    def step(self, budget_s: float) -> bool:
        deadline = time.perf_counter() + budget_s
        while self.done < len(self.positions) and time.perf_counter() < deadline:
            rows = slice(self.done, self.done + PROBES_AT_ONCE)
            self.matrices[rows], self.std_error[rows], self.back_share[rows] = _chunk(
                self.caster, self.normals, self.positions[rows], self.keys[rows], self.order,
                self.per_replicate, self.replicates, self.seed, self.exitant)
            self.done = min(len(self.positions), self.done + PROBES_AT_ONCE)
        self.progress.fraction = self.done / max(1, len(self.positions))
        return self.done == len(self.positions)

    def outcome(self) -> ProbeTransfer:
        return ProbeTransfer(self.matrices, self.std_error, self.back_share, self.back_share > INSIDE_SHARE, self.rays)


def _chunk(caster, normals, positions, keys, order, per_replicate, replicates, seed, exitant):
    """(matrices (c, C, N², n²), std_error (c,), back_share (c,)) of a chunk of probes, keyed for their shifts."""
    c, rays = len(positions), per_replicate * replicates
    shifts = sampling.hash_uniform(seed, keys, 2 * replicates).reshape(c, replicates, 2)
    directions = sphere_directions(per_replicate, shifts).reshape(c, rays, 3)
    hits = caster.engine.hits(positions - caster.center, directions)
    found = hits.found
    triangle = np.where(found, hits.triangle, 0)
    back = found & (np.einsum("ckd,ckd->ck", directions, normals[triangle]) > 0.0)
    received, size = received_order(order) ** 2, order * order
    values = sh.evaluate(received_order(order), directions)  # (c, k, N²): the light's n² come first
    weight = 4.0 * np.pi / per_replicate
    replicate_of = np.repeat(np.arange(replicates), per_replicate)
    estimates = np.empty((c, replicates, 1 if exitant is None else exitant.shape[1], received, size))
    lit = values[..., :size] * (~found)[..., None]  # V(ω) y_j(ω)
    if exitant is not None:
        reflected = _reflected(caster, exitant, triangle, hits.barycentric, found & ~back)  # (c, k, C, n²)
    for replicate in range(replicates):
        mine = replicate_of == replicate
        # Batched products of (N², k) by (k, ·): the probes bake 2.5× faster than through einsum, and each product
        # is small enough for OpenBLAS to keep to one thread (core.arrays).
        rows = values[:, mine].transpose(0, 2, 1)
        estimates[:, replicate] = weight * np.matmul(rows, lit[:, mine])[:, None]
        if exitant is not None:
            gathered = np.matmul(rows, reflected[:, mine].reshape(c, -1, exitant.shape[1] * size))
            estimates[:, replicate] += weight * gathered.reshape(c, received, -1, size).transpose(0, 2, 1, 3)
    spread = estimates.var(axis=1, ddof=1) / replicates
    return estimates.mean(axis=1), np.sqrt(spread.sum(axis=(1, 2, 3))), back.mean(axis=1)


def _reflected(caster, exitant, triangle, barycentric, front):
    """(c, k, C, n²) the exitant transfer at each ray's hit point, zero where the ray met no front face of a
    triangle whose corners are all solved vertices."""
    if len(caster.triangles) == 0:
        return np.zeros(triangle.shape + exitant.shape[1:])
    corners = caster.triangles[triangle]  # (c, k, 3)
    front = front & (corners < len(exitant)).all(axis=-1)
    corners = np.where(front[..., None], corners, 0)
    weights = np.where(front[..., None], np.nan_to_num(barycentric), 0.0)
    return sum(weights[..., v, None, None] * exitant[corners[..., v]] for v in range(3))


def _face_normals(vertices, triangles) -> np.ndarray:
    """(T, 3) each triangle's normal by its corners' winding, unnormalised (only its side matters); one zero row
    for a caster without triangles, so that indexing a missed ray's triangle 0 stays valid."""
    if len(triangles) == 0:
        return np.zeros((1, 3))
    corners = vertices[np.asarray(triangles, dtype=np.int64)]
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
