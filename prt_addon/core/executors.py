"""Executors: how a job's chunks get their results. One protocol for every way a bake runs, so a job never asks
how it is run:

- InProcess: this process bakes every chunk;
- ForkedWorkers: copies of this process (Linux, bpy module) bake beside it, taking chunks from a shared queue;
- SpawnedWorkers: new Blender (or Python) processes load the job from a file and bake fixed shares;
- FarmShard: one shard's share of the chunks, baked by a local executor, its results kept for a part file;
- FromParts: every chunk's result read from farm part files (the merge): no ray is cast.

An executor's `run(job, chunks, store)` is a generator: it yields after each bounded piece of work (the job's `step`
keeps to its time budget so), hands each chunk's result to store(chunk index, ChunkResult) and counts the job's
progress (job.done_vertices, job.rays). Every executor bakes `estimator.bake_chunk` on the same fixed chunks, so the
results are bit-identical whichever runs them.
"""

import functools
import os
import queue
import tempfile
import threading

from . import estimator, job_file
from .bake import BakeSettings
from .workers import (FORK_MIN_RAYS, WORKER_MIN_RAYS, WORKER_START_S, TYPICAL_RAYS_PER_S, ChunkQueue, ForkedWorker,
                      SpawnedWorker, chunk_owners, chunks_of, read_lines, shard_chunks)


def bake_here(job, caster, chunk_index, store):
    """Bakes one chunk in this process: yields between its rounds, counts its rays and vertices, stores it."""
    receiver_index, rows = job.chunks[chunk_index]
    work = estimator.bake_chunk(caster, job.receivers[receiver_index], rows, job.settings)
    while True:
        try:
            job.rays += next(work)
            yield
        except StopIteration as finished:
            store(chunk_index, finished.value)
            job.done_vertices += len(rows)
            return


class InProcess:
    """This process bakes every chunk."""
    workers = 1     # the processes asked for
    spawned = False  # whether its workers load their own copy of the job
    start_s = 0.0    # a worker's start-up, which this process takes on meanwhile
    whole = True     # its results are the whole job's (so the job bounces interreflections)

    def share(self, chunks: int) -> list[int]:
        """The chunks it produces results for, of a job of `chunks`."""
        return list(range(chunks))

    def processes(self, job_chunks: int, points: int, settings: BakeSettings) -> int:
        """How many processes bake `job_chunks` chunks of `points` points under these settings."""
        return 1

    def run(self, job, chunks, store):
        caster = job.occluders.ray_caster() if job.settings.mode != "unshadowed" else None
        yield
        for chunk_index in chunks:
            yield from bake_here(job, caster, chunk_index, store)


class _Workers(InProcess):
    """This process and `workers` − 1 worker processes, where the job has enough rays to repay starting them
    (`min_rays`); fewer, this process alone. `owners` (optional, one per chunk of the job: 0 this process, k
    worker k) fixes which process bakes each chunk."""
    min_rays = WORKER_MIN_RAYS

    def __init__(self, workers: int, owners=None):
        self.workers = max(1, int(workers))
        self.owners = owners

    def processes(self, job_chunks, points, settings) -> int:
        worth = (self.workers > 1 and settings.mode != "unshadowed" and job_chunks >= self.workers
                 and points * settings.samples >= self.min_rays)
        return self.workers if worth else 1

    def run(self, job, chunks, store):
        points = sum(len(job.chunks[index][1]) for index in chunks)
        if self.processes(len(chunks), points, job.settings) == 1:
            yield from super().run(job, chunks, store)
            return
        with tempfile.TemporaryDirectory(prefix="prt_bake_") as folder:
            owners = self._owners(job, chunks, points)
            shared_queue = ChunkQueue(chunks) if owners is None else None
            started = []
            try:
                for worker in range(1, self.workers):
                    theirs = shared_queue if owners is None else chunks_of(owners, worker)
                    if owners is not None and not theirs:
                        continue  # a worker with no chunks is not worth starting
                    out_file = os.path.join(folder, f"result_{worker}.npz")
                    started.append((self._start(job, theirs, out_file, shared_queue, folder), out_file))
                lines = queue.Queue()
                # Reader threads start after the last fork: a child has none of our threads, and a lock one of them
                # held at the fork would stay locked in the child forever
                for worker, _ in started:
                    threading.Thread(target=read_lines, args=(worker.stdout, lines), daemon=True).start()
                if shared_queue is not None:
                    shared_queue.fill()
                caster = job.occluders.ray_caster()  # spawned workers start meanwhile
                running = len(started)
                for chunk_index in shared_queue if owners is None else chunks_of(owners, 0):
                    yield from bake_here(job, caster, chunk_index, store)
                    running -= _take_progress(job, lines, wait=0.0)
                while running:
                    running -= _take_progress(job, lines, wait=0.05)
                    yield
                for worker, out_file in started:
                    failure = worker.finish()
                    if failure is not None:
                        raise RuntimeError("bake worker failed: " + failure)
                    for chunk_index, result in job_file.load_results(out_file):
                        store(chunk_index, result)
            finally:
                for worker, _ in started:
                    worker.kill()
                if shared_queue is not None:
                    shared_queue.close()

    def _owners(self, job, chunks, points) -> list | None:
        return self.owners


class ForkedWorkers(_Workers):
    """Copies of this process (Linux, with the bpy module): they start in milliseconds and share the ray tree built
    here before they fork, taking the next chunk from a queue shared with this process whenever they are free, so all
    finish together however the machine's load falls on them."""
    min_rays = FORK_MIN_RAYS

    def _start(self, job, theirs, out_file, shared_queue, folder):
        caster = job.occluders.ray_caster()  # built before forking: shared
        return ForkedWorker(functools.partial(job_file.bake_chunks, caster, job.receivers, job.settings, theirs,
                                              out_file), out_file + ".failed", shared_queue)


class SpawnedWorkers(_Workers):
    """New processes started with `command` (a prefix that runs a Python snippet with mathutils importable: see
    job_file.worker_process_command), each loading the job from a file: fixed shares of the chunks, this process
    taking the extra share that lets all finish together although the workers start `start_s` late."""
    spawned = True
    start_s = WORKER_START_S

    def __init__(self, workers: int, command, owners=None):
        super().__init__(workers, owners)
        self.command = command

    def _start(self, job, theirs, out_file, shared_queue, folder):
        saved_job = os.path.join(folder, "job.npz")
        if not os.path.exists(saved_job):
            job_file.save_job(saved_job, job.receivers, job.occluders, job.settings)
        return SpawnedWorker(job_file.worker_process_command(self.command, saved_job, out_file, theirs), folder)

    def _owners(self, job, chunks, points) -> list:
        """chunk_owners' split of the chunks baked here (`owners` where given); a chunk another farm shard bakes
        has no owner."""
        if self.owners is not None:
            return self.owners
        split = chunk_owners(len(chunks), self.workers, points * job.settings.samples / TYPICAL_RAYS_PER_S,
                             self.start_s)
        owners = [None] * len(job.chunks)
        for chunk_index, owner in zip(chunks, split):
            owners[chunk_index] = owner
        return owners


def _take_progress(job, lines: queue.Queue, wait: float) -> int:
    """Counts the workers' progress lines into the job; returns how many workers finished."""
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
            job.done_vertices += vertices
            job.rays += rays


class FarmShard:
    """Farm shard (K, N) of every job (workers.shard_chunks: K from 1), baked by `local` (in this process or with
    its workers); each job's chunk results are kept, by the job's name, for the shard's part file. Interreflections
    are bounced where the parts are merged."""
    whole = False

    def __init__(self, shard: tuple[int, int], local=None):
        self.shard = shard
        self.local = local or InProcess()
        self.workers, self.spawned, self.start_s = self.local.workers, self.local.spawned, self.local.start_s
        self.kept = {}  # job name → {chunk index: ChunkResult}

    def share(self, chunks: int) -> list[int]:
        return shard_chunks(chunks, *self.shard)

    def processes(self, job_chunks, points, settings) -> int:
        return self.local.processes(job_chunks, points, settings)

    def run(self, job, chunks, store):
        kept = self.kept.setdefault(job.name, {})

        def keeping(chunk_index, result):
            kept[chunk_index] = result
            store(chunk_index, result)
        yield from self.local.run(job, chunks, keeping)


class FromParts(InProcess):
    """Every chunk's result from farm part files: load(job name) gives a job's (chunk index, ChunkResult) pairs.
    The shards' commands took `time_s` in all, their bakes `rays_s` (the span a one-process bake's rays per second
    are over), with `workers` processes in all: the job's summary counts their seconds, rate and workers."""

    def __init__(self, load, time_s: float = 0.0, rays_s: float = 0.0, workers: int = 0):
        self.load = load
        self.time_s, self.rays_s, self.shard_workers = time_s, rays_s, workers

    def run(self, job, chunks, store):
        job.phase_times["shards_s"], job.phase_times["shards_rays_s"] = self.time_s, self.rays_s
        job.shards_workers = self.shard_workers
        for chunk_index, result in self.load(job.name):
            store(chunk_index, result)
            job.done_vertices += len(job.chunks[chunk_index][1])
            job.rays += int(result.rays.sum())
            yield
