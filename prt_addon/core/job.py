"""The bake job: the state machine that bakes every receiver's chunks in this process or with worker processes
(see workers), with progress, time left and cancel, and the results it hands back (per receiver, and a summary).

Both ways run `estimator.bake_chunk` on the same fixed chunks, so the results are bit-identical whatever the
number of workers. `step()` returns after a bounded amount of work so a modal operator stays responsive.
"""

from dataclasses import dataclass, field
import functools
import os
import queue
import tempfile
import threading
import time

import numpy as np

from . import bake, estimator, interreflect, job_file, lobes, scheduling
from .progress import Job, Progress
from .statistics import rms
from .workers import (FORK, FORK_MIN_RAYS, TYPICAL_RAYS_PER_S, WORKER_MIN_RAYS, WORKER_START_S, ChunkQueue,
                      ForkedWorker, SpawnedWorker, chunk_owners, chunks_of, read_lines, shard_chunks)


@dataclass
class ReceiverResult:
    transfer: np.ndarray    # (V, n²) float32, or (V, 3, n²) for coloured interreflections
    std_error: np.ndarray   # (V,) norm of the standard error of the coefficients
    rel_error: np.ndarray   # (V,) std_error ÷ norm of the unshadowed transfer (0 without a surface)
    rays: np.ndarray        # (V,) int64
    skipped: np.ndarray     # (V,) bool: exact without rays (provably unoccluded, or in contact)


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
    est_rms_rel_error: float
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
        return (f"PRT bake: {self.objects} objects, {self.vertices} vertices{split}, order {self.order} {self.mode}: "
                f"{self.time_s:.2f} s, {self.rays} rays, {self.rays_per_s / 1e3:.0f} k rays/s, "
                f"{self.skipped_vertices} vertices exact without rays, "
                f"est. RMS rel. error {self.est_rms_rel_error:.4f}, max {self.est_max_rel_error:.4f}{between}"
                f"{bounced}")


class TransferJob(Job):
    """Bakes every receiver. Call step() until it returns True, or run() to do it all at once."""

    def __init__(self, receivers, occluders, settings: bake.BakeSettings, workers: int = 1,
                 worker_command=None, albedo=None, owners=None, shard=None, gather_only: bool = False):
        """Interreflected bakes need `albedo`, one (V, C) array per receiver, and occluders whose first
        `solved_vertices` are the receivers' vertices in order (so a hit triangle's corners are solved vertices).
        `owners` fixes which process bakes each chunk when workers run (0: this one, k: worker k); by default
        spawned workers get chunk_owners' split and forked ones share a queue with this process.
        `shard` (K, N) bakes only farm shard K's chunks (workers.shard_chunks) and keeps their results for its part
        file (shard_results); interreflections are bounced where the parts are merged (take_parts).
        gather_only: an interreflected job whose receivers are not the solved surfaces (texels): it records its
        rays' hits (`records`) for a gather from a solution made elsewhere, and bounces nothing itself."""
        self.receivers = receivers
        self.occluders = occluders
        self.settings = settings
        self.workers = max(1, int(workers))
        self.worker_command = worker_command  # a command prefix (see job_file.worker_process_command) or FORK
        self.min_rays_for_workers = FORK_MIN_RAYS if worker_command == FORK else WORKER_MIN_RAYS
        self.worker_start_s = WORKER_START_S  # spawned workers: this process takes the share they start late
        self.owners = owners
        self.chunks = scheduling.chunk_rows(receivers)
        self.bake_only(shard)
        self.total_vertices = sum(len(r.positions) for r in receivers)
        self._vertex_offsets = np.cumsum([0] + [len(r.positions) for r in receivers])
        self.gather_only = gather_only
        if settings.mode == "interreflected" and not gather_only and occluders.solved_vertices != self.total_vertices:
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
        self.records = []  # interreflected: HitRecords per chunk, rows already global
        self.albedo = albedo
        self.bounce_report = None
        self.direct = None  # interreflected: each receiver's transfer before the bounces, once they have run
        self.phase_times = {}
        self.shards_workers = 0  # a merge of farm shards: the processes their bakes asked for (take_parts)
        self._runner = None
        self.finished = False

    def bake_only(self, shard):
        """Bakes only farm shard (K, N)'s chunks (workers.shard_chunks), keeping their results for its part file
        (shard_results), or every chunk for None. Called before the first step: a forked child of a process that
        gathered the whole bake takes its shard so."""
        self.shard = shard
        self.baked_chunks = range(len(self.chunks)) if shard is None else shard_chunks(len(self.chunks), *shard)
        self.shard_results = None if shard is None else {}
        self.baked_vertices = sum(len(self.chunks[index][1]) for index in self.baked_chunks)

    # -- running --------------------------------------------------------------------------------------
    def step(self, budget_s: float = 0.1) -> bool:
        """Works for about `budget_s` seconds; True once everything is baked."""
        if self.finished:
            return True
        if self._runner is None:
            self._runner = self._run_workers() if self.uses_workers() else self._run_here()
        deadline = time.perf_counter() + budget_s
        while time.perf_counter() < deadline:
            if next(self._runner, StopIteration) is StopIteration:
                self.phase_times["rays_s"] = self.progress.elapsed
                if self.settings.mode == "interreflected" and self.shard is None and not self.gather_only:
                    self._bounce()
                self.finished = True
                break
        self.progress.fraction = self.done_vertices / max(1, self.baked_vertices)
        return self.finished

    def uses_workers(self) -> bool:
        """Whether worker processes bake beside this one: only for enough rays to repay starting them."""
        return (self.workers > 1 and self.settings.mode != "unshadowed" and len(self.baked_chunks) >= self.workers
                and self.baked_vertices * self.settings.samples >= self.min_rays_for_workers)

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
        if self.shard_results is not None:
            self.shard_results[chunk_index] = result
        if result.records is not None:
            solved = self._vertex_offsets[receiver_index] + rows[result.records.vertex]
            self.records.append(interreflect.HitRecords(solved, result.records.triangle, result.records.barycentric,
                                                         result.records.weight, result.records.replicate))

    def _run_here(self):
        caster = self.occluders.ray_caster() if self.settings.mode != "unshadowed" else None
        yield
        for chunk_index in self.baked_chunks:
            yield from self._bake_chunk_here(caster, chunk_index)

    def take_parts(self, chunk_results, shards_time_s: float = 0.0, shards_rays_s: float = 0.0,
                   shards_workers: int = 0):
        """Merges farm shards: every chunk's result comes from their parts instead of being baked here; step() then
        bounces interreflections as after a bake. Their bake commands took `shards_time_s` in all, their bakes
        `shards_rays_s` (the span a one-process bake's rays per second are over), with `shards_workers` processes
        in all: the summary's rays per second and workers are theirs."""
        self.phase_times["shards_s"] = shards_time_s
        self.phase_times["shards_rays_s"] = shards_rays_s
        self.shards_workers = shards_workers
        self._runner = self._store_parts(chunk_results)

    def _store_parts(self, chunk_results):
        for chunk_index, result in chunk_results:
            self._store(chunk_index, result)
            self.done_vertices += len(self.chunks[chunk_index][1])
            self.rays += int(result.rays.sum())
            yield

    def _bake_chunk_here(self, caster, chunk_index):
        receiver_index, rows = self.chunks[chunk_index]
        work = estimator.bake_chunk(caster, self.receivers[receiver_index], rows, self.settings)
        while True:
            try:
                self.rays += next(work)
                yield
            except StopIteration as finished:
                self._store(chunk_index, finished.value)
                self.done_vertices += len(rows)
                return

    def _run_workers(self):
        """This process and N-1 worker processes bake the chunks. Spawned workers get fixed shares (they start a
        second late); forked workers and this process take the next chunk from a shared queue whenever they are
        free, so all finish together however the machine's load falls on them. Given `owners`, every process
        bakes the chunks it owns."""
        with tempfile.TemporaryDirectory(prefix="prt_bake_") as folder:
            forking = self.worker_command == FORK
            caster = self.occluders.ray_caster() if forking else None  # built before forking: shared
            if not forking:
                saved_job = os.path.join(folder, "job.npz")
                job_file.save_job(saved_job, self.receivers, self.occluders, self.settings)
            owners = self._chunk_owners(forking)
            shared_queue = ChunkQueue(self.baked_chunks) if owners is None else None
            mine = shared_queue if owners is None else chunks_of(owners, 0)
            workers, lines = [], queue.Queue()
            try:
                for worker in range(1, self.workers):
                    out_file = os.path.join(folder, f"result_{worker}.npz")
                    theirs = shared_queue if owners is None else chunks_of(owners, worker)
                    if owners is not None and not theirs:
                        continue  # a worker with no chunks is not worth starting
                    if forking:
                        started = ForkedWorker(functools.partial(
                            job_file.bake_chunks, caster, self.receivers, self.settings, theirs, out_file),
                            out_file + ".failed", shared_queue)
                    else:
                        started = SpawnedWorker(job_file.worker_process_command(self.worker_command, saved_job,
                                                                                out_file, theirs), folder)
                    workers.append((started, out_file))
                # Reader threads start after the last fork: a child has none of our threads, and a lock one of them
                # held at the fork would stay locked in the child forever
                for started, _ in workers:
                    threading.Thread(target=read_lines, args=(started.stdout, lines), daemon=True).start()
                if shared_queue is not None:
                    shared_queue.fill()
                caster = self.occluders.ray_caster()  # spawned workers start meanwhile
                running = len(workers)
                for chunk_index in mine:
                    yield from self._bake_chunk_here(caster, chunk_index)
                    running -= self._take_progress(lines, wait=0.0)
                while running:
                    running -= self._take_progress(lines, wait=0.05)
                    yield
                for started, out_file in workers:
                    failure = started.finish()
                    if failure is not None:
                        raise RuntimeError("bake worker failed: " + failure)
                    for chunk_index, result in job_file.load_results(out_file):
                        self._store(chunk_index, result)
            finally:
                for started, _ in workers:
                    started.kill()
                if shared_queue is not None:
                    shared_queue.close()

    def _chunk_owners(self, forking: bool) -> list[int] | None:
        """Which process bakes each chunk: `owners` if given, else chunk_owners' split for spawned workers, or
        None when forked workers share a queue with this process."""
        if self.owners is not None or forking:
            return self.owners
        split = chunk_owners(len(self.baked_chunks), self.workers, self._estimated_seconds(), self.worker_start_s)
        owners = [None] * len(self.chunks)  # a chunk another farm shard bakes has no owner here
        for chunk_index, owner in zip(self.baked_chunks, split):
            owners[chunk_index] = owner
        return owners

    def _estimated_seconds(self) -> float:
        """One process's time for the whole job, from the first round's rays at a typical rate."""
        return self.baked_vertices * self.settings.samples / TYPICAL_RAYS_PER_S

    def _take_progress(self, lines: queue.Queue, wait: float) -> int:
        """Counts the workers' progress lines; returns how many workers finished."""
        finished = 0
        while True:
            try:
                line = lines.get(timeout=wait) if wait else lines.get_nowait()
            except queue.Empty:
                return finished
            wait = 0.0
            if line is None:
                finished += 1
            elif line.startswith("PRT-PROGRESS "):
                vertices, rays = map(int, line.split()[1:3])
                self.done_vertices += vertices
                self.rays += rays

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
                                      self._rays[index], self._skipped[index]))
        return out

    def summary(self, results: list[ReceiverResult], receivers=None, elapsed: float | None = None) -> Summary:
        """receivers, elapsed: others than this job's (a texel bake's refinement runs several jobs); a merge's
        time adds its shards' commands' seconds (take_parts)."""
        receivers = receivers or self.receivers
        own_s = self.progress.elapsed if elapsed is None else elapsed
        # A merge's rays were cast by its shards: its rate is over their seconds baking and its own (the bounces).
        baking_s = own_s + self.phase_times.get("shards_rays_s", 0.0)
        rel = np.concatenate([r.rel_error for r in results]) if results else np.zeros(0)
        rays = int(sum(int(r.rays.sum()) for r in results))
        per_object = {
            receiver.name: {
                "vertices": len(receiver.positions),
                "rays": int(result.rays.sum()),
                "skipped_vertices": int(result.skipped.sum()),
                "est_rms_rel_error": rms(result.rel_error),
                "est_max_rel_error": float(result.rel_error.max(initial=0.0)),
            }
            for receiver, result in zip(receivers, results)
        }
        return Summary(
            objects=len(results), vertices=int(len(rel)), points=int(len(rel)), order=self.settings.order,
            mode=self.settings.mode,
            samples=self.settings.samples, rays=rays,
            skipped_vertices=int(sum(int(r.skipped.sum()) for r in results)),
            time_s=own_s + self.phase_times.get("shards_s", 0.0),
            rays_per_s=rays / baking_s if baking_s > 0 else 0.0,
            est_rms_rel_error=rms(rel), est_max_rel_error=float(rel.max(initial=0.0)),
            workers=self.shards_workers or self.workers, target_error=self.settings.target_error, per_object=per_object,
            phases_s=dict(self.phase_times),
            bounces=self.bounce_report.bounces if self.bounce_report else None,
            bounce_relative_changes=list(self.bounce_report.relative_changes) if self.bounce_report else [],
            bounce_tail=self.bounce_report.tail if self.bounce_report else 0.0,
            bounces_converged=self.bounce_report.converged if self.bounce_report else True,
            albedo_clamped=bool(self.bounce_report and self.bounce_report.albedo_clamped))

