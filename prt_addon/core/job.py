"""The bake job: the state machine that bakes every receiver's chunks through an executor (core.executors), with
progress, time left and cancel, bounces interreflections, and hands back the results (per receiver, and a summary).

Every executor runs `estimator.bake_chunk` on the same fixed chunks, so the results are bit-identical however the job is
run. `step()` returns after a bounded amount of work so a modal operator stays responsive.
"""

from dataclasses import dataclass, field
import time

import numpy as np

from . import bake, error_curve, interreflect, lobes, mesh_faults, rules, scheduling
from .executors import InProcess
from .progress import Job, Progress
from .statistics import rms


BOUNCE_PHASES = ("gather_setup_s", "bounces_s", "bounce_error_s")  # phase_times after the rays, bouncing
# A point is black within its noise when its transfer's norm is below NOISE_SPREAD standard errors and BLACK of the
# unshadowed transfer's norm: a point the rays find wholly blocked is not exactly zero where flat polygons' closed
# forms join its estimate (core.polygons), only within its noise (the wheel pushed into a body's arch of
# benchmarks/messy_assets.py: 48 of the 49 points inside the other part lie within 1.8 standard errors of black).
NOISE_SPREAD, BLACK = 3.0, 1e-4


@dataclass
class ReceiverResult:
    transfer: np.ndarray    # (V, n²) float32, or (V, 3, n²) for coloured interreflections
    std_error: np.ndarray   # (V,) norm of the standard error of the coefficients
    rel_error: np.ndarray   # (V,) std_error ÷ norm of the unshadowed transfer (0 without a surface)
    rays: np.ndarray        # (V,) int64
    skipped: np.ndarray     # (V,) bool: exact without rays (provably unoccluded, or in contact)
    rules: np.ndarray       # (V,) uint8: the rule that decided each point (core.rules), MEASURED where none did
    rel_rule_error: np.ndarray  # (V,) what that rule may have got wrong (core.rules.doubt), relative as rel_error


@dataclass
class Summary:
    objects: int
    vertices: int           # the points baked; the scene bake counts mesh vertices and split ones
    order: int
    mode: str
    samples: int
    rays: int
    skipped_vertices: int
    time_s: float
    rays_per_s: float
    est_rms_rel_error: float  # noise and the rules' doubt together (core.rules.estimate)
    est_max_rel_error: float
    workers: int = 1
    target_error: float = 0.0
    per_object: dict = field(default_factory=dict)
    phases_s: dict = field(default_factory=dict)   # seconds per phase: rays, gather setup, bounces
    bounces: int | None = None                     # interreflected: bounces run
    bounce_relative_changes: list = field(default_factory=list)  # relative change of each bounce
    bounce_tail: float = 0.0                       # geometric tail added after the last bounce (auto)
    bounces_converged: bool = True                 # False: auto bounces stopped at the limit, not converged
    albedo_clamped: bool = False
    split_vertices: int = 0  # vertices baked once per distinct corner normal
    points: int = 0          # shading points baked: the vertices and the split vertices' further normals
    # What storage per vertex loses between vertices (core.interpolation), from `interp_points` points inside faces
    # baked with `interp_rays` more rays; None when not measured.
    est_interp_rms_rel_error: float | None = None
    est_interp_max_rel_error: float | None = None
    interp_points: int = 0
    interp_rays: int = 0
    ray_engine: str = ""  # the engine that cast the rays, with its version ("" where none was cast)
    decided_by_rule: dict = field(default_factory=dict)  # points each rule decided (core.rules.counts), non-zero
    error_curve: list = field(default_factory=list)  # core.error_curve.Row after each round, bounces, texel lattices
    est_rule_rms_rel_error: float = 0.0  # the rules' part of est_rms_rel_error (core.rules.estimate)
    inside_another_part: int = 0  # points the rays found black inside another part (TransferJob.inside_another_part)
    dynamic: int = 0  # objects baked dynamic: each in its own frame, against itself only
    probe_volumes: int = 0  # probe volumes baked with the static scene (core.probe_transfer)
    probes: int = 0         # their probes
    probe_rays: int = 0     # the probes' rays, which `rays` leaves out

    def line(self) -> str:
        bounced = (f", {self.bounces} bounces in {self.phases_s.get('bounces_s', 0.0):.2f} s "
                   f"(last change {self.bounce_relative_changes[-1]:.1e})" if self.bounce_relative_changes else "")
        if not self.bounces_converged:
            bounced += f"; auto bounces NOT converged: stopped at the limit of {self.bounces} bounces"
        split = (f" ({self.split_vertices} split by their corner normals: {self.points} points)"
                 if self.split_vertices else "")
        between = ("" if self.est_interp_rms_rel_error is None else
                   f"; between vertices est. RMS {self.est_interp_rms_rel_error:.4f}, max "
                   f"{self.est_interp_max_rel_error:.4f} ({self.interp_points} points, {self.interp_rays} rays)")
        engine = f" with {self.ray_engine}" if self.ray_engine else ""
        ruled = f"; decided by rule: {rules.words(self.decided_by_rule)}" if self.decided_by_rule else ""
        doubt = (f" (of which decided by rule {self.est_rule_rms_rel_error:.4f})"
                 if round(self.est_rule_rms_rel_error, 4) else "")  # as printed: an exactly reversed normal has none
        if self.inside_another_part:
            ruled += f"; {self.inside_another_part} points inside another part (black)"
        dynamic = (f"; {self.dynamic} dynamic object{'s' if self.dynamic > 1 else ''}, each baked in its own frame "
                   f"against itself only" if self.dynamic else "")
        probes = (f"; {self.probes} probes in {self.probe_volumes} probe volume{'s' if self.probe_volumes > 1 else ''}"
                  f", {self.probe_rays} rays" if self.probe_volumes else "")
        return (f"PRT bake: {self.objects} objects, {self.vertices} vertices{split}, order {self.order} {self.mode}: "
                f"{self.time_s:.2f} s, {self.rays} rays, {self.rays_per_s / 1e3:.0f} k rays/s{engine}, "
                f"{self.skipped_vertices} vertices exact without rays, "
                f"est. RMS rel. error {self.est_rms_rel_error:.4f}{doubt}, max {self.est_max_rel_error:.4f}{between}"
                f"{bounced}{ruled}{dynamic}{probes}")

    def curve_line(self) -> str:
        """The bake's error against its run time in one line (core.error_curve), logged after line()."""
        return "PRT bake " + error_curve.line(self.error_curve)


class TransferJob(Job):
    """Bakes every receiver through an executor (core.executors: in this process, with workers, a farm shard's
    share, or from farm parts). Call step() until it returns True, or run() to do it all at once."""

    def __init__(self, receivers, occluders, settings: bake.BakeSettings, executor=None, albedo=None,
                 name: str = "bake"):
        """With `albedo`, one (V, C) array per receiver, the job bounces interreflections once it has every chunk's
        result; its occluders' first `solved_vertices` must then be the receivers' vertices in order (so a hit
        triangle's corners are solved vertices). Without, an interreflected job only records its rays' hits
        (`records`), for a gather from a solution made elsewhere (core.texel_gather). `name` tells the bake's jobs
        apart where their chunks are kept or read by name (farm parts)."""
        self.receivers = receivers
        self.occluders = occluders
        self.settings = settings
        self.executor = executor or InProcess()
        self.name = name
        self.chunks = scheduling.chunk_rows(receivers)
        self.run_by(self.executor)
        self.total_vertices = sum(len(r.positions) for r in receivers)
        self._vertex_offsets = np.cumsum([0] + [len(r.positions) for r in receivers])
        if albedo is not None and occluders.solved_vertices != self.total_vertices:
            raise ValueError(f"interreflection needs occluders that begin with the {self.total_vertices} solved "
                             f"vertices, not {occluders.solved_vertices}")
        self.done_vertices = 0
        self.rays = 0
        self.progress = Progress("PRT bake")
        order = settings.order
        # float32, as stored on the mesh: the job holds the whole mesh's transfer, chunks are float64
        self._transfer = [np.zeros((len(r.positions), order * order), dtype=np.float32) for r in receivers]
        self._std_error = [np.zeros(len(r.positions)) for r in receivers]
        self._rays = [np.zeros(len(r.positions), dtype=np.int64) for r in receivers]
        self._skipped = [np.zeros(len(r.positions), dtype=bool) for r in receivers]
        self._rules = [rules.measured(len(r.positions)) for r in receivers]
        self._curves = {}  # chunk index → its core.error_curve rows, summed in chunk order whatever order they came
        self._rule_error = [np.zeros(len(r.positions)) for r in receivers]
        self.records = []  # interreflected: HitRecords per chunk, rows already global
        self.albedo = albedo
        self.bounce_report = None
        self.direct = None  # interreflected: each receiver's transfer before the bounces, once they have run
        self.phase_times = {}
        self.shards_workers = 0  # a merge of farm shards: the processes their bakes asked for (FromParts)
        self._runner = None
        self.finished = False

    def run_by(self, executor):
        """Before the first step: the executor that bakes the job (its share of the chunks)."""
        self.executor = executor
        self.baked_chunks = executor.share(len(self.chunks))
        self.baked_vertices = sum(len(self.chunks[index][1]) for index in self.baked_chunks)

    @property
    def workers(self) -> int:
        return self.executor.workers

    def processes(self) -> int:
        """How many processes bake this job's chunks."""
        return self.executor.processes(len(self.baked_chunks), self.baked_vertices, self.settings)

    # -- running --------------------------------------------------------------------------------------
    def step(self, budget_s: float = 0.1) -> bool:
        """Works for about `budget_s` seconds; True once everything is baked."""
        if self.finished:
            return True
        if self._runner is None:
            self._runner = self.executor.run(self, self.baked_chunks, self._store)
        deadline = time.perf_counter() + budget_s
        while time.perf_counter() < deadline:
            if next(self._runner, StopIteration) is StopIteration:
                self.phase_times["rays_s"] = self.progress.elapsed
                if self.albedo is not None and self.executor.whole:
                    self._bounce()
                self.finished = True
                break
        self.progress.fraction = self.done_vertices / max(1, self.baked_vertices)
        return self.finished

    def outcome(self) -> list:
        return self.results()

    def cancel(self):
        if self._runner is not None:
            self._runner.close()
        self.finished = False

    def _store(self, chunk_index, result: bake.ChunkResult):
        receiver_index, rows = self.chunks[chunk_index]
        self._transfer[receiver_index][rows] = result.transfer
        self._std_error[receiver_index][rows] = result.std_error
        self._rays[receiver_index][rows] = result.rays
        self._skipped[receiver_index][rows] = result.skipped
        self._rules[receiver_index][rows] = result.rules
        self._curves[chunk_index] = result.curve
        self._rule_error[receiver_index][rows] = result.rule_error
        if result.records is not None:
            solved = self._vertex_offsets[receiver_index] + rows[result.records.vertex]
            self.records.append(interreflect.HitRecords(solved, result.records.triangle, result.records.barycentric,
                                                         result.records.weight, result.records.replicate))

    def _bounce(self):
        """Interreflections from the recorded hits: T_total = Σ_b (G ρ)^b T_direct, no new rays."""
        start = time.perf_counter()
        records = interreflect.HitRecords.concatenate(self.records)
        operator = interreflect.bounce_operator(records, self.occluders.triangles, self.total_vertices)
        self.phase_times["gather_setup_s"] = time.perf_counter() - start
        direct = np.concatenate(self._transfer).astype(np.float64)
        albedo = np.concatenate(self.albedo)
        total, self.bounce_report = interreflect.interreflect(
            direct, albedo, operator, self.settings.bounces, self.settings.bounce_tolerance)
        self.phase_times["bounces_s"] = self.bounce_report.time_s
        self.direct = np.split(direct, self._vertex_offsets[1:-1])
        self._transfer = np.split(total.astype(np.float32), self._vertex_offsets[1:-1])
        # The bounces gather over the same Monte Carlo rays: their noise joins the direct transfer's.
        start = time.perf_counter()
        gathered = interreflect.gather_std_error(records, self.occluders.triangles, direct, albedo,
                                                 self.settings.replicates, self.settings.bounces,
                                                 self.settings.bounce_tolerance)
        self._std_error = np.split(np.hypot(np.concatenate(self._std_error), gathered), self._vertex_offsets[1:-1])
        self.phase_times["bounce_error_s"] = time.perf_counter() - start

    # -- results --------------------------------------------------------------------------------------
    def results(self) -> list[ReceiverResult]:
        out = []
        scale = lobes.unshadowed_norm(self.settings.order)
        for index, receiver in enumerate(self.receivers):
            rel_error = self._std_error[index] / scale
            transfer = self._transfer[index]
            if transfer.ndim == 3 and transfer.shape[1] == 1:
                transfer = transfer[:, 0]  # grey: one channel, stored as (V, n²)
            out.append(ReceiverResult(transfer, self._std_error[index], rel_error,
                                      self._rays[index], self._skipped[index], self._rules[index],
                                      self._rule_error[index] / scale))
        return out

    def summary(self, results: list[ReceiverResult], receivers=None, elapsed: float | None = None) -> Summary:
        """receivers, elapsed: others than this job's (a texel bake's refinement runs several jobs); a merge's
        time adds its shards' commands' seconds (executors.FromParts)."""
        receivers = receivers or self.receivers
        own_s = self.progress.elapsed if elapsed is None else elapsed
        # A merge's rays were cast by its shards: its rate is over their seconds baking and its own (the bounces).
        baking_s = own_s + self.phase_times.get("shards_rays_s", 0.0)
        rel = np.concatenate([r.rel_error for r in results]) if results else np.zeros(0)
        doubt = np.concatenate([r.rel_rule_error for r in results]) if results else np.zeros(0)
        rays = int(sum(int(r.rays.sum()) for r in results))
        inside = self.inside_another_part(receivers, results)
        per_object = {
            receiver.name: {
                "vertices": len(receiver.positions),
                "rays": int(result.rays.sum()),
                "skipped_vertices": int(result.skipped.sum()),
                "decided_by_rule": rules.counts(result.rules),
                **rules.estimate(result.rel_error, result.rel_rule_error),
                "inside_another_part": count,
            }
            for receiver, result, count in zip(receivers, results, inside)
        }
        own, rays_s = self.results(), self.phase_times.get("rays_s", own_s) + self.phase_times.get("shards_rays_s", 0.0)
        curve = self.error_rows(rays_s, own, len(results))
        for index, receiver in enumerate(receivers[:len(results)]):
            per_object[receiver.name]["error_curve"] = self.error_rows(rays_s, own, len(results), index, curve)
        return Summary(
            objects=len(results), vertices=int(len(rel)), points=int(len(rel)), order=self.settings.order,
            mode=self.settings.mode,
            samples=self.settings.samples, rays=rays,
            skipped_vertices=int(sum(int(r.skipped.sum()) for r in results)),
            time_s=own_s + self.phase_times.get("shards_s", 0.0),
            rays_per_s=rays / baking_s if baking_s > 0 else 0.0,
            **rules.estimate(rel, doubt),
            workers=self.shards_workers or self.workers, target_error=self.settings.target_error, per_object=per_object,
            phases_s=dict(self.phase_times),
            bounces=self.bounce_report.bounces if self.bounce_report else None,
            bounce_relative_changes=list(self.bounce_report.relative_changes) if self.bounce_report else [],
            bounce_tail=self.bounce_report.tail if self.bounce_report else 0.0,
            bounces_converged=self.bounce_report.converged if self.bounce_report else True,
            albedo_clamped=bool(self.bounce_report and self.bounce_report.albedo_clamped),
            decided_by_rule=rules.total(entry["decided_by_rule"] for entry in per_object.values()),
            error_curve=curve, inside_another_part=sum(inside))

    def inside_another_part(self, receivers, results) -> list[int]:
        """Per receiver, how many of its points that rays measured black lie inside another part of the occluders
        (core.mesh_faults.points_inside): black in Cycles too, whose rays meet that part whichever way they leave,
        and named in the report so an artist sees them. Only the points black within their noise are tested, once
        per bake."""
        if self.occluders is None or not len(self.occluders.triangles):
            return [0] * len(results)
        scale = lobes.unshadowed_norm(self.settings.order)
        # Rays > 0: a farm shard holds zeros for the points other shards bake, which are not black.
        black = [(r.rules == rules.MEASURED) & (r.rays > 0) & (np.abs(s.normals).sum(1) > 0)
                 & (np.linalg.norm(r.transfer.reshape(len(r.rules), -1), axis=1)
                    <= NOISE_SPREAD * r.std_error + BLACK * scale)
                 for s, r in zip(receivers, results)]
        points = np.concatenate([s.positions[mask] for s, mask in zip(receivers, black)]) if results else []
        inside = mesh_faults.points_inside(np.reshape(points, (-1, 3)), self.occluders.vertices,
                                           self.occluders.triangles)
        return [int(part.sum()) for part in np.split(inside, np.cumsum([mask.sum() for mask in black])[:-1])]

    def error_rows(self, rays_s: float, own: list, stored: int, index=None, bake_rows=None) -> list:
        """The error against time (core.error_curve) of the `stored` first receivers (the others only bounce
        light), or of receiver `index` at the bake's seconds (`bake_rows`): after each round of its chunks, and
        after the bounces. `own`: this job's results; its chunks took `rays_s` seconds."""
        scale = lobes.unshadowed_norm(self.settings.order)
        kept = range(stored) if index is None else [index]
        curves = [self._curves[chunk] for chunk in sorted(self._curves) if self.chunks[chunk][0] in kept]
        points = sum(len(self.receivers[i].positions) for i in kept)
        if index is None:
            busy = sum(curve[-1, 0] for curve in self._curves.values())
            rows = error_curve.rounds(curves, points, scale, rays_s / busy if busy > 0 else 0.0)
        else:
            rows = error_curve.part(bake_rows, curves, points, scale)
        if self.bounce_report is not None and rows:
            bounced_s = (rows[-1].seconds + sum(self.phase_times.get(phase, 0.0) for phase in BOUNCE_PHASES)
                         if index is None else bake_rows[len(rows)].seconds)
            rows = error_curve.then(rows, error_curve.BOUNCES, bounced_s, rows[-1].rays,
                                    np.concatenate([rules.point_errors(own[i].rel_error, own[i].rel_rule_error)
                                                    for i in kept]))
        return rows
