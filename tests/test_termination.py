"""SIGTERM, which a farm manager sends to stop a task, ends `prt bake` (in one process, with forked or spawned
worker processes, as a farm shard) the way Ctrl+C does: exit code 143 and one line, the input file as it was, no
worker left running and nothing left in the process's TMPDIR (neither the bake's prt_bake_* folder nor the bpy
module's blender_* one). Each command runs in a process of its own, as a farm runs it."""

import os
import signal
import tempfile

import bpy  # noqa: F401  (before mathutils, which the core imports)
import numpy as np
import pytest

from conftest import start_cli, wait_until
from prt_addon.core import bake, executors, job

TERMINATED_LINE = "prt: error: terminated (SIGTERM); nothing was written"
SAMPLES = "16384"  # suzanne at this many rays a vertex bakes for tens of seconds: still baking when signalled
# The real command with spawned worker processes, which the bpy module uses where it cannot fork (macOS, Windows)
SPAWNING = ("import sys\n"
            "import bpy\n"
            "from prt_addon.blender import execute\n"
            "from prt_addon.core import executors\n"
            "execute.local_executor = lambda workers: executors.SpawnedWorkers(workers, [sys.executable, '-c'])\n"
            "from prt_addon.commands.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid`, from /proc."""
    found = []
    for entry in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{entry}/stat") as stat:
                parent = int(stat.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):  # ended meanwhile
            continue
        if parent == pid:
            found.append(int(entry))
    return found


def alive(pid: int) -> bool:
    """Whether `pid` runs: it exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] not in "ZX"
    except OSError:
        return False


def temporary(folder) -> list[str]:
    return sorted(os.listdir(folder / "tmp"))


def terminated(process, folder, before: bytes, path):
    """Sends SIGTERM and checks the end: exit 143, the one line, the file as it was, an empty TMPDIR."""
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=120)
    errors = (folder / "stderr.txt").read_text()
    assert process.returncode == 143, errors
    assert [line for line in errors.splitlines() if line.startswith("prt:")] == [TERMINATED_LINE], errors
    assert path.read_bytes() == before
    assert temporary(folder) == []


@pytest.fixture
def suzanne(tmp_path, sample_scene_files):
    path = tmp_path / "suzanne.blend"
    path.write_bytes((sample_scene_files / "suzanne.blend").read_bytes())
    return path


def bake_started(folder, process, workers: int, blender_folders: int = 1):
    """Waits until the bake runs: in one process, its first progress line; else its worker processes started, in
    its prt_bake_* folder, and the bpy module started in `blender_folders` processes (a spawned worker makes its
    own blender_* folder, a forked one shares its parent's). Returns the workers' process ids."""
    if workers == 1:
        wait_until(lambda: " left " in (folder / "stdout.txt").read_text(), "progress line", process)
        return []
    wait_until(lambda: [name for name in temporary(folder) if name.startswith("prt_bake_")], "prt_bake_* folder",
               process)
    wait_until(lambda: len(list((folder / "tmp").rglob("blender_*"))) >= blender_folders, "blender_* folders",
               process)
    return wait_until(lambda: len(children(process.pid)) >= workers - 1 and children(process.pid),
                      "worker processes", process)


@pytest.mark.parametrize("workers, command, blender_folders", [(1, None, 1), (2, None, 1), (2, ("-c", SPAWNING), 2)],
                         ids=["in one process", "forked workers", "spawned workers"])
def test_sigterm_during_a_bake_ends_it_as_ctrl_c_and_leaves_nothing(suzanne, tmp_path, workers, command,
                                                                    blender_folders):
    before = suzanne.read_bytes()
    process = start_cli(["bake", suzanne, "--samples", SAMPLES, "--workers", workers], tmp_path,
                        **({"command": command} if command else {}))
    try:
        workers_running = bake_started(tmp_path, process, workers, blender_folders)
        terminated(process, tmp_path, before, suzanne)
    finally:
        process.kill()
        process.wait()
    assert not [pid for pid in workers_running if alive(pid)]


def test_sigterm_during_a_farm_shard_writes_no_part(suzanne, tmp_path):
    before = suzanne.read_bytes()
    parts = tmp_path / "parts"
    process = start_cli(["bake", suzanne, "--samples", SAMPLES, "--workers", 2, "--shard", "1/2",
                         "--out", parts / "part_1.npz"], tmp_path)
    try:
        workers_running = bake_started(tmp_path, process, 2)
        terminated(process, tmp_path, before, suzanne)
    finally:
        process.kill()
        process.wait()
    assert not [pid for pid in workers_running if alive(pid)]
    assert not parts.exists() or list(parts.iterdir()) == []  # neither the part nor a partial one


def test_sigterm_while_blender_starts_is_taken_once_the_command_runs(suzanne, tmp_path):
    """SIGTERM as soon as the bpy module has made its blender_* folder, while it starts: held back until the command
    takes it, so that the folder is removed as the process ends."""
    before = suzanne.read_bytes()
    process = start_cli(["bake", suzanne, "--samples", SAMPLES], tmp_path)
    try:
        wait_until(lambda: [name for name in temporary(tmp_path) if name.startswith("blender_")],
                   "blender_* folder", process)
        terminated(process, tmp_path, before, suzanne)
    finally:
        process.kill()
        process.wait()


def test_a_job_stopped_between_its_steps_ends_its_workers_and_removes_its_folder(tmp_path, monkeypatch):
    """Ctrl+C or SIGTERM can land in Job.run between two steps, outside the loop that runs the workers: the run
    cancels the job on the way out, so its forked worker is ended and its prt_bake_* folder removed before the
    caller hears of it, not whenever Python's garbage collector gets to the job."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    positions = np.column_stack([np.linspace(-1.0, 1.0, 600), np.zeros(600), np.zeros(600)])
    receiver = bake.Receiver("w", positions, np.tile([0.0, 0.0, 1.0], (600, 1)), 21)
    occluder = np.array([[-2.0, -2.0, 1.0], [2.0, -2.0, 1.0], [0.0, 2.0, 1.0]])
    stopped = job.TransferJob([receiver], bake.Occluders(occluder, np.array([[0, 1, 2]]), occluder.copy()),
                              bake.BakeSettings(order=4, samples=4096), executors.ForkedWorkers(2))
    before = set(children(os.getpid()))

    def interrupted(line):
        raise KeyboardInterrupt

    try:
        with pytest.raises(KeyboardInterrupt):
            stopped.run(log=interrupted, budget_s=0.01)  # one short step starts the worker, then the log line
        assert os.listdir(tmp_path) == []
        assert not [pid for pid in set(children(os.getpid())) - before if alive(pid)]
    finally:
        stopped.cancel()
