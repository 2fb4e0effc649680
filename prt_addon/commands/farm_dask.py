"""`prt bake FILE --dask SCHEDULER` (or `--dask local:N`): one shard per worker thread of a Dask cluster, each a
`python -m prt_addon bake FILE --shard K/N` process on its worker (a fresh Blender per shard, as a farm task runs
it; the bpy module is not thread-safe), its part file sent back to be merged here.

Dask (the `distributed` package) is a pipeline dependency: imported only on this path, so the add-on in Blender
needs neither. The workers run the bpy module's Python with this package importable, and read FILE at the same
path as this process (a shared folder, as on any farm). The workers import this module to run its tasks: it
imports neither bpy (a worker's path may find Blender's scripts' `bpy` package first) nor the Blender layer.
"""

from contextlib import contextmanager
import os
import subprocess
import sys
import tempfile

from ..core import settings as spec
from ..core.errors import InputError

PACKAGE = __name__.split(".")[-3]  # the package's name where this runs from its parent folder: prt_addon
PACKAGE_PARENT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKERS_TIMEOUT_S = 60


@contextmanager
def parts_baked_on_dask(scheduler: str, blend_file: str, settings, receivers, log):
    """Bakes the saved file's shards on the cluster; yields their part files, in a folder removed afterwards."""
    if not blend_file:
        raise InputError("--dask bakes a saved .blend file: give one")
    arguments = bake_arguments(settings, receivers)
    with tempfile.TemporaryDirectory(prefix="prt_dask_") as folder, _client(scheduler) as client:
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


def bake_arguments(settings, receivers) -> list[str]:
    """The command-line options that bake these settings and receivers."""
    arguments = []
    for setting in spec.BAKE:
        value = getattr(settings, setting.name)
        arguments += ["--" + setting.name.replace("_", "-"), "auto" if value is None else str(value)]
    return arguments + (["--objects", ",".join(receivers)] if receivers else [])


def run_shard(blend_file: str, shard: tuple[int, int], arguments: list[str]) -> bytes:
    """A Dask task: bakes one shard in a new process on the worker; its part file's bytes. Raises (Dask retries
    it once) when the shard fails."""
    with tempfile.TemporaryDirectory(prefix="prt_shard_") as folder:
        part = os.path.join(folder, "part.npz")
        command = [sys.executable, "-m", PACKAGE, "bake", blend_file, "--shard", "%d/%d" % shard, "--out", part,
                   *arguments]
        path = os.pathsep.join(filter(None, [PACKAGE_PARENT, os.environ.get("PYTHONPATH")]))
        finished = subprocess.run(command, capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=path))
        if finished.returncode != 0:
            said = finished.stderr.strip().splitlines()
            raise RuntimeError(f"shard {shard[0]}/{shard[1]} failed: {said[-1] if said else finished.returncode}")
        with open(part, "rb") as baked:
            return baked.read()


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
