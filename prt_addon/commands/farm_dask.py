"""`prt bake FILE --dask SCHEDULER` (or `--dask local:N`): one shard per worker thread of a Dask cluster, their part
files merged here.

The Dask client runs in a fork of this process (its threads must never be in a process that forks again), so that
meanwhile this process reads and plans the bake, once (blender.request, blender.plan): the merge stores the parts
with that plan. With `local:N` the LocalCluster's workers are threads of the client process, and each of their
tasks asks this process for its shard: a fork of it, which has the whole plan already (receivers, occluders, probes,
and the ray tree), executes its share of the chunks in one process (the worker threads are the parallelism) and
writes its part. On a cluster of
its own each shard is a `prt bake FILE --shard K/N --workers 1` in a new process on its worker (as a farm task runs
it; the bpy module is not thread-safe), its part file's bytes sent back.

Dask (the `distributed` package) is a pipeline dependency: imported only on this path, so the add-on in Blender
needs neither. The workers run the bpy module's Python with this package importable, and read FILE at the same
path as this process (a shared folder, as on any farm). The workers import this module to run its tasks: it
imports neither bpy (a worker's path may find Blender's scripts' `bpy` package first) nor the Blender layer.
"""

from contextlib import contextmanager
import functools
import importlib.util
import itertools
import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading

from ..core import settings as spec
from ..core.errors import InputError

PACKAGE = __name__.split(".")[-3]  # the package's name where this runs from its parent folder: prt_addon
PACKAGE_PARENT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKERS_TIMEOUT_S = 60
POLL_S = 0.01  # how often the baking process looks for a local shard's end
# A LocalCluster's diagnostics, for a dashboard it does not have, sample the client process while the shards bake:
# 0.35 s of CPU in 6 s, taken from the shards on a machine whose cores they fill; 0.07 s without them.
LOCAL_CLUSTER_CONFIG = {"distributed.worker.profile.enabled": False,  # the worker threads' stacks every 10 ms
                        "distributed.admin.system-monitor.interval": "5s",  # CPU and memory plots, every 0.5 s
                        "distributed.admin.tick.interval": "1s"}  # a blocked event loop's warning, every 20 ms
_baking_process = None  # in the client process: the BakingProcess its local:N worker threads send their shards to


@contextmanager
def dask_bake(scheduler: str, blend_file: str, settings, receivers, log):
    """Starts baking the saved file's shards on the cluster (local:N or a scheduler's address); yields a DaskBake
    whose parts() are the part files, in a folder removed afterwards."""
    if not blend_file:
        raise InputError("--dask bakes a saved .blend file: give one")
    local_workers = _local_workers(scheduler)
    if importlib.util.find_spec("distributed") is None:  # the client process imports it, in parallel with this one
        raise InputError("--dask needs Dask's distributed package (pip install distributed)")
    with tempfile.TemporaryDirectory(prefix="prt_dask_") as folder:
        cluster = DaskBake(functools.partial(_parts_from_cluster, scheduler, local_workers, blend_file,
                                             bake_arguments(settings, receivers), folder, log),
                           local=local_workers is not None)
        try:
            yield cluster
        finally:
            cluster.close()


def _local_workers(scheduler: str) -> int | None:
    """local:N's N, checked; None for a scheduler's address."""
    if not scheduler.startswith("local:"):
        return None
    try:
        workers = int(scheduler.split(":", 1)[1])
    except ValueError:
        workers = 0
    if workers < 1:
        raise InputError(f"--dask local:N needs N ≥ 1 workers, not {scheduler!r}")
    return workers


def bake_arguments(settings, receivers) -> list[str]:
    """The command-line options that bake these settings and receivers (each named exactly, commas and all)."""
    arguments = []
    for setting in spec.BAKE:
        value = getattr(settings, setting.name)
        arguments += ["--" + setting.name.replace("_", "-"), "auto" if value is None else str(value)]
    return arguments + [option for name in receivers or () for option in ("--object", name)]


class DaskBake:
    """The shards' bake on the cluster, its Dask client in a fork of this process started at once (where the system
    cannot fork, the client runs in this process when parts() is called, and every shard in a new process). This
    process must start no thread of its own meanwhile: it forks the local shards."""

    def __init__(self, parts_from_cluster, local: bool):
        self._parts_from_cluster = parts_from_cluster  # a context manager: the client, yielding the part files
        self.pid = None
        self.forks_shards = False  # whether parts() bakes the shards in forks of this process (local:N)
        if not hasattr(os, "fork"):
            return
        self.forks_shards = local
        requests_in, requests = os.pipe()
        replies_in, replies = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        self.pid = os.fork()
        if self.pid == 0:  # the client: nothing may escape into the code it was forked from
            try:
                os.close(requests_in)
                os.close(replies)
                _client_process(parts_from_cluster, BakingProcess(requests, replies_in))
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(0)
        os.close(requests)
        os.close(replies_in)
        self._requests, self._replies = requests_in, replies
        self._finished = False

    def parts(self, bake_here) -> list[str]:
        """The shards' part files, once the cluster has baked them all. Meanwhile every local shard the client asks
        for is baked in a fork of this process, bake_here((K, N), part_file), its output into the file the client
        reads."""
        if self.pid is None:
            with self._parts_from_cluster() as parts:
                return parts
        running, pending, outcome = {}, b"", None  # running: forked shard → the client's request id
        try:
            while outcome is None or running:
                if outcome is None and select.select([self._requests], [], [], POLL_S)[0]:
                    received = os.read(self._requests, 65536)
                    *lines, pending = (pending + received).split(b"\n")
                    for message in map(json.loads, lines):
                        if "shard" in message:
                            running[_forked(bake_here, message)] = message["id"]
                        else:
                            outcome = message
                    if not received and outcome is None:
                        outcome = {"failed": "the Dask client ended without its parts"}
                elif outcome is not None:
                    select.select([], [], [], POLL_S)
                for child in list(running):
                    ended, status = os.waitpid(child, os.WNOHANG)
                    if ended:
                        self._reply(f"{running.pop(child)} {os.waitstatus_to_exitcode(status)}\n")
                if "failed" in (outcome or {}):
                    break  # the shards still running are of no use
        finally:
            for child in running:
                os.kill(child, signal.SIGKILL)
                os.waitpid(child, 0)
        self._finished = "parts" in outcome
        if not self._finished:
            raise InputError(outcome["failed"])
        return outcome["parts"]

    def _reply(self, line: str):
        try:
            os.write(self._replies, line.encode())
        except BrokenPipeError:  # the client ended: parts() hears it on the requests' pipe
            pass

    def close(self):
        """Waits for the client to close the cluster after it sent the parts; ends it at once otherwise."""
        if self.pid is None:
            return
        os.close(self._requests)
        os.close(self._replies)
        if not self._finished:
            os.kill(self.pid, signal.SIGTERM)
        os.waitpid(self.pid, 0)


def _forked(bake_here, request: dict) -> int:
    """Forks a child that runs bake_here for the request's shard, its stdout and stderr into the request's output
    file, and leaves with exit code 0, or 1 and a line saying why."""
    sys.stdout.flush()
    sys.stderr.flush()
    child = os.fork()
    if child == 0:  # nothing may escape into the code it was forked from
        code = 1
        try:
            said = open(request["output"], "w", encoding="utf-8")
            os.dup2(said.fileno(), 1)  # what Blender's C code prints
            os.dup2(said.fileno(), 2)
            sys.stdout = sys.stderr = said  # Python's own, wherever they pointed
            bake_here(tuple(request["shard"]), request["part"])
            code = 0
        except BaseException as failure:
            print(f"prt: error: {failure}", file=sys.stderr)
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    return child


def _client_process(parts_from_cluster, baking: "BakingProcess"):
    """The client's life: the shards baked on the cluster, their part files (or why not) sent to the baking process
    before the cluster closes, so the merge runs while it does."""
    global _baking_process
    _baking_process, sent = baking, False
    try:
        with parts_from_cluster() as parts:
            baking.send({"parts": parts})
            sent = True
    except BaseException as failure:
        if not sent:
            said = str(failure) if isinstance(failure, InputError) else f"{type(failure).__name__}: {failure}"
            baking.send({"failed": said})


class BakingProcess:
    """In the client process: the process it was forked from, which bakes local:N's shards, each in a fork of its
    own, and merges the parts. Worker threads send it their shards at once; each waits for its shard's exit code."""

    def __init__(self, requests: int, replies: int):
        self._requests = requests
        self._ids = itertools.count()
        self._writing, self._ended = threading.Lock(), threading.Condition()
        self._codes, self._gone = {}, False
        self._reader = threading.Thread(target=self._read_replies, args=(replies,), daemon=True)
        self._reader.start()

    def send(self, message: dict):
        with self._writing:
            os.write(self._requests, (json.dumps(message) + "\n").encode())

    def bake(self, shard: tuple[int, int], part: str, output: str) -> int:
        """Bakes the shard into the part file, its output into the file `output`; its exit code (-1 when the baking
        process ended without baking it)."""
        request = next(self._ids)
        self.send({"id": request, "shard": shard, "part": part, "output": output})
        with self._ended:
            self._ended.wait_for(lambda: request in self._codes or self._gone)
            return self._codes.pop(request, -1)

    def _read_replies(self, replies: int):
        with os.fdopen(replies) as lines:
            for line in lines:
                request, code = map(int, line.split())
                with self._ended:
                    self._codes[request] = code
                    self._ended.notify_all()
        with self._ended:
            self._gone = True
            self._ended.notify_all()


@contextmanager
def _parts_from_cluster(scheduler: str, local_workers: int | None, blend_file: str, arguments: list[str],
                        folder: str, log):
    """Submits one shard per worker thread and yields their part files in `folder` once all are baked; the client
    closes afterwards."""
    with _client(scheduler, local_workers) as client:
        shards = sum(client.nthreads().values())
        log(f"PRT dask: {shards} shards on {scheduler}")
        futures = [client.submit(run_shard, blend_file, (shard, shards), arguments, pure=False, retries=1)
                   for shard in range(1, shards + 1)]
        parts = []
        for shard, future in enumerate(futures, start=1):
            parts.append(os.path.join(folder, f"part_{shard}_of_{shards}.npz"))
            with open(parts[-1], "wb") as out:
                out.write(future.result())
            log(f"PRT dask: shard {shard}/{shards} done")
        yield parts


def run_shard(blend_file: str, shard: tuple[int, int], arguments: list[str]) -> bytes:
    """A Dask task: bakes one shard in a process of its own on the worker (one process: the worker threads are the
    parallelism), a fork of the baking process for local:N; its part file's bytes. Raises (Dask retries it once)
    when the shard fails."""
    with tempfile.TemporaryDirectory(prefix="prt_shard_") as folder:
        part, said = os.path.join(folder, "part.npz"), os.path.join(folder, "output.txt")
        if _baking_process is not None:
            code = _baking_process.bake(shard, part, said)
        else:
            command = ["bake", blend_file, "--shard", "%d/%d" % shard, "--out", part, *arguments, "--workers", "1"]
            path = os.pathsep.join(filter(None, [PACKAGE_PARENT, os.environ.get("PYTHONPATH")]))
            with open(said, "w", encoding="utf-8") as output:
                code = subprocess.run([sys.executable, "-m", PACKAGE, *command], stdout=output,
                                      stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONPATH=path)).returncode
        if code != 0:
            with open(said, encoding="utf-8", errors="replace") as output:
                lines = output.read().strip().splitlines()
            raise RuntimeError(f"shard {shard[0]}/{shard[1]} failed: {lines[-1] if lines else f'exit code {code}'}")
        with open(part, "rb") as baked:
            return baked.read()


@contextmanager
def _client(scheduler: str, local_workers: int | None):
    """A Dask client of the scheduler at this address, or of a LocalCluster of local_workers, closed afterwards. The
    LocalCluster's workers are threads of this process, one task each at a time: every task waits on its shard's
    own process, which is the parallelism, so worker processes would add only their start-up (seconds)."""
    import dask
    from dask.distributed import Client, LocalCluster
    if local_workers is not None:
        with dask.config.set(LOCAL_CLUSTER_CONFIG), LocalCluster(
                n_workers=local_workers, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            yield client
        return
    with Client(scheduler, timeout=WORKERS_TIMEOUT_S) as client:
        client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
        yield client
