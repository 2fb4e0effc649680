"""Texel bakes that spend rays only where the transfer varies: the texels on a coarse lattice are baked first, then
each finer lattice's texels are interpolated from the coarser one where that is safe, and baked where it is not,
down to every texel.

A texel is interpolated (bilinearly, from the corners of the coarser lattice's cell it lies in) only when
- every corner is a covered texel whose value is known,
- the corners lie on one smooth piece of surface: the interpolated position is within a tenth of the cell's size of
  the texel's own and the interpolated normal within 10° of its own (no UV seam, gap or crease inside the cell),
- the transfer barely bends there: an eighth of the second differences at the corners (the error linear
  interpolation makes of a quadratic) is within half the target error (relative to the unshadowed transfer's
  norm) beyond twice the corners' Monte Carlo noise (one-sided differences at a border; where a corner has too
  few known neighbours, the corners' spread about the interpolated value stands in, which is stricter). So a shadow's edge or a wall's base,
  where the transfer bends, is baked texel by texel, while a smooth or linear stretch is interpolated. A feature
  lying wholly between two texels of the coarsest lattice (about 1/32 of the map) can be missed.
The estimate of an interpolated texel holds two parts, added in quadrature: noise, its corners' Monte Carlo noise
weighted as bilinear interpolation averages independent errors (√Σw²σ²), and bias, what interpolating may have
missed: the bound above plus its corners' own bias, weighted linearly (Σw·b), since the texels interpolated from one
coarser cell share its error rather than averaging it away. What interpolation may have missed is counted, not
hidden.
"""

from dataclasses import dataclass

import numpy as np

from . import bake, error_curve, lobes, rules
from .job import ReceiverResult
from .progress import Job, Progress

COARSEST_SAMPLES = 32  # the coarsest lattice has about this many texels across the largest map
AGREEMENT = 0.5         # of the target error: what interpolating a cell may err by
NOISE_ALLOWANCE = 2.0   # beyond this many standard errors of the corners' own noise
POSITION_TOLERANCE = 0.1  # of the cell's size: farther, the cell spans a seam or a gap
NORMAL_COSINE = np.cos(np.radians(10.0))
ROWS_AT_ONCE = 1 << 17  # texels interpolated at once: their corners' transfer is (rows, 4, n²) float64


@dataclass
class TexelGrid:
    """A texel receiver: every covered texel's point, and where it lies on the image."""
    receiver: bake.Receiver
    x: np.ndarray  # (N,) texel column
    y: np.ndarray  # (N,) texel row
    width: int
    height: int


class GridState:
    """What is known of one texel receiver so far: transfer, error, rays, and how each texel was found."""

    def __init__(self, grid: TexelGrid, order: int):
        count = len(grid.x)
        self.grid = grid
        self.index = np.full((grid.height, grid.width), -1, dtype=np.int64)
        self.index[grid.y, grid.x] = np.arange(count)
        self.transfer = np.zeros((count, order * order))
        self.std_error = np.zeros(count)
        self.noise = np.zeros(count)  # the independent part of std_error
        self.bias = np.zeros(count)   # the part interpolation shares with its neighbours
        self.rays = np.zeros(count, dtype=np.int64)
        self.skipped = np.zeros(count, dtype=bool)
        self.rules = rules.measured(count)  # of the texels baked; an interpolated one was measured by its neighbours
        self.rel_rule_error = np.zeros(count)
        self.known = np.zeros(count, dtype=bool)
        self.interpolated = np.zeros(count, dtype=bool)

    def lattice(self, stride: int) -> np.ndarray:
        """Rows of the texels on the lattice of this stride that are not known yet."""
        grid = self.grid
        return np.flatnonzero((grid.x % stride == 0) & (grid.y % stride == 0) & ~self.known)

    def subset(self, rows: np.ndarray, stride: int) -> bake.Receiver:
        """The receiver of these rows, with random streams of its own for this level."""
        receiver = self.grid.receiver
        return bake.Receiver(receiver.name, receiver.positions[rows], receiver.normals[rows],
                             bake.Receiver.key_for(f"{receiver.name} texels {stride}"),
                             None if receiver.inward is None else receiver.inward[rows])

    def store(self, rows, result):
        self.transfer[rows] = result.transfer
        self.std_error[rows] = self.noise[rows] = result.std_error
        self.bias[rows] = 0.0
        self.rays[rows] = result.rays
        self.skipped[rows] = result.skipped
        self.rules[rows] = result.rules
        self.rel_rule_error[rows] = result.rel_rule_error
        self.known[rows] = True

    def interpolate(self, rows: np.ndarray, stride: int, scale: float, target: float) -> np.ndarray:
        """Interpolates the rows (on the lattice of `stride`) that can be, from the lattice of 2·stride; returns the
        rows that must be baked. In batches, so memory stays bounded at any resolution: each row's choice reads the
        coarser lattice only, which no batch changes."""
        baked = [self._interpolate_batch(rows[start: start + ROWS_AT_ONCE], stride, scale, target)
                 for start in range(0, len(rows), ROWS_AT_ONCE)]
        return np.concatenate(baked) if baked else rows

    def _interpolate_batch(self, rows, stride, scale, target):
        corners, weights = self._cell_corners(rows, 2 * stride)
        usable = (corners >= 0).all(axis=1)
        usable[usable] = self.known[corners[usable]].all(axis=1)
        candidates = rows[usable]
        corners, weights = corners[usable], weights[usable]
        corner_values = self.transfer[corners]
        value = np.einsum("mc,mck->mk", weights, corner_values)
        bend = self._bend(corners, 2 * stride)
        spread = np.linalg.norm(corner_values - value[:, None], axis=2).max(axis=1)
        interpolation = np.where(np.isnan(bend), spread, bend) / scale
        noise = np.sqrt(np.einsum("mc,mc->m", weights ** 2, self.noise[corners] ** 2))
        inherited = np.einsum("mc,mc->m", weights, self.bias[corners])
        corner_noise = self.noise[corners].max(axis=1) / scale
        smooth = self._smooth(candidates, corners, weights)
        chosen = smooth & (interpolation <= AGREEMENT * target + NOISE_ALLOWANCE * corner_noise)
        taken = candidates[chosen]
        self.transfer[taken] = value[chosen]
        self.noise[taken] = noise[chosen]
        self.bias[taken] = inherited[chosen] + interpolation[chosen] * scale
        self.std_error[taken] = np.hypot(self.noise[taken], self.bias[taken])
        self.known[taken] = self.interpolated[taken] = True
        return np.setdiff1d(rows, taken)

    def _cell_corners(self, rows, cell):
        """(M, 4) corner rows (−1 where a corner is no covered texel) and (M, 4) bilinear weights of the cells of
        size `cell` the rows lie in; a row on a cell's edge takes its two ends (the other two weigh nothing)."""
        grid = self.grid
        x, y = grid.x[rows], grid.y[rows]
        x0, y0 = (x // cell) * cell, (y // cell) * cell
        x1, y1 = np.where(x == x0, x0, x0 + cell), np.where(y == y0, y0, y0 + cell)
        fx = np.where(x1 > x0, (x - x0) / cell, 0.0)
        fy = np.where(y1 > y0, (y - y0) / cell, 0.0)
        corner_x = np.stack([x0, x1, x0, x1], axis=1)
        corner_y = np.stack([y0, y0, y1, y1], axis=1)
        inside = (corner_x < grid.width) & (corner_y < grid.height)
        corners = np.where(inside, self.index[np.minimum(corner_y, grid.height - 1),
                                              np.minimum(corner_x, grid.width - 1)], -1)
        weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], axis=1)
        return corners, weights

    def _bend(self, corners, cell) -> np.ndarray:
        """(M,) the error bilinear interpolation makes in each cell: an eighth of the largest second difference
        (along x plus along y) at its corners over the lattice of `cell`, as linear interpolation of a quadratic
        errs by h²f''/8; one-sided at a border. NaN where a corner has too few known neighbours (the caller falls
        back on the corners' spread)."""
        grid = self.grid
        unique, inverse = np.unique(corners, return_inverse=True)  # neighbouring cells share corners: once each
        x, y = grid.x[unique], grid.y[unique]
        total = np.zeros(len(unique))
        for dx, dy in ((cell, 0), (0, cell)):
            second = np.full(len(unique), np.nan)
            for first, middle, last in ((-1, 0, 1), (0, 1, 2), (-2, -1, 0)):  # centred, forward, backward
                pending = np.flatnonzero(np.isnan(second))
                rows = [self._known_at(x[pending] + k * dx, y[pending] + k * dy) for k in (first, middle, last)]
                usable = (rows[0] >= 0) & (rows[1] >= 0) & (rows[2] >= 0)
                a, b, c = (self.transfer[r[usable]] for r in rows)
                second[pending[usable]] = np.linalg.norm(a - 2 * b + c, axis=1)
            total += second
        return total[inverse.reshape(corners.shape)].max(axis=1) / 8.0

    def _known_at(self, x, y) -> np.ndarray:
        """Rows of the known texels at (x, y), −1 outside the map or where nothing is known."""
        grid = self.grid
        inside = (x >= 0) & (y >= 0) & (x < grid.width) & (y < grid.height)
        rows = np.where(inside, self.index[np.clip(y, 0, grid.height - 1), np.clip(x, 0, grid.width - 1)], -1)
        rows[rows >= 0] = np.where(self.known[rows[rows >= 0]], rows[rows >= 0], -1)
        return rows

    def _smooth(self, rows, corners, weights) -> np.ndarray:
        """Whether the cell's corners lie on one smooth piece of surface with the row's texel."""
        receiver = self.grid.receiver
        position = np.einsum("mc,mcd->md", weights, receiver.positions[corners])
        normal = np.einsum("mc,mcd->md", weights, receiver.normals[corners])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        size = np.linalg.norm(receiver.positions[corners].max(axis=1) - receiver.positions[corners].min(axis=1), axis=1)
        near = np.linalg.norm(position - receiver.positions[rows], axis=1) <= POSITION_TOLERANCE * np.maximum(size, 1e-12)
        return near & (np.einsum("md,md->m", normal, receiver.normals[rows]) >= NORMAL_COSINE)


def lattice_strides(side: int) -> list[int]:
    """Powers of two from the coarsest lattice's (about COARSEST_SAMPLES texels across `side`) down to 1."""
    coarsest = max(0, round(np.log2(max(side, 1) / COARSEST_SAMPLES)))
    return [1 << level for level in range(coarsest, -1, -1)]


class RefiningJob(Job):
    """The first job (the other receivers, and each texel receiver's coarsest lattice), then, lattice by lattice,
    one job for the texels that cannot be interpolated. `make_job(receivers)` makes a TransferJob with the bake's
    occluders, settings and workers."""

    def __init__(self, receivers, grids: dict, settings: bake.BakeSettings, target: float, make_job,
                 first_job=None):
        """receivers: every receiver in the bake's order; grids: {position in that order: TexelGrid}. first_job: a
        job that must finish before any texel is baked (an interreflected bake's vertex solve, its results at the
        texel receivers' positions replaced by theirs); None: the first job bakes the other receivers and every
        texel receiver's coarsest lattice together."""
        self.strides = lattice_strides(max((max(grid.width, grid.height) for grid in grids.values()), default=1))
        self.receivers = receivers
        self.states = {position: GridState(grid, settings.order) for position, grid in grids.items()}
        self.settings = settings
        self.target = target
        self.scale = lobes.unshadowed_norm(settings.order)
        self.make_job = make_job
        self.progress = Progress("PRT bake")
        self._rows = {position: state.lattice(self.strides[0]) for position, state in self.states.items()}
        self._texels_pending = first_job is not None  # the coarsest lattice still to bake after the first job
        self.first = first_job or make_job([self.states[position].subset(self._rows[position], self.strides[0])
                                            if position in self.states else receiver
                                            for position, receiver in enumerate(receivers)])
        self.jobs = [self.first]
        self._first_results = None
        self._baking = list(self.states)
        self._level = 0
        self.baked = {stride: 0 for stride in self.strides}         # texels baked on each lattice
        self.interpolated = {stride: 0 for stride in self.strides}  # texels interpolated on each lattice
        self.finished = False

    def step(self, budget_s: float) -> bool:
        if not self.finished and self.jobs[-1].step(budget_s):
            self._level_done(self.jobs[-1])
        self.progress.fraction = self._fraction()
        return self.finished

    def _fraction(self) -> float:
        """Texels known (and the running job's share of those it bakes) of all texels; without texels, the job's."""
        total = sum(len(state.known) for state in self.states.values())
        if self.finished or not total:
            return 1.0 if self.finished else self.jobs[-1].progress.fraction
        known = sum(int(state.known.sum()) for state in self.states.values())
        baking = sum(len(self._rows[position]) for position in self._baking)
        return (known + self.jobs[-1].progress.fraction * baking) / total

    def _level_done(self, current):
        results = current.results()
        if current is self.first:
            self._first_results = results
            if self._texels_pending and self._baking:
                self._texels_pending = False
                self.jobs.append(self._job_for(self._baking))
                return
            results = [results[position] for position in self._baking]
        for position, result in zip(self._baking, results):
            self.states[position].store(self._rows[position], result)
            self.baked[self.strides[self._level]] += len(self._rows[position])
        self._next_level()
        if not self._baking:
            self.finished = True
            return
        self.jobs.append(self._job_for(self._baking))

    def _job_for(self, positions):
        """The job baking these texel receivers' rows of the current lattice."""
        return self.make_job([self.states[position].subset(self._rows[position], self.strides[self._level])
                              for position in positions])

    def _next_level(self):
        """Moves to the next lattice that has texels to bake, interpolating what it can on the way."""
        self._baking = []
        while self._level < len(self.strides) - 1 and not self._baking:
            self._level += 1
            stride = self.strides[self._level]
            for position, state in self.states.items():
                before = int(state.interpolated.sum())
                self._rows[position] = state.interpolate(state.lattice(stride), stride, self.scale, self.target)
                self.interpolated[stride] += int(state.interpolated.sum()) - before
                if len(self._rows[position]):
                    self._baking.append(position)

    def cancel(self):
        self.jobs[-1].cancel()

    def summary(self, results):
        """The bake's summary over every receiver and every lattice's job; its error against time ends with what
        the lattices after the first job gave."""
        summary = self.first.summary(results, self.receivers, self.progress.elapsed)
        if len(self.jobs) > 1:
            errors = [rules.point_errors(result.rel_error, result.rel_rule_error) for result in results]
            summary.error_curve = error_curve.then(summary.error_curve, error_curve.TEXELS, summary.time_s,
                                                   summary.rays, np.concatenate(errors))
            for receiver, error in zip(self.receivers, errors):
                entry = summary.per_object[receiver.name]
                entry["error_curve"] = error_curve.then(entry["error_curve"], error_curve.TEXELS, summary.time_s,
                                                        entry["rays"], error)
        return summary

    def results(self) -> list:
        """Per receiver in order: the first job's result, or the texel receiver's refined one."""
        out = list(self._first_results)
        for position, state in self.states.items():
            out[position] = ReceiverResult(state.transfer.astype(np.float32), state.std_error,
                                           state.std_error / self.scale, state.rays, state.skipped,
                                           state.rules, state.rel_rule_error)
        return out

    def outcome(self) -> list:
        return self.results()

    def lattice_line(self) -> str:
        """Texels baked and interpolated per lattice, for the bake's notes."""
        return "; ".join(f"every {stride}: {self.baked[stride]} baked, {self.interpolated[stride]} interpolated"
                         for stride in self.strides)
