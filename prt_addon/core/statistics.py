"""Error statistics in numpy: the RMS, PRT's colours against Cycles' passes with Cycles' own noise taken out (in
the RMS, per vertex, in the 99th percentile and in the worst vertices), and the share of a light that Cycles cannot
emit."""

from dataclasses import dataclass, field
import math

import numpy as np

from . import lobes


def rms(values: np.ndarray) -> float:
    """Root mean square; 0 for no values."""
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else 0.0


PERCENTILE = 99.0  # the tail figure reported beside the RMS and the max
WORST_VERTICES = 5  # how many of the worst object's vertices the report lists


def percentile(values: np.ndarray, q: float = PERCENTILE) -> float:
    """numpy's percentile, linear between the sorted values (0 for no values)."""
    return float(np.percentile(values, q)) if len(values) else 0.0


def denoised_errors(difference: np.ndarray, noise_variance: np.ndarray) -> np.ndarray:
    """Per vertex, PRT's own error: sqrt(max(d² − σ², 0)) for the measured difference d = ‖PRT − Cycles‖ and the
    variance σ² of Cycles' noise at that vertex (of the mean of its passes, summed over RGB).

    Why this: PRT's error and Cycles' noise are independent, so E[d²] = e² + σ² at every vertex, and d² − σ² is
    an unbiased estimate of e² there; its mean over vertices (before the clamp) is exactly the RMS's
    measured² − noise², so the per-vertex figures and the RMS take the noise out the same way. A percentile does
    not split in quadrature the way a mean square does, so it cannot be taken out of p99(d) afterwards.

    What it cannot do: it removes the noise's expected square, not the noise drawn at a vertex, so the tail keeps
    part of Cycles' noise. Where PRT is exact, Gaussian noise and 4 passes leave a p99 of 1.7 × Cycles' noise RMS
    (RGB noise independent) to 2.4 × (grey light: one draw scaled per channel), against 1.9-2.6 × for d itself
    (tests/core/test_statistics.py computes both in closed form). A p99 is firm only well above twice
    Cycles' noise RMS; the worst vertices are ranked by it too, so where PRT's errors stand below that floor the
    ranking picks noise."""
    return np.sqrt(np.maximum(np.square(difference) - noise_variance, 0.0))


def worst_vertices(errors: np.ndarray, k: int = WORST_VERTICES) -> list[tuple[int, float]]:
    """The k largest errors as (index, error), largest first; equal errors in index order."""
    order = np.argsort(-np.asarray(errors), kind="stable")[:k]
    return [(int(i), float(errors[i])) for i in order]


@dataclass
class Comparison:
    """PRT's colours against the mean of Cycles' passes. Every value is relative to the RMS over vertices of
    ‖Cycles‖ (RGB norms), so dark vertices do not divide by zero."""
    name: str
    vertices: int
    measured: float        # RMS over vertices of ‖PRT − Cycles‖
    cycles_noise: float    # RMS of the noise of Cycles' mean, from the spread of its passes
    max_difference: float  # largest ‖PRT − Cycles‖, Cycles' noise included
    p99: float             # 99th percentile of the per-vertex error, Cycles' noise taken out (denoised_errors)
    measured_p99: float    # 99th percentile of ‖PRT − Cycles‖, Cycles' noise included
    worst: list            # worst_vertices of the per-vertex error, Cycles' noise taken out: (index, error)
    errors: np.ndarray = field(repr=False, compare=False)  # the per-vertex error itself (V,): the heatmap shows it

    @property
    def error(self) -> float:
        """PRT's own RMS error: the measured difference with Cycles' independent noise taken out."""
        return math.sqrt(max(self.measured ** 2 - self.cycles_noise ** 2, 0.0))

    def text(self) -> str:
        return (f"error {100 * self.error:.2f} % RMS (measured {100 * self.measured:.2f} %, "
                f"Cycles noise {100 * self.cycles_noise:.2f} %), p99 {100 * self.p99:.1f} %, "
                f"max {100 * self.max_difference:.1f} %")

    def as_dict(self) -> dict:
        return {"vertices": self.vertices, "rel_rms_error": self.error, "measured_rel_rms": self.measured,
                "cycles_noise_rel_rms": self.cycles_noise, "rel_p99_error": self.p99,
                "measured_rel_p99": self.measured_p99, "rel_max_difference": self.max_difference}


def compare(name: str, prt: np.ndarray, passes: np.ndarray, k: int = WORST_VERTICES) -> Comparison:
    """prt (V, 3) against Cycles' passes (k ≥ 2, V, 3): equal samples, different seeds."""
    cycles = passes.mean(axis=0)
    scale = rms(np.linalg.norm(cycles, axis=1)) or 1.0
    difference = np.linalg.norm(prt - cycles, axis=1)
    noise = np.sum(passes.var(axis=0, ddof=1), axis=1) / len(passes)  # per vertex, variance of the mean
    errors = denoised_errors(difference, noise) / scale
    return Comparison(name, len(prt), rms(difference) / scale, float(np.sqrt(np.mean(noise))) / scale,
                      float(difference.max(initial=0.0)) / scale, percentile(errors),
                      percentile(difference) / scale, worst_vertices(errors, k), errors)


def worst_object(comparisons: list) -> Comparison:
    """The comparison with the largest p99 (the first of equals). The p99 rather than the RMS: what an artist
    must find is a local fault (a seam, a leak, a missed shadow), which a few vertices show and the RMS of a
    large object dilutes, while an error spread evenly raises the p99 as well."""
    return max(comparisons, key=lambda comparison: comparison.p99)


def clamped_fraction(pixels: np.ndarray) -> float:
    """The share of the light's magnitude (∫ |L| dω over the channels) in negative lobes, which Cycles cannot
    emit; pixels is an equirect image (H, W, channels)."""
    solid_angles = lobes.equirect_solid_angles(*pixels.shape[:2])[..., None]
    magnitude = float((np.abs(pixels) * solid_angles).sum())
    return float((np.maximum(-pixels, 0.0) * solid_angles).sum()) / magnitude if magnitude > 0 else 0.0
