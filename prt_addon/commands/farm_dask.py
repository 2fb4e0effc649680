"""`prt bake FILE --dask SCHEDULER` (or `--dask local:N`): one shard per worker thread of a Dask cluster, each a
`prt bake FILE --shard K/N --workers 1` in a process of its own (a fresh Blender per shard, as a farm task runs it;
the bpy module is not thread-safe), its part file sent back to be merged here.

With `local:N` the workers are threads of this process, and a shard's process is a fork of a shard server forked
from this process before the cluster starts: it has the bpy module imported already, where a new process would
spend about a second of CPU importing it again. On a cluster of its own each shard is a new `python -m prt_addon`.

Dask (the `distributed` package) is a pipeline dependency: imported only on this path, so the add-on in Blender
needs neither. The workers run the bpy module's Python with this package importable, and read FILE at the same
path as this process (a shared folder, as on any farm). The workers import this module to run its tasks: it
imports neither bpy (a worker's path may find Blender's scripts' `bpy` package first) nor the Blender layer.
"""

from contextlib import contextmanager
import itertools
import json
import os
import select
import subprocess
import sys
import tempfile
import threading

from ..core import settings as spec
from ..core.errors import InputError

PACKAGE = __name__.split(".")[-3]  # the package's name where this runs from its parent folder: prt_addon
PACKAGE_PARENT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKERS_TIMEOUT_S = 60
_shard_server = None  # local:N: the ShardServer this process's worker threads run their shards on


@contextmanager
def parts_baked_on_dask(scheduler: str, blend_file: str, settings, receivers, log):
    """Bakes the saved file's shards on the cluster; yields their part files, in a folder removed afterwards."""
    global _shard_server
    if not blend_file:
        raise InputError("--dask bakes a saved .blend file: give one")
    arguments = bake_arguments(settings, receivers)
    local = scheduler.startswith("local:")
    with tempfile.TemporaryDirectory(prefix="prt_dask_") as folder:
        _shard_server = ShardServer() if local else None  # forked before the cluster starts any thread
        try:
            with _client(scheduler) as client:
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
        finally:
            if _shard_server is not None:
                _shard_server.close()
                _shard_server = None
        yield parts


def bake_arguments(settings, receivers) -> list[str]:
    """The command-line options that bake these settings and receivers."""
    arguments = []
    for setting in spec.BAKE:
        value = getattr(settings, setting.name)
        arguments += ["--" + setting.name.replace("_", "-"), "auto" if value is None else str(value)]
    return arguments + (["--objects", ",".join(receivers)] if receivers else [])


def run_shard(blend_file: str, shard: tuple[int, int], arguments: list[str]) -> bytes:
    """A Dask task: bakes one shard in a process of its own on the worker (one process: the worker threads are the
    parallelism); its part file's bytes. Raises (Dask retries it once) when the shard fails."""
    with tempfile.TemporaryDirectory(prefix="prt_shard_") as folder:
        part, said = os.path.join(folder, "part.npz"), os.path.join(folder, "output.txt")
        command = ["bake", blend_file, "--shard", "%d/%d" % shard, "--out", part, *arguments, "--workers", "1"]
        if _shard_server is not None:
            code = _shard_server.run(command, said)
        else:
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


class ShardServer:
    """A fork of this process (which has the bpy module imported) that forks one child per command it is sent;
    the child runs the command line in its main thread and leaves with its exit code. Fork it while this process
    has no other thread: a lock another thread held at the fork would stay locked in the server for ever."""

    def __init__(self):
        requests, self._requests = os.pipe()
        replies_in, replies = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        self.pid = os.fork()
        if self.pid == 0:  # the server: nothing may escape into the code it was forked from
            try:
                os.close(self._requests)
                os.close(replies_in)
                _serve(requests, replies)
            finally:
                os._exit(0)
        os.close(requests)
        os.close(replies)
        self._ids = itertools.count()
        self._writing, self._ended = threading.Lock(), threading.Condition()
        self._codes, self._server_ended = {}, False
        self._reader = threading.Thread(target=self._read_replies, args=(replies_in,), daemon=True)
        self._reader.start()

    def run(self, command: list[str], output: str) -> int:
        """Runs `prt` with these arguments in a fork of the server, its stdout and stderr into the file `output`;
        its exit code (-1 when the server ended without running it)."""
        with self._writing:
            request = next(self._ids)
            os.write(self._requests, (json.dumps([request, command, output]) + "\n").encode())
        with self._ended:
            self._ended.wait_for(lambda: request in self._codes or self._server_ended)
            return self._codes.pop(request, -1)

    def _read_replies(self, replies: int):
        with os.fdopen(replies) as lines:
            for line in lines:
                request, code = map(int, line.split())
                with self._ended:
                    self._codes[request] = code
                    self._ended.notify_all()
        with self._ended:
            self._server_ended = True
            self._ended.notify_all()

    def close(self):
        """Ends the server once its running commands have ended."""
        os.close(self._requests)
        os.waitpid(self.pid, 0)
        self._reader.join()


def _serve(requests: int, replies: int):
    """The server's loop: forks a child for each request ([id, arguments, output file]) and replies "id code" as each
    child ends; returns when the requests' pipe is closed and every child has ended."""
    from .cli import main  # this process is the bpy module's: the command line imports at no cost
    running, waiting, pending = {}, True, b""
    while waiting or running:
        if waiting and select.select([requests], [], [], 0.01)[0]:
            received = os.read(requests, 65536)
            waiting = bool(received)
            *lines, pending = (pending + received).split(b"\n")
            for line in lines:
                request, command, output = json.loads(line)
                child = os.fork()
                if child == 0:
                    code = 1
                    try:
                        said = os.open(output, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
                        os.dup2(said, 1)
                        os.dup2(said, 2)
                        code = main(command)
                    finally:
                        sys.stdout.flush()
                        sys.stderr.flush()
                        os._exit(code)
                running[child] = request
        elif not waiting:
            select.select([], [], [], 0.01)
        while running:
            child, status = os.waitpid(-1, os.WNOHANG)
            if child == 0:
                break
            os.write(replies, f"{running.pop(child)} {os.waitstatus_to_exitcode(status)}\n".encode())


@contextmanager
def _client(scheduler: str):
    """A Dask client of the scheduler at this address, or of a LocalCluster for local:N, closed afterwards. The
    LocalCluster's N workers are threads of this process, one task each at a time: every task waits on its shard's
    own process, which is the parallelism, so worker processes would add only their start-up (seconds)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise InputError("--dask needs Dask's distributed package (pip install distributed)") from None
    if scheduler.startswith("local:"):
        try:
            workers = int(scheduler.split(":", 1)[1])
        except ValueError:
            workers = 0
        if workers < 1:
            raise InputError(f"--dask local:N needs N ≥ 1 workers, not {scheduler!r}")
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            yield client
        return
    with Client(scheduler, timeout=WORKERS_TIMEOUT_S) as client:
        client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
        yield client
