"""A bake job: chunks run in this process or in worker processes, with progress, time left and cancel.

Both ways run `bake.bake_chunk` on the same fixed chunks, so the results are bit-identical whatever the
number of workers. `step()` returns after a bounded amount of work so a modal operator stays responsive.
"""

from dataclasses import dataclass, field
import functools
import json
import os
import queue
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

from . import bake, interreflect
from .progress import Progress


@dataclass
class ReceiverResult:
    transfer: np.ndarray    # (V, n²) float32, or (V, 3, n²) for coloured interreflections
    std_error: np.ndarray   # (V,) norm of the standard error of the coefficients
    rel_error: np.ndarray   # (V,) std_error ÷ norm of the unshadowed transfer (0 without a surface)
    rays: np.ndarray        # (V,) int64
    skipped: np.ndarray     # (V,) bool: provably unoccluded, exact without rays


@dataclass
class Summary:
    objects: int
    vertices: int
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
    phases: dict = field(default_factory=dict)     # seconds per phase: rays, gather setup, bounces
    bounces: int | None = None                     # interreflected: bounces run
    bounce_changes: list = field(default_factory=list)  # relative change of each bounce
    bounce_tail: float = 0.0                       # geometric tail added after the last bounce (auto)
    albedo_clamped: bool = False

    def line(self) -> str:
        bounced = (f", {self.bounces} bounces in {self.phases.get('bounces_s', 0.0):.2f} s "
                   f"(last change {self.bounce_changes[-1]:.1e})" if self.bounce_changes else "")
        return (f"PRT bake: {self.objects} objects, {self.vertices} vertices, order {self.order} {self.mode}: "
                f"{self.time_s:.2f} s, {self.rays} rays, {self.rays_per_s / 1e3:.0f} k rays/s, "
                f"{self.skipped_vertices} vertices exact without rays, "
                f"est. RMS rel. error {self.est_rms_rel_error:.4f}, max {self.est_max_rel_error:.4f}{bounced}")


# Starting a worker process costs about a second (importing bpy): below this many rays one process is faster.
WORKER_MIN_RAYS = 2_000_000
WORKER_START_S = 1.0
# FORK as the worker command forks this process instead (Linux, bpy module): a few milliseconds, and the
# workers share the ray tree already built here. Forked workers take chunks from a shared queue as they go.
FORK = "fork"
FORK_MIN_RAYS = 200_000
TYPICAL_RAYS_PER_S = 500_000  # one process on the demo scene, benchmarks/bake.py


def chunk_owners(chunks: int, processes: int, estimated_s: float, start_s: float = WORKER_START_S) -> list[int]:
    """Which process bakes each chunk (0: this one), interleaved so every process gets a similar mix of the
    scene. Workers start WORKER_START_S late, so this process takes the extra share that lets all finish
    together: t = (T + (N−1)·s)/N, this process T·(t/T), each worker (t − s). Any split gives the same bits."""
    time_each = (estimated_s + (processes - 1) * start_s) / processes
    shares = np.array([time_each] + [max(time_each - start_s, 0.0)] * (processes - 1))
    shares = shares / shares.sum() if shares.sum() > 0 else np.full(processes, 1.0 / processes)
    owners, taken = [], np.zeros(processes)
    for _ in range(chunks):
        owner = int(np.argmin((taken + 0.5) / np.maximum(shares, 1e-12)))
        owners.append(owner)
        taken[owner] += 1
    return owners


class TransferJob:
    """Bakes every receiver. Call step() until it returns True, or run() to do it all at once."""

    def __init__(self, receivers, occluders, settings: bake.BakeSettings, workers: int = 1,
                 worker_command=None, albedo=None):
        """Interreflected bakes need `albedo`, one (V, C) array per receiver, and occluders whose first
        vertices are the receivers' vertices in order (so a hit triangle's corners are solved vertices)."""
        self.receivers = receivers
        self.occluders = occluders
        self.settings = settings
        self.workers = max(1, int(workers))
        self.worker_command = worker_command  # a command prefix (see worker_process_command) or FORK
        self.min_rays_for_workers = FORK_MIN_RAYS if worker_command == FORK else WORKER_MIN_RAYS
        self.worker_start_s = WORKER_START_S  # spawned workers: this process takes the share they start late
        self.chunks = bake.chunk_ranges([len(r.positions) for r in receivers])
        self.total_vertices = sum(len(r.positions) for r in receivers)
        self._vertex_offsets = np.cumsum([0] + [len(r.positions) for r in receivers])
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
        self.phase_times = {}
        self._runner = None
        self.finished = False

    # -- running --------------------------------------------------------------------------------------
    def step(self, budget_s: float = 0.1) -> bool:
        """Works for about `budget_s` seconds; True once everything is baked."""
        if self.finished:
            return True
        if self._runner is None:
            use_workers = (self.workers > 1 and self.settings.mode != "unshadowed"
                           and len(self.chunks) >= self.workers
                           and self.total_vertices * self.settings.samples >= self.min_rays_for_workers)
            self._runner = self._run_workers() if use_workers else self._run_here()
        deadline = time.perf_counter() + budget_s
        while time.perf_counter() < deadline:
            if next(self._runner, StopIteration) is StopIteration:
                self.phase_times["rays_s"] = self.progress.elapsed
                if self.settings.mode == "interreflected":
                    self._bounce()
                self.finished = True
                break
        self.progress.fraction = self.done_vertices / max(1, self.total_vertices)
        return self.finished

    def run(self, report=None, budget_s: float = 0.5):
        """Runs to the end; `report(progress)` is called after each step (background logs)."""
        while not self.step(budget_s):
            if report:
                report(self.progress)
        if report:
            report(self.progress)
        return self.results()

    def cancel(self):
        if self._runner is not None:
            self._runner.close()
        self.finished = False

    def _store(self, chunk_index, result: bake.ChunkResult):
        receiver_index, start, stop = self.chunks[chunk_index]
        self._transfer[receiver_index][start:stop] = result.transfer
        self._std_error[receiver_index][start:stop] = result.std_error
        self._rays[receiver_index][start:stop] = result.rays
        self._skipped[receiver_index][start:stop] = result.skipped
        if result.records is not None:
            offset = self._vertex_offsets[receiver_index] + start
            self.records.append(interreflect.HitRecords(result.records.vertex + offset, result.records.triangle,
                                                         result.records.barycentric, result.records.weight))

    def _run_here(self):
        caster = bake.RayCaster(self.occluders) if self.settings.mode != "unshadowed" else None
        yield
        for chunk_index in range(len(self.chunks)):
            yield from self._bake_chunk_here(caster, chunk_index)

    def _bake_chunk_here(self, caster, chunk_index):
        receiver_index, start, stop = self.chunks[chunk_index]
        work = bake.bake_chunk(caster, self.receivers[receiver_index], start, stop, self.settings)
        while True:
            try:
                self.rays += next(work)
                yield
            except StopIteration as finished:
                self._store(chunk_index, finished.value)
                self.done_vertices += stop - start
                return

    def _run_workers(self):
        """This process and N-1 worker processes bake the chunks. Spawned workers get fixed shares (they start a
        second late); forked workers and this process take the next chunk from a shared queue whenever they are
        free, so all finish together however the machine's load falls on them."""
        with tempfile.TemporaryDirectory(prefix="prt_bake_") as folder:
            forking = self.worker_command == FORK
            caster = bake.RayCaster(self.occluders) if forking else None  # built once, before forking: shared
            if forking:
                queue_of_chunks = _ChunkQueue(range(len(self.chunks)))
                mine = queue_of_chunks
            else:
                job_file = os.path.join(folder, "job.npz")
                save_job(job_file, self.receivers, self.occluders, self.settings)
                owners = chunk_owners(len(self.chunks), self.workers, self._estimated_seconds(), self.worker_start_s)
                mine = [index for index, owner in enumerate(owners) if owner == 0]
            workers, lines = [], queue.Queue()
            try:
                for worker in range(1, self.workers):
                    out_file = os.path.join(folder, f"result_{worker}.npz")
                    if forking:
                        started = _ForkedWorker(functools.partial(
                            bake_chunks, caster, self.receivers, self.settings, queue_of_chunks, out_file),
                            out_file + ".failed", queue_of_chunks)
                    else:
                        theirs = [index for index, owner in enumerate(owners) if owner == worker]
                        if not theirs:
                            continue
                        started = _SpawnedWorker(worker_process_command(self.worker_command, job_file, out_file,
                                                                        theirs))
                    threading.Thread(target=_read_lines, args=(started.stdout, lines), daemon=True).start()
                    workers.append((started, out_file))
                if forking:
                    queue_of_chunks.fill()
                caster = caster or bake.RayCaster(self.occluders)  # spawned workers start meanwhile
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
                    for chunk_index, result in load_results(out_file):
                        self._store(chunk_index, result)
            finally:
                for started, _ in workers:
                    started.kill()
                if forking:
                    queue_of_chunks.close()

    def _estimated_seconds(self) -> float:
        """One process's time for the whole job, from the first round's rays at a typical rate."""
        return self.total_vertices * self.settings.samples / TYPICAL_RAYS_PER_S

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
        total, self.bounce_report = interreflect.interreflect(
            direct, np.concatenate(self.albedo), operator, self.settings.bounces, self.settings.bounce_tolerance)
        self.phase_times["bounces_s"] = self.bounce_report.time_s
        self._transfer = np.split(total.astype(np.float32), self._vertex_offsets[1:-1])

    # -- results --------------------------------------------------------------------------------------
    def results(self) -> list[ReceiverResult]:
        out = []
        scale = bake.unshadowed_norm(self.settings.order)
        for index, receiver in enumerate(self.receivers):
            rel_error = self._std_error[index] / scale
            transfer = self._transfer[index]
            if transfer.ndim == 3 and transfer.shape[1] == 1:
                transfer = transfer[:, 0]  # grey: one channel, stored as (V, n²)
            out.append(ReceiverResult(transfer, self._std_error[index], rel_error,
                                      self._rays[index], self._skipped[index]))
        return out

    def summary(self, results: list[ReceiverResult]) -> Summary:
        elapsed = self.progress.elapsed
        rel = np.concatenate([r.rel_error for r in results]) if results else np.zeros(0)
        rays = int(sum(int(r.rays.sum()) for r in results))
        per_object = {
            receiver.name: {
                "vertices": len(receiver.positions),
                "rays": int(result.rays.sum()),
                "skipped_vertices": int(result.skipped.sum()),
                "est_rms_rel_error": _rms(result.rel_error),
                "est_max_rel_error": float(result.rel_error.max(initial=0.0)),
            }
            for receiver, result in zip(self.receivers, results)
        }
        return Summary(
            objects=len(results), vertices=int(len(rel)), order=self.settings.order, mode=self.settings.mode,
            samples=self.settings.samples, rays=rays,
            skipped_vertices=int(sum(int(r.skipped.sum()) for r in results)),
            time_s=elapsed, rays_per_s=rays / elapsed if elapsed > 0 else 0.0,
            est_rms_rel_error=_rms(rel), est_max_rel_error=float(rel.max(initial=0.0)),
            workers=self.workers, target_error=self.settings.target_error, per_object=per_object,
            phases=dict(self.phase_times),
            bounces=self.bounce_report.bounces if self.bounce_report else None,
            bounce_changes=list(self.bounce_report.relative_changes) if self.bounce_report else [],
            bounce_tail=self.bounce_report.tail if self.bounce_report else 0.0,
            albedo_clamped=bool(self.bounce_report and self.bounce_report.albedo_clamped))


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else 0.0


def _read_lines(stream, lines: queue.Queue):
    for line in stream:
        lines.put(line.strip())
    lines.put(None)


def _worker_environment():
    # One BLAS thread per worker: the workers are the parallelism.
    return dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")


class _SpawnedWorker:
    """A new process running `command`; its progress lines come on stdout, a failure's message on stderr."""

    def __init__(self, command):
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        env=_worker_environment())
        self.stdout = self.process.stdout

    def finish(self) -> str | None:
        """Waits for the worker; None when it succeeded, else the last line of what it said."""
        if self.process.wait() == 0:
            return None
        message = self.process.stderr.read().strip().splitlines()
        return message[-1] if message else f"exit code {self.process.returncode}"

    def kill(self):
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


class _ChunkQueue:
    """Chunk indices in a pipe shared by this process and its forked workers. Each read of one 4-byte record
    takes the next chunk atomically, so whichever process is free bakes it. Fill it after forking: a thread
    writes the records in blocks of at most PIPE_BUF bytes (whole records, atomic) and then closes the pipe, so
    a read that finds it empty and closed ends the queue."""

    def __init__(self, indices):
        self._records = np.asarray(list(indices), dtype="<i4").tobytes()
        self._read, self._write = os.pipe()
        self._filling = False

    def fill(self):
        self._filling = True
        threading.Thread(target=self._feed, daemon=True).start()

    def _feed(self):
        try:
            for start in range(0, len(self._records), 4096):
                os.write(self._write, self._records[start:start + 4096])
        except OSError:  # everyone stopped reading: a cancelled or failed bake
            pass
        finally:
            os.close(self._write)

    def in_worker(self):
        """A forked worker keeps only the reading end: the queue ends when this process's writer closes."""
        os.close(self._write)

    def __iter__(self):
        while record := os.read(self._read, 4):
            yield int.from_bytes(record, "little")

    def close(self):
        os.close(self._read)
        if not self._filling:  # the bake stopped before the queue was filled: its writer closes nothing
            os.close(self._write)


class _ForkedWorker:
    """A fork of this process running work(stream): it inherits the scene and the ray tree, so it starts in
    milliseconds. It leaves with os._exit, never running this process's exit handlers."""

    def __init__(self, work, failure_file, chunks: _ChunkQueue):
        read, write = os.pipe()
        self._failure_file = failure_file
        self.pid = os.fork()
        if self.pid == 0:  # the child: nothing may escape into the parent's code it was forked from
            code = 1
            try:
                os.close(read)
                chunks.in_worker()
                with os.fdopen(write, "w") as stream:
                    work(stream)
                code = 0
            except BaseException as error:  # whatever it is, the child reports it and leaves
                with open(self._failure_file, "w", encoding="utf-8") as failure:
                    failure.write(f"{type(error).__name__}: {error}")
            finally:
                os._exit(code)
        os.close(write)
        self.stdout = os.fdopen(read, "r")
        self._code = None

    def finish(self) -> str | None:
        """Waits for the worker; None when it succeeded, else what went wrong."""
        if self._code is None:
            self._code = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
        if self._code == 0:
            return None
        if not os.path.exists(self._failure_file):
            return f"exit code {self._code}"
        with open(self._failure_file, encoding="utf-8") as failure:
            return failure.read().strip()

    def kill(self):
        if self._code is None:
            os.kill(self.pid, signal.SIGKILL)
            self._code = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])


# -- the worker side ----------------------------------------------------------------------------------
def worker_process_command(python_prefix, job_file, out_file, chunk_indices):
    """`python_prefix` runs a Python snippet with mathutils importable: [python, '-c'] with the bpy module,
    [blender, '--background', '--factory-startup', '--python-expr'] in a real Blender."""
    package_parent = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    package = __name__.rsplit(".", 2)[0].rsplit(".", 1)[-1]
    snippet = (
        "import sys\n"
        "try:\n    import bpy\nexcept ImportError:\n    pass\n"
        f"sys.path.insert(0, {package_parent!r})\n"
        f"from {package}.core import job\n"
        f"job.worker_main({job_file!r}, {out_file!r}, {list(chunk_indices)!r})\n"
    )
    return [*python_prefix, snippet]


def save_job(path, receivers, occluders, settings: bake.BakeSettings):
    arrays = {"occluder_vertices": occluders.vertices, "occluder_triangles": occluders.triangles,
              "occluder_hull": occluders.hull}
    arrays.update({f"polygon_{index}": polygon for index, polygon in enumerate(occluders.polygons)})
    for index, receiver in enumerate(receivers):
        arrays[f"positions_{index}"] = receiver.positions
        arrays[f"normals_{index}"] = receiver.normals
        if receiver.inward is not None:
            arrays[f"inward_{index}"] = receiver.inward
    meta = {"settings": settings.__dict__, "receivers": [[r.name, r.key] for r in receivers]}
    np.savez(path, meta=np.array(json.dumps(meta)), **arrays)


def load_job(path):
    with np.load(path) as data:
        meta = json.loads(str(data["meta"]))
        flat = [data[f"polygon_{index}"] for index in range(sum(name.startswith("polygon_") for name in data.files))]
        occluders = bake.Occluders(data["occluder_vertices"], data["occluder_triangles"], data["occluder_hull"], flat)
        receivers = [bake.Receiver(name, data[f"positions_{i}"], data[f"normals_{i}"], key,
                                   data[f"inward_{i}"] if f"inward_{i}" in data else None)
                     for i, (name, key) in enumerate(meta["receivers"])]
    return receivers, occluders, bake.BakeSettings(**meta["settings"])


def load_results(path) -> list[tuple[int, bake.ChunkResult]]:
    """(chunk index, result) for every chunk a worker baked."""
    with np.load(path) as data:
        return [(int(chunk_index), bake.ChunkResult(data[f"transfer_{i}"], data[f"std_error_{i}"], data[f"rays_{i}"],
                                                     data[f"skipped_{i}"], _load_records(data, i)))
                for i, chunk_index in enumerate(data["chunks"])]


def _load_records(data, slot):
    if f"records_vertex_{slot}" not in data:
        return None
    return interreflect.HitRecords(*(data[f"records_{name}_{slot}"]
                                     for name in ("vertex", "triangle", "barycentric", "weight")))


def bake_chunks(caster, receivers, settings, chunk_indices, out_file, stream):
    """A worker's work: bakes the chunks it is given (a list, or a shared queue it takes them from) with a
    progress line on `stream` after each, then saves the results and which chunks they are."""
    chunks = bake.chunk_ranges([len(r.positions) for r in receivers])
    arrays, done = {}, []
    for slot, chunk_index in enumerate(chunk_indices):
        receiver_index, start, stop = chunks[chunk_index]
        work = bake.bake_chunk(caster, receivers[receiver_index], start, stop, settings)
        rays = 0
        while True:
            try:
                rays += next(work)
            except StopIteration as finished:
                result = finished.value
                break
        for name in ("transfer", "std_error", "rays", "skipped"):
            arrays[f"{name}_{slot}"] = getattr(result, name)
        if result.records is not None:
            for name in ("vertex", "triangle", "barycentric", "weight"):
                arrays[f"records_{name}_{slot}"] = getattr(result.records, name)
        done.append(chunk_index)
        print(f"PRT-PROGRESS {stop - start} {rays}", file=stream, flush=True)
    np.savez(out_file, chunks=np.array(done, dtype=np.int64), **arrays)


def worker_main(job_file, out_file, chunk_indices):
    """Runs in a spawned worker process: loads the job, builds its own ray tree, bakes its chunks."""
    receivers, occluders, settings = load_job(job_file)
    bake_chunks(bake.RayCaster(occluders), receivers, settings, chunk_indices, out_file, sys.stdout)
