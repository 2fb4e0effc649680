"""Interreflected transfer at texels: one gather from the solution the vertices found.

Every visible mesh's vertices solve the bounces as in a vertex bake (core.interreflect); each texel then casts its
own rays (the shadowed estimate, its blocked rays' hits recorded) and adds the light the surfaces it sees send back:

    T(p) = T₀(p) + Σ_rays w · Σ_i β_i ρ(v_i) T(v_i),

T(v) the vertices' converged total, v_i the corners of the hit triangle. The texel's own shadows and direct light
are resolved per texel; the bounced light it gathers is resolved per vertex of the surfaces it sees (bounced light
is smooth, which is why this is the classic final gather). Gathering per texel of those surfaces, through the
hit's lightmap UV, would need the texels of every texel object as the bounce's unknowns: not built.

The gather's own noise (it sums over the texel's Monte Carlo rays) joins the texel's estimate as the vertex bake's
bounce noise does: the gather repeated from each replicate's hit records alone, their spread ÷ √R.
"""

import numpy as np

from . import interreflect, lobes
from .progress import Job


class GatheringJob(Job):
    """A TransferJob over texel receivers without albedo (its rays record their hits, it bounces nothing), then the
    gather from the solved vertices' total transfer `solved` (S, C, n²) with their albedo (S, C)."""

    def __init__(self, inner, solved: np.ndarray, albedo: np.ndarray):
        self.inner = inner
        self.solved = solved
        self.albedo = albedo

    @property
    def progress(self):
        return self.inner.progress

    def step(self, budget_s: float) -> bool:
        return self.inner.step(budget_s)

    def cancel(self):
        self.inner.cancel()

    def results(self) -> list:
        """The inner job's results with the gathered light added: grey transfer stays (N, n²) when the albedo is
        grey, else becomes (N, C, n²)."""
        results = self.inner.results()
        rows, triangles = self.inner.total_vertices, self.inner.occluders.triangles
        records = interreflect.HitRecords.concatenate(self.inner.records)
        gathered = gather(records, triangles, self.solved, self.albedo, rows)
        replicates = self.inner.settings.replicates
        spread = np.stack([gather(records.of_replicate(replicate, replicates), triangles, self.solved, self.albedo,
                                  rows) for replicate in range(replicates)])
        noise = np.sqrt((spread.var(axis=0, ddof=1) / replicates).sum(-1).mean(-1))  # (rows,) as interreflect's
        scale = lobes.unshadowed_norm(self.inner.settings.order)
        offsets = np.cumsum([0] + [len(result.transfer) for result in results])
        for result, start, end in zip(results, offsets[:-1], offsets[1:]):
            part = gathered[start:end]
            direct = result.transfer if result.transfer.ndim == 3 else result.transfer[:, None, :]
            total = direct + part
            result.transfer = (total[:, 0] if total.shape[1] == 1 else total).astype(np.float32)
            result.std_error = np.hypot(result.std_error, noise[start:end])
            result.rel_error = result.std_error / scale
        return results

    def outcome(self) -> list:
        return self.results()


def gather(records: interreflect.HitRecords, triangles, solved, albedo, rows: int) -> np.ndarray:
    """(rows, C, n²): Σ over each row's recorded hits of weight · Σ_i β_i ρ(v_i) T(v_i); hits on triangles with a
    corner beyond the solved vertices (instances, which nothing solves) bring nothing, as in the bounces."""
    count = len(albedo)
    solved = solved if solved.ndim == 3 else solved[:, None, :]
    source = np.clip(albedo, 0.0, interreflect.MAX_ALBEDO)[:, :, None] * solved  # (S, C, n²)
    corners = triangles[records.triangle]
    keep = (corners < count).all(axis=1)
    size = max(rows, count)
    operator = interreflect.bounce_operator(records.where(keep), triangles, size)
    padded = np.zeros((size,) + source.shape[1:])
    padded[:count] = source
    return operator.apply(padded)[:rows]
