"""`prt convergence`: bakes at several sample counts and sets each bake's estimated error beside its actual error.

The reference is, by default, a bake at 16 × the largest count with another seed. The actual error is then in the
estimate's own measure, RMS over vertices of ‖T − T_ref‖ ÷ ‖T_unshadowed‖, so the two curves say directly whether
the estimate is honest; the reference's own error adds to it in quadrature, and its estimate is reported.
With the Cycles reference (validate.py), the actual error is the RMS relative error of the radiance under the
scene's light, Cycles' noise taken out: a measure of what one sees under that light, not the same measure as the
estimate, which covers any light.
"""

import csv
from dataclasses import astuple, dataclass, fields
import os

import numpy as np

from . import baking, mesh_data, plot, validate
from .core import bake
from .core.progress import LogThrottle, Progress

DEFAULT_SAMPLES = [16 << step for step in range(9)]  # 16, 32, ..., 4096
REFERENCE_FACTOR = 16
REFERENCE_SEED_OFFSET = 1_000_003  # the reference must be randomised independently of what it judges
# For the time left only: one Cycles sample costs about as much as ten bake rays (demo scene, 2 cores).
CYCLES_SAMPLE_COST = 10
REFERENCES = ("bake", "cycles")


@dataclass
class Row:
    samples: int
    rays: int
    time_s: float
    est_rms_rel_error: float
    actual_rms_rel_error: float


class Study:
    """Bakes the scene at each sample count (order `order`, shadowed) and measures each against the reference."""

    def __init__(self, context, samples, object_names=None, order=4, reference="bake", reference_samples=None,
                 workers=1, seed=0, cycles_passes=validate.DEFAULT_PASSES):
        if reference not in REFERENCES:
            raise mesh_data.InputError(f"reference must be one of {', '.join(REFERENCES)}, not {reference!r}")
        self.samples = sorted(set(samples))
        if not self.samples:
            raise mesh_data.InputError("give at least one sample count")
        if reference == "bake":
            reference_samples = reference_samples or min(REFERENCE_FACTOR * self.samples[-1], bake.MAX_SAMPLES)
        self.reference_samples = reference_samples or validate.DEFAULT_SAMPLES
        baked_counts = self.samples + ([self.reference_samples] if reference == "bake" else [])
        problems = [problem for count in baked_counts for problem in self._settings(count, order, seed).problems()]
        if problems:
            raise mesh_data.InputError("; ".join(dict.fromkeys(problems)))
        self.context, self.object_names, self.order = context, object_names, order
        self.reference, self.workers, self.seed, self.cycles_passes = reference, workers, seed, cycles_passes
        self.rows: list[Row] = []
        self.notes: list[str] = []
        self.progress = Progress("PRT convergence")
        reference_cost = (self.reference_samples if reference == "bake"
                          else cycles_passes * self.reference_samples * CYCLES_SAMPLE_COST)
        self._total_cost = reference_cost + sum(self.samples)
        self._done_cost = 0.0
        self._throttle = LogThrottle(0.05)

    @staticmethod
    def _settings(samples, order, seed):
        return bake.BakeSettings(order=order, mode="shadowed", samples=samples, seed=seed)

    def run(self, log=print) -> list:
        reference = None
        if self.reference == "bake":
            summary, reference = self._bake(self.reference_samples, self.seed + REFERENCE_SEED_OFFSET, log)
            log(f"PRT convergence: reference, {self.reference_samples} samples: {summary.time_s:.1f} s, "
                f"est. RMS rel. error {summary.est_rms_rel_error:.5f}")
        for samples in self.samples:
            summary, transfers = self._bake(samples, self.seed, log)
            if self.reference == "cycles" and reference is None:
                reference = self._cycles(list(transfers), log)
            actual = (coefficient_error(transfers, reference, self.order) if self.reference == "bake"
                      else reference.comparisons()[-1].error)
            row = Row(samples, summary.rays, summary.time_s, summary.est_rms_rel_error, actual)
            self.rows.append(row)
            log(f"PRT convergence: {samples} samples: {row.time_s:.2f} s, {row.rays} rays, "
                f"est. {row.est_rms_rel_error:.5f}, actual {row.actual_rms_rel_error:.5f}")
        return self.rows

    def _bake(self, samples, seed, log):
        """Bakes (stored on the meshes, as the Cycles reference reads them) → (summary, {name: transfer})."""
        scene_bake = baking.SceneBake(self.context, self._settings(samples, self.order, seed), self.object_names,
                                      workers=self.workers)
        self._note(scene_bake.problems + scene_bake.notes)
        self._advance(scene_bake, samples, log)
        summary = scene_bake.store()
        return summary, {ob.name: mesh_data.read_transfer(ob.data)[0] for ob in scene_bake.objects}

    def _cycles(self, names, log):
        validation = validate.Validation(self.context, self.reference_samples, self.cycles_passes, names)
        self._note(validation.notes)
        self._advance(validation, self.cycles_passes * self.reference_samples * CYCLES_SAMPLE_COST, log)
        log(f"PRT convergence: Cycles reference, {self.cycles_passes} × {self.reference_samples} samples: "
            f"{validation.cycles.time_s:.1f} s")
        return validation

    def _advance(self, job, cost, log):
        """Steps a bake or the Cycles passes to the end, logging the whole study's progress and time left."""
        finished = False
        while not finished:
            finished = job.step(0.5)
            self.progress.fraction = (self._done_cost + job.progress.fraction * cost) / self._total_cost
            if self._throttle.due(self.progress.fraction):
                log(self.progress.line())
        self._done_cost += cost

    def _note(self, sentences):
        self.notes += [sentence for sentence in sentences if sentence not in self.notes]

    def reference_text(self) -> str:
        if self.reference == "bake":
            return f"a bake of {self.reference_samples} samples"
        return f"Cycles, {self.cycles_passes} × {self.reference_samples} samples"


def coefficient_error(transfers: dict, reference: dict, order: int) -> float:
    """RMS over every vertex of ‖T − T_ref‖ ÷ ‖T_unshadowed‖: the measure of the bake's own estimate."""
    squared = np.concatenate([np.sum(np.square(transfers[name].astype(np.float64) - reference[name]), axis=1)
                              for name in reference])
    return float(np.sqrt(np.mean(squared))) / bake.unshadowed_norm(order)


def write_csv(path, rows):
    _make_folder(path)
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow([field.name for field in fields(Row)])
        writer.writerows(astuple(row) for row in rows)


def write_plot(path, rows, title, reference_text):
    """Actual and estimated error against bake time, log-log, each point labelled with its sample count. The
    estimate is drawn thin with rings over the actual error, so both show where they coincide."""
    times = [row.time_s for row in rows]
    series = [plot.Series(f"actual (against {reference_text})", times, [row.actual_rms_rel_error for row in rows],
                          plot.VERMILION, "square", width=3.0),
              plot.Series("estimated (the bake's own)", times, [row.est_rms_rel_error for row in rows], plot.BLUE,
                          "ring", tuple(str(row.samples) for row in rows), width=1.5)]
    _make_folder(path)
    plot.write_png(path, plot.log_log_plot(series, title, "bake time (s)", "RMS relative error"))


def _make_folder(path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
