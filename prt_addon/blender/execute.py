"""The third step of a bake: the plan executed, as one job (core.progress: stepped with a time budget, progress and
time left, cancel) whose every step casts its rays through the executor (core.executors):

1. Auto's probes, where texel or Auto receivers wait for them; then each such receiver's layout is chosen;
2. the bake itself: every receiver and bouncer, texel receivers lattice by lattice (core.texel_refine), and in
   interreflected bakes the bounces (core.interreflect) and the texels' gather (core.texel_gather);
3. the probes between vertices of the receivers stored per point (core.interpolation);
4. the probe volumes' probes (core.probe_transfer), whose bounced light is the solved surfaces' exitant transfer.

Its outcome, BakeResults, is what storing writes: nothing is written here, so a cancelled or failed bake leaves
the previous data as it was.
"""

from dataclasses import dataclass, field
import sys

import bpy
import numpy as np

from ..core import (bake, error_curve, executors, interpolation, job, lobes, probe_transfer, rules, scheduling,
                    texel_gather, texel_refine)
from ..core.errors import InputError
from ..core.progress import JobSequence, WrappingJob
from . import texel_plan
from .plan import BakePlan, albedo_channels

INTERPOLATION_KEYS = ("est_interp_rms_rel_error", "est_interp_max_rel_error", "interp_points")


@dataclass
class BakeResults:
    """The execution's outcome: per receiver in the plan's order (those it dropped left out), their layout and
    result, the bake's summary, what each texel and Auto receiver stores and why, and the objects not baked."""
    names: list
    layouts: list
    results: list            # core.job.ReceiverResult
    summary: job.Summary
    decisions: list          # one sentence per texel or Auto receiver
    lattices: str            # what the texel lattices baked and interpolated ("" without texels)
    problems: list
    parts: list = field(default_factory=list)  # each dynamic part's own BakeResults; `summary` then covers all
    probes: probe_transfer.ProbeTransfer | None = None  # the request's probe volumes' probes, in order


def local_executor(workers: int):
    """How `workers` processes bake on this machine (core.executors): this process alone for one; else workers
    running Blender's own binary in a real Blender; with the bpy module, forks of this process on Linux (they start
    in milliseconds instead of importing bpy for a second, and share the ray tree), the module's Python elsewhere
    (macOS and Windows cannot fork a process that runs Blender safely)."""
    if workers <= 1:
        return executors.InProcess()
    if bpy.app.binary_path:
        return executors.SpawnedWorkers(workers, [bpy.app.binary_path, "--background", "--factory-startup",
                                                  "--python-expr"])
    if sys.platform.startswith("linux"):
        return executors.ForkedWorkers(workers)
    return executors.SpawnedWorkers(workers, [sys.executable, "-c"])


def execute(plan: BakePlan, executor) -> "Execution":
    """The plan's bake as a job to step or run; its outcome is BakeResults."""
    return Execution(plan, executor)


def main_job(plan: BakePlan, chosen: list, executor, surfaces=None) -> texel_refine.RefiningJob:
    """The bake of the receivers in their layouts `chosen` (and of the bouncers) in the solved order, the texel
    receivers lattice by lattice (core.texel_refine) to the bake's target error (or Auto's, without one).
    Interreflected, the vertices of every surface solve the bounces first, then each texel gathers from them
    (core.texel_gather). `surfaces`: the receivers' vertex surfaces, where some planned ones were dropped."""
    settings, occluders = plan.settings, plan.occluders
    surfaces = (surfaces or [receiver.surface for receiver in plan.receivers]) + plan.request.bouncers
    albedo = albedo_channels([surface.albedo for surface in surfaces]) if settings.mode == "interreflected" else None

    def transfer_job(receivers, gathering=False):
        return job.TransferJob(receivers, occluders, settings, executor, albedo=None if gathering else albedo)
    receivers = [layout.receiver for layout in chosen] + [surface.receiver for surface in surfaces[len(chosen):]]
    grids = {position: grid for position, grid in enumerate(layout.grid() for layout in chosen) if grid is not None}
    target = settings.target_error or interpolation.AUTO_TARGET
    if settings.mode != "interreflected" or not grids:
        return texel_refine.RefiningJob(receivers, grids, settings, target, transfer_job)
    solve = transfer_job([surface.receiver for surface in surfaces])
    solved_albedo = np.concatenate(solve.albedo)

    def gathering_job(texel_receivers):
        solved = np.concatenate([result.transfer for result in solve.results()])
        return texel_gather.GatheringJob(transfer_job(texel_receivers, gathering=True), solved, solved_albedo)
    return texel_refine.RefiningJob(receivers, grids, settings, target, gathering_job, first_job=solve)


def between_job(plan: BakePlan, executor) -> job.TransferJob:
    """The job of the probes between vertices (plan.between): an interreflected bake's are shadowed."""
    return job.TransferJob(plan.between.receivers, plan.occluders, texel_plan.probe_settings(plan.settings),
                           executor, name="probes")


def first_job(plan: BakePlan, executor) -> job.TransferJob:
    """The job the bake starts with, made but not run (Auto's receivers per vertex): what the checks size."""
    return main_job(plan, plan.layouts(), executor).first


class Execution(WrappingJob):
    """The plan's bake: Auto's probes, the bake, the probes between vertices, one after another."""

    def __init__(self, plan: BakePlan, executor):
        self.plan, self.executor = plan, executor
        settings = plan.settings
        self.pending = plan.pending
        self.auto, self.auto_s = None, 0.0
        self.measured = {}  # Auto receivers kept per vertex → their probes' squared interpolation errors
        self.chosen = [receiver.layout for receiver in plan.receivers]
        self.decisions = {receiver.name: receiver.decision for receiver in plan.receivers}
        self.problems = list(plan.problems)
        self.main = None
        self.between = between_job(plan, executor)
        stages, shares = [], []
        if self.pending:
            self.auto = job.TransferJob(texel_plan.place_probes(self.pending, settings), plan.occluders,
                                        texel_plan.probe_settings(settings), executor, name="auto probes")
            stages.append(self.auto)
            shares.append(self.auto.total_vertices)
        stages.append(self._decided if self.pending else self._main())
        shares.append(sum(len(layout.receiver.positions) for layout in plan.layouts())
                      + sum(len(surface.receiver.positions) for surface in plan.request.bouncers))
        stages.append(self.between)
        shares.append(max(1, self.between.total_vertices))
        self.probes = None
        volumes = plan.request.probe_volumes
        if volumes:
            stages.append(self._probes)
            shares.append(sum(len(volume.positions) for volume in volumes))
        self.parts = [Execution(part, executor) for part in plan.parts]  # each dynamic receiver alone, after
        stages += self.parts
        shares += [sum(len(layout.receiver.positions) for layout in part.plan.layouts()) for part in self.parts]
        self.sequence = JobSequence(stages, shares, "PRT bake")

    def inner(self) -> JobSequence:
        return self.sequence

    def _main(self) -> texel_refine.RefiningJob:
        """The bake's job over the receivers whose layout is chosen."""
        self.kept = [index for index, layout in enumerate(self.chosen) if layout is not None]
        self.main = main_job(self.plan, [self.chosen[index] for index in self.kept], self.executor,
                             [self.plan.receivers[index].surface for index in self.kept])
        return self.main

    def _decided(self) -> texel_refine.RefiningJob:
        """Once Auto's probes are baked: each waiting receiver's layout (dropped, with why, where its texels cannot
        be baked at the resolution they call for), then the bake's job."""
        settings = self.plan.settings
        self.auto_s = self.auto.progress.elapsed
        texel_plan.measure(self.pending, self.auto.results(), settings.order)
        target = settings.target_error or interpolation.AUTO_TARGET
        for index, receiver in enumerate(self.plan.receivers):
            if receiver.layout is not None:
                continue
            try:
                self.chosen[index], self.decisions[receiver.name] = receiver.candidate.choose(settings.order, target)
            except InputError as problem:
                self.problems.append(str(problem))
                continue
            if self.chosen[index].between_vertices:
                self.measured[receiver.name] = receiver.candidate.errors
        if not any(layout is not None for layout in self.chosen):
            raise InputError("nothing to bake: " + "; ".join(self.problems))
        texel_plan.check_memory([layout for layout in self.chosen if layout is not None], settings.order)
        return self._main()

    def _probes(self) -> probe_transfer.ProbeJob:
        """Once the scene is solved: the job of the probe volumes' probes, their bounces from the solved surfaces'
        exitant transfer ρ·T (interreflected bakes; their first job solves every surface's vertices)."""
        settings, exitant = self.plan.settings, None
        if settings.mode == "interreflected":
            solve = self.main.first
            transfer = np.concatenate([result.transfer for result in solve.results()]).astype(np.float64)
            transfer = transfer[:, None, :] if transfer.ndim == 2 else transfer
            exitant = np.concatenate(solve.albedo)[:, :, None] * transfer
        volumes = self.plan.request.probe_volumes
        positions = np.concatenate([volume.positions for volume in volumes])
        # Each volume's probes keyed by its name, as a receiver's vertices are: a volume rebaked alone (stale-only)
        # casts the rays a bake of everything would.
        keys = np.concatenate([scheduling.stream_keys(bake.Receiver.key_for(volume.name),
                                                      np.arange(np.prod(volume.resolution))) for volume in volumes])
        self.probes = probe_transfer.ProbeJob(self.plan.occluders.ray_caster(), positions, settings.order,
                                              settings.samples, settings.replicates, settings.seed, exitant, keys)
        return self.probes

    def outcome(self) -> BakeResults:
        """The receivers' results and the bake's summary, in mesh vertices, with what storing per vertex loses
        between them; the bake's time includes every probe."""
        receivers = [self.plan.receivers[index] for index in self.kept]
        chosen = [self.chosen[index] for index in self.kept]
        results = self.main.results()[: len(receivers)]  # bouncers are not stored
        summary = self.main.summary(results)
        summary.ray_engine = self.plan.request.ray_engine if self.plan.occluders is not None else ""
        vertices = {receiver.name: receiver.vertices for receiver in self.plan.request.receivers}
        for receiver, layout in zip(receivers, chosen):
            summary.per_object[receiver.name].update(vertices=vertices[receiver.name],
                                                     points=len(layout.receiver.positions),
                                                     split_vertices=layout.split_vertices,
                                                     dynamic=self.plan.request.dynamic)
        summary.vertices = sum(entry["vertices"] for entry in summary.per_object.values())
        summary.split_vertices = sum(entry["split_vertices"] for entry in summary.per_object.values())
        summary.dynamic = sum(entry["dynamic"] for entry in summary.per_object.values())
        self._measure_interpolation(summary, [receiver.name for receiver in receivers], results)
        decisions = [self.decisions[receiver.name] for receiver in receivers if self.decisions[receiver.name]]
        own = BakeResults([receiver.name for receiver in receivers], chosen, results, summary, decisions,
                          self.main.lattice_line() if self.main.states else "", self.problems,
                          probes=self.probes.outcome() if self.probes else None)
        if self.parts:
            own.parts = [part.outcome() for part in self.parts]
            own.summary = merged_summary([own] + own.parts, self.sequence.progress.elapsed)
        return own

    def _measure_interpolation(self, summary: job.Summary, names, results):
        """The probes' interpolation error per object and overall, into the summary."""
        scale = lobes.unshadowed_norm(self.plan.settings.order)
        between = self.plan.between
        probe_results = dict(zip(between.probes, self.between.results()))
        direct = self.main.first.direct or [result.transfer for result in results]
        everything = []
        for name, result, transfer in zip(names, results, direct):
            if name in self.measured:
                squared = self.measured[name]
            elif name in between.probes:
                found = probe_results[name]
                squared = interpolation.interpolation_errors(between.probes[name], found.transfer, found.std_error,
                                                             transfer, result.std_error, scale)
            else:
                continue
            everything.append(squared)
            rms, worst = interpolation.summarise(squared)
            summary.per_object[name].update(est_interp_rms_rel_error=rms, est_interp_max_rel_error=worst,
                                            interp_points=len(squared))
        (summary.est_interp_rms_rel_error,
         summary.est_interp_max_rel_error) = interpolation.summarise(np.concatenate(everything or [[]]))
        summary.interp_points = self.between.total_vertices + sum(map(len, self.measured.values()))
        summary.interp_rays = self.between.rays + (self.auto.rays if self.auto else 0)
        summary.phases_s["probes_s"] = self.between.progress.elapsed + self.auto_s
        if self.probes:
            summary.phases_s["probe_volumes_s"] = self.probes.progress.elapsed
            summary.probe_volumes = len(self.plan.request.probe_volumes)
            summary.probes = len(self.probes.positions)
            summary.probe_rays = summary.probes * self.probes.rays
        # A merge's time is the shards' seconds summed plus its own, as its job's summary counts it.
        summary.time_s = self.sequence.progress.elapsed + self.main.first.phase_times.get("shards_s", 0.0)


def merged_summary(outcomes: list, time_s: float) -> job.Summary:
    """One summary of a bake and its dynamic parts (BakeResults each), baked one after another in `time_s`: counts
    add, the error statistics are over every point, the bounces and the settings are the first bake's."""
    first, summaries = outcomes[0].summary, [outcome.summary for outcome in outcomes]
    results = [result for outcome in outcomes for result in outcome.results]
    rel, doubt = (np.concatenate([getattr(result, name) for result in results])
                  for name in ("rel_error", "rel_rule_error"))
    merged = job.Summary(**{**vars(first), "per_object": {}, "phases_s": {}})
    for name in ("objects", "vertices", "points", "rays", "skipped_vertices", "split_vertices", "interp_points",
                 "interp_rays", "inside_another_part", "dynamic"):
        setattr(merged, name, sum(getattr(summary, name) for summary in summaries))
    for summary in summaries:
        merged.per_object.update(summary.per_object)
        for phase, seconds in summary.phases_s.items():
            merged.phases_s[phase] = merged.phases_s.get(phase, 0.0) + seconds
    merged.time_s = time_s
    casting_s = sum(summary.rays / summary.rays_per_s for summary in summaries if summary.rays_per_s > 0)
    merged.rays_per_s = merged.rays / casting_s if casting_s > 0 else 0.0
    for name, value in rules.estimate(rel, doubt).items():
        setattr(merged, name, value)
    measured = [summary for summary in summaries if summary.est_interp_rms_rel_error is not None]
    if measured and merged.interp_points:
        merged.est_interp_rms_rel_error = float(np.sqrt(sum(
            summary.interp_points * summary.est_interp_rms_rel_error ** 2 for summary in measured) / max(
            1, sum(summary.interp_points for summary in measured))))
        merged.est_interp_max_rel_error = max(summary.est_interp_max_rel_error for summary in measured)
    merged.ray_engine = next((summary.ray_engine for summary in summaries if summary.ray_engine), "")
    merged.error_curve = error_curve.added([summary.error_curve for summary in summaries])
    return merged
