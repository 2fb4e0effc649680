"""Error against run time: bakes a scene at several sample counts and sets each bake's estimated error beside its
actual error, as a CSV and a log-log plot against bake time.

    .venv/bin/python benchmarks/convergence.py FILE [--samples 16,32,...] [--objects A,B] [--object NAME] [--order 4]
        [--reference bake|cycles] [--reference-samples N] [--workers N] [--seed 0]
        [--csv convergence.csv] [--plot convergence.png] [--json [DIR]] [--quick]

The reference is, by default, a bake at 16 × the largest count with another seed. The actual error is then in the
estimate's own measure, RMS over vertices of ‖T − T_ref‖ ÷ ‖T_unshadowed‖, so the two curves say directly whether
the estimate is honest; the reference's own error adds to it in quadrature, and its estimate is printed.
With the Cycles reference (blender.validation), the actual error is the RMS relative error of the radiance under
the scene's light, Cycles' noise taken out: a measure of what one sees under that light, not the same measure as
the estimate, which covers any light.

--quick is a smoke run of seconds on a small FILE (or --objects): 16 and 32 samples against a 256-sample reference
(options given override it).
"""

import argparse
import csv
from dataclasses import asdict, astuple, dataclass, fields
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402  (before mathutils, which the add-on imports)
from benchmarks import results as result_files  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter  # noqa: E402
import numpy as np  # noqa: E402

from prt_addon.blender import storage, validation  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.commands.common import (  # noqa: E402
    add_object_options, log, object_names, open_file, schema_registered, warn)
from prt_addon.core.bake import BakeSettings  # noqa: E402
from prt_addon.core.lobes import unshadowed_norm  # noqa: E402
from prt_addon.core.errors import InputError  # noqa: E402
from prt_addon.core.progress import Job, Progress  # noqa: E402
from prt_addon.core.settings import MOST_SAMPLES  # noqa: E402
from prt_addon.core.statistics import rms  # noqa: E402

DEFAULT_SAMPLES = [16 << step for step in range(9)]  # 16, 32, ..., 4096
QUICK_SAMPLES, QUICK_REFERENCE_SAMPLES = [16, 32], 256
REFERENCE_FACTOR = 16
REFERENCE_SEED_OFFSET = 1_000_003  # the reference must be randomised independently of what it judges
# For the time left only: one Cycles sample costs about as much as ten bake rays (demo scene, 2 cores).
CYCLES_SAMPLE_COST = 10
REFERENCES = ("bake", "cycles")
LABEL = "PRT convergence"
# Told apart also by readers with red-green colour blindness (Okabe-Ito vermilion and blue).
VERMILION = "#D55E00"
BLUE = "#0072B2"
FIGURE_INCHES, FIGURE_DPI = (7.6, 5.0), 100  # 760 × 500 pixels


@dataclass
class Row:
    samples: int
    rays: int
    time_s: float
    est_rms_rel_error: float
    actual_rms_rel_error: float


class Study(Job):
    """Bakes the scene at each sample count (order `order`, shadowed) and measures each against the reference.

    Its sub-jobs run one after another: the reference bake (or, after the first bake, Cycles' passes), then the
    bakes. Each step advances the current one, and the study's progress is their done cost plus the current one's
    share of its own, so `run` shows the whole study's time left."""

    def __init__(self, context, samples, object_names=None, order=4, reference="bake", reference_samples=None,
                 workers=1, seed=0, cycles_passes=validation.DEFAULT_PASSES):
        if reference not in REFERENCES:
            raise InputError(f"reference must be one of {', '.join(REFERENCES)}, not {reference!r}")
        self.samples = sorted(set(samples))
        if not self.samples:
            raise InputError("give at least one sample count")
        if reference == "bake":
            reference_samples = reference_samples or min(REFERENCE_FACTOR * self.samples[-1], MOST_SAMPLES)
        self.reference_samples = reference_samples or validation.DEFAULT_SAMPLES
        baked_counts = self.samples + ([self.reference_samples] if reference == "bake" else [])
        problems = [problem for count in baked_counts for problem in _settings(count, order, seed).problems()]
        if problems:  # found before any bake is spent
            raise InputError("; ".join(dict.fromkeys(problems)))
        self.context, self.object_names, self.order = context, object_names, order
        self.reference, self.workers, self.seed, self.cycles_passes = reference, workers, seed, cycles_passes
        self.rows: list[Row] = []
        self.notes: list[str] = []
        self.reference_summary = None  # the reference bake's
        self.validation = None  # the Cycles reference
        self.progress = Progress(LABEL)
        self._cycles_cost = cycles_passes * self.reference_samples * CYCLES_SAMPLE_COST
        self._total_cost = (self.reference_samples if reference == "bake" else self._cycles_cost) + sum(self.samples)
        self._done_cost = 0.0
        self._sub_jobs = self._sub_jobs_in_order()
        self._current = next(self._sub_jobs)  # (sub-job, cost): the first gathers the scene, as a bake does

    def step(self, budget_s: float = 0.5) -> bool:
        job, cost = self._current
        finished = job.step(budget_s)
        self.progress.fraction = (self._done_cost + job.progress.fraction * cost) / self._total_cost
        if finished:
            self._done_cost += cost
            self._current = next(self._sub_jobs, None)  # measures the finished one, starts the next
        return self._current is None

    def cancel(self):
        if self._current is not None:
            self._current[0].cancel()

    def outcome(self) -> list:
        return self.rows

    def _sub_jobs_in_order(self):
        """Yields (sub-job, cost) in turn; the code after each yield runs once that sub-job is done."""
        if self.reference == "bake":
            reference_bake = self._scene_bake(self.reference_samples, self.seed + REFERENCE_SEED_OFFSET,
                                              "reference bake")
            yield reference_bake, self.reference_samples
            self.reference_summary = reference_bake.outcome()
            reference_transfers = stored_transfers(reference_bake.objects)
        for samples in self.samples:
            scene_bake = self._scene_bake(samples, self.seed, "bake")
            yield scene_bake, samples
            summary = scene_bake.outcome()
            if self.reference == "cycles" and self.validation is None:  # rendered once, for the first bake's objects
                yield self._cycles([ob.name for ob in scene_bake.objects]), self._cycles_cost
            actual = (coefficient_error(stored_transfers(scene_bake.objects), reference_transfers, self.order)
                      if self.reference == "bake" else self.validation.comparisons()[-1].error)  # the bake stored last
            self.rows.append(Row(samples, summary.rays, summary.time_s, summary.est_rms_rel_error, actual))

    def _scene_bake(self, samples, seed, what):
        """A bake, stored on the meshes when done (the Cycles reference reads them there)."""
        self.progress.label = f"{LABEL}: {what}, {samples} samples"
        scene_bake = SceneBake(self.context, _settings(samples, self.order, seed), self.object_names,
                               workers=self.workers)
        self._note(scene_bake.problems + scene_bake.notes)
        return scene_bake

    def _cycles(self, object_names):
        self.progress.label = f"{LABEL}: Cycles, {self.cycles_passes} × {self.reference_samples} samples"
        self.validation = validation.Validation(self.context, self.reference_samples, self.cycles_passes,
                                                object_names)
        self._note(self.validation.notes)
        return self.validation

    def _note(self, sentences):
        self.notes += [sentence for sentence in sentences if sentence not in self.notes]

    def reference_text(self) -> str:
        if self.reference == "bake":
            return f"a bake of {self.reference_samples} samples"
        return f"Cycles, {self.cycles_passes} × {self.reference_samples} samples"

    def reference_line(self) -> str:
        """What the reference took and, for a bake, its own estimated error (small beside what it judges)."""
        if self.reference == "bake":
            return (f"reference, {self.reference_text()}: {self.reference_summary.time_s:.1f} s, "
                    f"est. RMS rel. error {self.reference_summary.est_rms_rel_error:.5f}")
        return f"reference, {self.reference_text()}: {self.validation.cycles.time_s:.1f} s"


def _settings(samples, order, seed):
    # No target error, so the ray budget only has to admit the samples (its default is below a large reference's).
    return BakeSettings(order=order, mode="shadowed", samples=samples,
                        max_samples=max(samples, BakeSettings.max_samples), seed=seed)


def stored_transfers(objects) -> dict:
    """{name: transfer} as stored on the objects' meshes, read before the next bake replaces it."""
    return {ob.name: storage.read_transfer(ob.data)[0] for ob in objects}


def coefficient_error(transfers: dict, reference: dict, order: int) -> float:
    """RMS over every vertex of ‖T − T_ref‖ ÷ ‖T_unshadowed‖ (a coloured transfer's channels in one norm): the
    measure of the bake's own estimate."""
    distances = np.concatenate([
        np.linalg.norm((transfers[name].astype(np.float64) - reference[name]).reshape(len(reference[name]), -1),
                       axis=1)
        for name in reference])
    return rms(distances) / unshadowed_norm(order)


def row_line(row: Row) -> str:
    return (f"{row.samples} samples: {row.time_s:.2f} s, {row.rays} rays, est. {row.est_rms_rel_error:.5f}, "
            f"actual {row.actual_rms_rel_error:.5f}")


def write_csv(path, rows):
    _make_folder(path)
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow([field.name for field in fields(Row)])
        writer.writerows(astuple(row) for row in rows)


def write_plot(path, rows, title, reference_text):
    """Actual and estimated error against bake time, log-log, each estimate labelled with its sample count. The
    estimate is drawn thin with rings over the thick actual error, so both show where they coincide."""
    figure = Figure(figsize=FIGURE_INCHES, dpi=FIGURE_DPI, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    times = [row.time_s for row in rows]
    estimates = [row.est_rms_rel_error for row in rows]
    axes.loglog(times, [row.actual_rms_rel_error for row in rows], color=VERMILION, linewidth=3.0, marker="s",
                markersize=6, label=f"actual (against {reference_text})")
    axes.loglog(times, estimates, color=BLUE, linewidth=1.5, marker="o", markersize=9, markerfacecolor="none",
                markeredgewidth=1.5, label="estimated (the bake's own)")
    for row, time_s, estimate in zip(rows, times, estimates):
        # Above and right of the point: the curves fall to the right, so they leave that corner free.
        axes.annotate(str(row.samples), (time_s, estimate), xytext=(6, 5), textcoords="offset points",
                      color=BLUE, fontsize=8)
    for axis in (axes.xaxis, axes.yaxis):
        plain_log_ticks(axis)
    axes.grid(which="major", color="0.8")
    axes.grid(which="minor", color="0.93")
    axes.set(title=title, xlabel="bake time (s)", ylabel="RMS relative error")
    axes.legend()
    _make_folder(path)
    figure.savefig(path)


def plain_log_ticks(axis):
    """Ticks at 1, 2 and 5 × each power of ten, written as plain numbers: the range spans only a few decades."""
    axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def _make_folder(path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)


def sample_counts(text):
    try:
        return [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, e.g. 16,64,256, got {text!r}") \
            from None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="bake at several sample counts; estimated and actual error "
                                                 "against bake time as CSV and a PNG plot")
    parser.add_argument("file", help=".blend file")
    parser.add_argument("--samples", type=sample_counts, metavar="16,32,...",
                        help="rays per vertex of each bake (default 16,32,...,4096)")
    add_object_options(parser, "every visible mesh")
    parser.add_argument("--order", type=int, default=4, help="SH bands, 1-10")
    parser.add_argument("--reference", choices=REFERENCES, default="bake",
                        help="bake: a bake at 16x the largest count, another seed (default); cycles: Cycles "
                             "under the scene's SH lights")
    parser.add_argument("--reference-samples", type=int, help="rays per vertex of the reference bake, or Cycles "
                        f"samples per pass (default {validation.DEFAULT_SAMPLES}, "
                        f"{validation.DEFAULT_PASSES} passes)")
    parser.add_argument("--workers", type=int, default=1, help="worker processes casting rays")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--csv", default="convergence.csv", help="where to write the table")
    parser.add_argument("--plot", default="convergence.png", help="where to write the log-log plot")
    parser.add_argument("--quick", action="store_true", help=f"a smoke run: --samples "
                        f"{','.join(map(str, QUICK_SAMPLES))} --reference-samples {QUICK_REFERENCE_SAMPLES}")
    result_files.add_argument(parser)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    args.samples = args.samples or (QUICK_SAMPLES if args.quick else DEFAULT_SAMPLES)
    if args.quick and args.reference == "bake":
        args.reference_samples = args.reference_samples or QUICK_REFERENCE_SAMPLES
    try:
        with schema_registered():  # the scene's SH lights, which the Cycles reference shines
            open_file(args.file, required=True)
            study = Study(bpy.context, args.samples, object_names(args), args.order, args.reference,
                          args.reference_samples, args.workers, args.seed)
            rows = study.run(log=log)
    except InputError as failure:
        print(f"convergence: error: {failure}", file=sys.stderr)
        return 1
    warn(study.notes)
    print(study.reference_line())
    for row in rows:
        print(row_line(row))
    write_csv(args.csv, rows)
    write_plot(args.plot, rows, f"PRT error against bake time: {os.path.basename(args.file)}",
               study.reference_text())
    print(f"wrote {os.path.abspath(args.csv)} and {os.path.abspath(args.plot)}")
    if args.json:  # no goal: the evidence that the estimate is honest is the rows themselves
        result_files.write("convergence", args, {"reference": study.reference_line(),
                                                 "rows": [asdict(row) for row in rows]}, [], argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
