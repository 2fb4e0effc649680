"""Error statistics in numpy: the RMS, PRT's colours against Cycles' passes with Cycles' own noise taken out, and
the share of a light that Cycles cannot emit."""

from dataclasses import dataclass
import math

import numpy as np

from . import lobes


def rms(values: np.ndarray) -> float:
    """Root mean square; 0 for no values."""
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else 0.0


@dataclass
class Comparison:
    """PRT's colours against the mean of Cycles' passes. Every value is relative to the RMS over vertices of
    ‖Cycles‖ (RGB norms), so dark vertices do not divide by zero."""
    name: str
    vertices: int
    measured: float        # RMS over vertices of ‖PRT − Cycles‖
    cycles_noise: float    # RMS of the noise of Cycles' mean, from the spread of its passes
    max_difference: float  # largest ‖PRT − Cycles‖, Cycles' noise included

    @property
    def error(self) -> float:
        """PRT's own RMS error: the measured difference with Cycles' independent noise taken out."""
        return math.sqrt(max(self.measured ** 2 - self.cycles_noise ** 2, 0.0))

    def text(self) -> str:
        return (f"error {100 * self.error:.2f} % RMS (measured {100 * self.measured:.2f} %, "
                f"Cycles noise {100 * self.cycles_noise:.2f} %), max {100 * self.max_difference:.1f} %")

    def as_dict(self) -> dict:
        return {"vertices": self.vertices, "rel_rms_error": self.error, "measured_rel_rms": self.measured,
                "cycles_noise_rel_rms": self.cycles_noise, "rel_max_difference": self.max_difference}


def compare(name: str, prt: np.ndarray, passes: np.ndarray) -> Comparison:
    """prt (V, 3) against Cycles' passes (k ≥ 2, V, 3): equal samples, different seeds."""
    cycles = passes.mean(axis=0)
    scale = rms(np.linalg.norm(cycles, axis=1)) or 1.0
    difference = np.linalg.norm(prt - cycles, axis=1)
    noise = np.sum(passes.var(axis=0, ddof=1), axis=1) / len(passes)  # per vertex, variance of the mean
    return Comparison(name, len(prt), rms(difference) / scale, float(np.sqrt(np.mean(noise))) / scale,
                      float(difference.max(initial=0.0)) / scale)


def clamped_fraction(pixels: np.ndarray) -> float:
    """The share of the light's magnitude (∫ |L| dω over the channels) in negative lobes, which Cycles cannot
    emit; pixels is an equirect image (H, W, channels)."""
    solid_angles = lobes.equirect_solid_angles(*pixels.shape[:2])[..., None]
    magnitude = float((np.abs(pixels) * solid_angles).sum())
    return float((np.maximum(-pixels, 0.0) * solid_angles).sum()) / magnitude if magnitude > 0 else 0.0
