"""Interreflected transfer: bounces gathered over the shadow pass's own ray hits, no new rays.

Radiance leaving a vertex is ρ_p Σ_k L_k T_k(p). Light that a blocked ray would have brought from the sky is
replaced by what the surface it hit sends back, so with T₀ the shadowed (direct) transfer:

    T_{b+1}(p) = (1/π) ∫ (1 − V) cos · ρ(q) T_b(q) dω ≈ Σ_rays w · Σ_i β_i ρ(v_i) T_b(v_i),

the same cosine-distributed rays as T₀ (w = 1 / rays of p), q the hit point with barycentric weights β on the
hit triangle's vertices v_i. The bounce operator G (rows: vertices, columns: hit vertices) has row sums ≤ 1
(the blocked fraction), so with ρ < 1 the series converges and noise cannot be amplified.
"""

from dataclasses import dataclass, field
import time

import numpy as np

# Albedo this close to 1 makes the series converge arbitrarily slowly; it is clamped (and the report says so).
MAX_ALBEDO = 0.999
MAX_BOUNCES = 10_000
ROWS_PER_BLOCK = 32  # BounceOperator; the demo's Final bake fills 28 % of its blocks' rectangles
MIN_DENSITY = 1 / 8


@dataclass
class HitRecords:
    """Blocked rays that hit a solved surface: which vertex cast them and where they landed."""
    vertex: np.ndarray       # (H,) int64 index of the casting vertex
    triangle: np.ndarray     # (H,) int64 index of the hit triangle
    barycentric: np.ndarray  # (H, 3) float64 weights of the triangle's corners at the hit point
    weight: np.ndarray       # (H,) float64 the ray's weight in its vertex's estimate
    replicate: np.ndarray    # (H,) int64 the replicate the ray belongs to (core.estimator: independent lattice shifts)

    FIELDS = ("vertex", "triangle", "barycentric", "weight", "replicate")

    @staticmethod
    def empty():
        return HitRecords(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0),
                          np.zeros(0, np.int64))

    @staticmethod
    def concatenate(parts):
        parts = [p for p in parts if len(p.vertex)] or [HitRecords.empty()]
        return HitRecords(*(np.concatenate([getattr(p, name) for p in parts]) for name in HitRecords.FIELDS))

    def where(self, mask: np.ndarray) -> "HitRecords":
        return HitRecords(*(getattr(self, name)[mask] for name in HitRecords.FIELDS))

    def of_replicate(self, replicate: int, replicates: int) -> "HitRecords":
        """The records of one replicate's rays, weighted as that replicate's estimate alone weighs them (each
        replicate holds 1/R of every vertex's rays)."""
        mine = self.where(self.replicate == replicate)
        mine.weight = mine.weight * replicates
        return mine


class BounceOperator:
    """G, ROWS_PER_BLOCK rows to a block. A bounce applies G to (V, C·n²) values, so every entry is a product with a
    row of C·n² values: a block is held as the dense rectangle of its rows by the columns they touch (one BLAS
    product per application, on the gathered rows of those columns) where its entries fill at least MIN_DENSITY of
    that rectangle, else as its entries (one gather, one product and one sum per application), which bounds the
    memory at 1 / MIN_DENSITY times the entries'. rows, columns: sorted by row then column, no duplicates."""

    def __init__(self, rows: np.ndarray, columns: np.ndarray, values: np.ndarray, size: int):
        self.size = size
        self.dense = []   # (first row, end row, the columns touched, (rows, columns touched) matrix)
        self.sparse = []  # (rows with entries, their entries' columns, values, where each row's entries start)
        firsts = np.append(np.arange(0, size, ROWS_PER_BLOCK), size)
        bounds = np.searchsorted(rows, firsts)
        for first, end, lo, hi in zip(firsts[:-1], firsts[1:], bounds[:-1], bounds[1:]):
            if lo == hi:
                continue
            touched, local = np.unique(columns[lo:hi], return_inverse=True)
            if hi - lo >= MIN_DENSITY * (end - first) * len(touched):
                matrix = np.zeros((end - first, len(touched)))
                matrix[rows[lo:hi] - first, local] = values[lo:hi]
                self.dense.append((first, end, touched, matrix))
            else:
                starts = np.flatnonzero(np.diff(rows[lo:hi], prepend=-1))
                self.sparse.append((rows[lo:hi][starts], columns[lo:hi], values[lo:hi, None], starts))

    def apply(self, values: np.ndarray) -> np.ndarray:
        """G @ values for values (V, ...)."""
        flat = values.reshape(self.size, -1)
        out = np.zeros_like(flat)
        for first, end, touched, matrix in self.dense:
            out[first:end] = matrix @ flat[touched]
        for present, columns, weights, starts in self.sparse:
            out[present] = np.add.reduceat(flat[columns] * weights, starts, axis=0)
        return out.reshape(values.shape)


def bounce_operator(records: HitRecords, triangles: np.ndarray, size: int) -> BounceOperator:
    """G from the hit records; hits on triangles with a corner outside the solved vertices are dropped."""
    corners = triangles[records.triangle]                       # (H, 3) vertex indices
    rows = np.repeat(records.vertex, 3)
    columns = corners.ravel()
    values = (records.weight[:, None] * records.barycentric).ravel()
    inside = columns < size
    rows, columns, values = rows[inside], columns[inside], values[inside]
    key = rows * size + columns                                  # sum duplicates once, not every bounce
    unique, inverse = np.unique(key, return_inverse=True)
    return BounceOperator(unique // size, unique % size, np.bincount(inverse, values), size)


@dataclass
class BounceReport:
    bounces: int = 0
    relative_changes: list = field(default_factory=list)  # ‖T_b‖ / ‖T₀ + … + T_b‖ per bounce
    tail: float = 0.0          # the geometric tail added after the last bounce, relative to the total (auto)
    converged: bool = True     # False when auto bounces stopped at MAX_BOUNCES with the tail still uncertain
    albedo_clamped: bool = False
    time_s: float = 0.0


def interreflect(direct, albedo, operator: BounceOperator, bounces=None, tolerance=1e-3):
    """T₀ + T₁ + … with T_{b+1} = G (ρ ⊙ T_b). direct (V, n²) or (V, C, n²); albedo (V, C).

    bounces: a count, or None for 'auto': late bounces shrink by a steady ratio r (the spectral radius of ρG),
    so the rest of the series is T_b·r/(1−r) once T_b is (nearly) an eigenvector. Iterate until the error of
    that tail, bounded by ‖T_b − r·T_{b−1}‖ / (1−r)², is below `tolerance` of the total, then add the tail.
    Stopping on the last bounce's size instead would leave a 10 % tail at ρ = 0.99, or take ~900 bounces to make it small.
    Returns the total (V, C, n²) and a BounceReport."""
    start = time.perf_counter()
    report = BounceReport()
    report.albedo_clamped = bool((albedo > MAX_ALBEDO).any())
    albedo = np.clip(albedo, 0.0, MAX_ALBEDO)
    channels = albedo.shape[1]
    current = direct[:, None, :] if direct.ndim == 2 else direct
    current = np.broadcast_to(current, (len(albedo), channels, current.shape[-1])).astype(np.float64)
    total = current.copy()
    limit = MAX_BOUNCES if bounces is None else int(bounces)
    report.converged = bounces is not None  # a fixed count is what was asked for
    while report.bounces < limit and np.any(current):
        previous, current = current, operator.apply(albedo[:, :, None] * current)
        total += current
        report.bounces += 1
        size = float(np.linalg.norm(current))
        report.relative_changes.append(size / max(float(np.linalg.norm(total)), 1e-300))
        ratio = size / float(np.linalg.norm(previous))
        if bounces is None and ratio < 1.0:
            uncertainty = float(np.linalg.norm(current - ratio * previous)) / (1.0 - ratio) ** 2
            if uncertainty < tolerance * np.linalg.norm(total):
                tail = ratio / (1.0 - ratio)
                total += current * tail
                report.tail = float(size * tail / np.linalg.norm(total))
                report.converged = True
                break
    else:
        report.converged = report.converged or not np.any(current)  # the series ended: nothing is left out
    report.time_s = time.perf_counter() - start
    return total, report


def gather_std_error(records: HitRecords, triangles, direct, albedo, replicates: int, bounces=None,
                     tolerance=1e-3) -> np.ndarray:
    """(V,) the standard error the bounces add: the interreflected total recomputed from each replicate's hit
    records alone, and the spread of those R totals ÷ √R, as the direct transfer's replicates give its error.
    Per vertex, the norm over coefficients, as RMS over colour channels."""
    totals = np.stack([interreflect(direct, albedo, bounce_operator(records.of_replicate(replicate, replicates),
                                                                    triangles, len(albedo)), bounces, tolerance)[0]
                       for replicate in range(replicates)])
    variance = totals.var(axis=0, ddof=1) / replicates  # (V, C, n²)
    return np.sqrt(variance.sum(-1).mean(-1))
