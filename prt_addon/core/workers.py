"""Worker processes of a bake: what one costs, which chunks each process takes, and the two ways to run one.

A spawned worker is a new Python (or Blender) process that loads the job from a file; a forked worker is a copy
of this process, which inherits the scene and the ray tree. Either reports a progress line per chunk on its
stdout and leaves its results in a file (see job_file).
"""

import os
import queue
import signal
import subprocess
import threading

import numpy as np

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


def chunks_of(owners: list, process: int) -> list[int]:
    """The chunks `process` owns."""
    return [index for index, owner in enumerate(owners) if owner == process]


def shard_chunks(chunks: int, shard: int, shards: int) -> list[int]:
    """The chunks farm shard K of N bakes (K from 1, as farm frame ranges count): chunk_owners' interleaved split
    into N equal shares, so every shard gets a similar mix of the scene; chunk i goes to shard i mod N + 1. Taken
    directly, in the share's size whatever N is (a part file's N may be any number)."""
    return list(range(shard - 1, chunks, shards))


def read_lines(stream, lines: queue.Queue):
    """Puts every line of a worker's `stream` on `lines`, then None once the worker closed it."""
    for line in stream:
        lines.put(line.strip())
    lines.put(None)


def _worker_environment(temporary_folder):
    """One BLAS thread per worker (the workers are the parallelism), and the bake's temporary folder as the
    worker's: the Blender it imports makes its own blender_* folder there, which a killed worker cannot remove
    and the bake removes with the folder."""
    return dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
                TMPDIR=temporary_folder, TEMP=temporary_folder, TMP=temporary_folder)


class SpawnedWorker:
    """A new process running `command`, its temporary files in `temporary_folder`; its progress lines come on
    stdout, a failure's message on stderr."""

    def __init__(self, command, temporary_folder):
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        env=_worker_environment(temporary_folder))
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


class ChunkQueue:
    """Chunk indices in a pipe shared by this process and its forked workers. Each read of one 4-byte record
    takes the next chunk atomically, so whichever process is free bakes it. Fill it after forking: the `filler`
    thread writes the records in blocks of at most PIPE_BUF bytes (whole records, atomic) and then closes the
    pipe, so a read that finds it empty and closed ends the queue."""

    def __init__(self, indices):
        self._records = np.asarray(list(indices), dtype="<i4").tobytes()
        self._read, self._write = os.pipe()
        self.filler = None

    def fill(self):
        self.filler = threading.Thread(target=self._feed, daemon=True)
        self.filler.start()

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
        if self.filler is None:  # the bake stopped before the queue was filled: its writer closes nothing
            os.close(self._write)


class ForkedWorker:
    """A fork of this process running work(stream): it inherits the scene and the ray tree, so it starts in
    milliseconds. When it takes its chunks from `shared_queue`, it lets go of the queue's writing end. It leaves
    with os._exit, never running this process's exit handlers."""

    def __init__(self, work, failure_file, shared_queue: ChunkQueue | None = None):
        read, write = os.pipe()
        self._failure_file = failure_file
        self.pid = os.fork()
        if self.pid == 0:  # the child: nothing may escape into the parent's code it was forked from
            code = 1
            try:
                os.close(read)
                if shared_queue is not None:
                    shared_queue.in_worker()
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
