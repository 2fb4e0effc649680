"""A bake's own error against its run time: after each round of rays (and after the bounces or texel lattices that
follow them), the seconds the bake would have taken had it stopped there, the rays cast and the estimated RMS
relative error, so a user sees what more time buys.

Chunks bake in parallel, each its own rounds (core.estimator), so the bake's curve is built from every chunk's: a
chunk keeps, after each of its rounds, its busy seconds, its rays and the sum of its points' squared standard errors
(CHUNK_COLUMNS). The bake after round r is every chunk after round r (or its last, if it stopped sooner); its seconds
are the rays' wall time in the share of all chunks' busy seconds spent by then, as the processes baked them side by
side. The rows are additive (seconds, rays, squared errors and points sum), so the bakes of several parts, run one
after another, add up to one curve."""

from dataclasses import dataclass, field

import numpy as np

CHUNK_COLUMNS = ("seconds", "rays", "squared")  # a chunk's row after each round: cumulative, all of them
BOUNCES, TEXELS = "bounces", "texel lattices"   # what follows the rounds, in this order


@dataclass
class Row:
    after: str        # 'round 1', 'round 2', ... then BOUNCES, TEXELS
    seconds: float
    rays: int
    squared: float    # Σ over the points of the squared relative standard error
    points: int
    est_rms_rel_error: float = field(init=False)

    def __post_init__(self):
        self.est_rms_rel_error = float(np.sqrt(self.squared / self.points)) if self.points else 0.0


def chunk_row(seconds: float, rays: int, std_error: np.ndarray) -> tuple:
    """A chunk's row (CHUNK_COLUMNS) after a round, from its points' standard errors (absolute)."""
    return seconds, float(rays), float(np.square(std_error).sum())


def rounds(chunk_curves: list, points: int, scale: float, seconds_per_busy: float) -> list[Row]:
    """The rows after each round of the chunks whose curves ((r, 3) arrays of CHUNK_COLUMNS) are given, over
    `points` points, errors relative to `scale` (the unshadowed transfer's norm); a busy second of a chunk is
    `seconds_per_busy` of the bake's (the rays' wall time ÷ every chunk's busy seconds)."""
    summed = _summed(chunk_curves, max((len(curve) for curve in chunk_curves), default=0))
    return [Row(f"round {index + 1}", float(seconds * seconds_per_busy), int(rays), float(squared / scale ** 2),
                points) for index, (seconds, rays, squared) in enumerate(summed)]


def part(bake_rows: list[Row], chunk_curves: list, points: int, scale: float) -> list[Row]:
    """The rows after each round of the part of a bake that some of its chunks baked (an object's): its own rays and
    errors, at the bake's seconds."""
    bake_rounds = [row for row in bake_rows if row.after.startswith("round ")]
    summed = _summed(chunk_curves, len(bake_rounds))
    return [Row(row.after, row.seconds, int(rays), float(squared / scale ** 2), points)
            for row, (_, rays, squared) in zip(bake_rounds, summed)]


def then(rows: list[Row], after: str, seconds: float, rays: int, rel_error: np.ndarray) -> list[Row]:
    """The rows and one more: the bake after `after`, at `seconds` with `rays`, its points' relative errors."""
    return rows + [Row(after, seconds, int(rays), float(np.square(rel_error).sum()), len(rel_error))]


def added(curves: list[list[Row]]) -> list[Row]:
    """One curve of bakes run one after another: at each step, each bake as it was at its last row up to that
    step (its final row once it has none further)."""
    steps = sorted({row.after for curve in curves for row in curve}, key=_step_order)
    out = []
    for step in steps:
        reached = [_at(curve, step) for curve in curves if curve]
        out.append(Row(step, sum(row.seconds for row in reached), sum(row.rays for row in reached),
                       sum(row.squared for row in reached), sum(row.points for row in reached)))
    return out


def line(rows: list[Row]) -> str:
    """The curve in one log line: 'error against time: round 1 2.1 s 1.2 M rays RMS 0.0131 | ...'."""
    return "error against time: " + " | ".join(
        f"{row.after} {row.seconds:.1f} s {row.rays / 1e6:.2f} M rays RMS {row.est_rms_rel_error:.4f}"
        for row in rows)


def _summed(chunk_curves: list, length: int) -> np.ndarray:
    """(length, 3) the chunks' rows summed, a chunk that stopped sooner counted at its last row."""
    if not chunk_curves or length == 0:
        return np.zeros((0, len(CHUNK_COLUMNS)))
    return sum(np.vstack([curve[:length], np.repeat(curve[-1:], max(0, length - len(curve)), axis=0)])
               for curve in chunk_curves)


def _step_order(after: str) -> tuple:
    if after.startswith("round "):
        return 0, int(after.split()[1])
    return 1, (BOUNCES, TEXELS).index(after)


def _at(curve: list[Row], step: str) -> Row:
    reached = [row for row in curve if _step_order(row.after) <= _step_order(step)]
    return reached[-1] if reached else Row(step, 0.0, 0, 0.0, 0)
