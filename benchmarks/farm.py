"""Farm bakes, measured side by side in one run on the demo scene (order 4, shadowed):

1. Shards' fixed work: the CPU time of the 4 processes of `prt bake --shard K/4` summed ÷ one process baking the
   whole scene, `--shard 1/4`'s twin `--shard 1/1` (the same command with the same fixed work), each command's
   median CPU over 3 alternated rounds (FULL). Three figures:
   (a) whole processes at 256 rays per vertex; (b) the bake commands alone at 256 rays, from the command's start
   inside its process to its part written (the part's cpu_s: the file opened, the scene gathered, the ray tree
   built, the bake, the part written: all the fixed work that is ours), which the goal judges; (c) whole processes
   at 1,024 rays per vertex (the issue's farm-scale premise). Beside them the CPU of starting Python and the bpy
   module alone (`python -c "import bpy"`), which each process of (a) and (c) pays and (b) leaves out, and the
   merge's CPU.
2. Dask: the wall time of `prt bake --dask local:2` (a LocalCluster of 2 workers, its start and the merge
   included) ÷ `prt bake --workers 1`, alternated 3 times, the median of the paired ratios (other
   tenants' load cancels in a pair); whether both stored the same bits; and after each pair a machine check: how
   much longer two CPU-bound processes take together than one alone (0.5 on two free cores; other tenants raise
   it).

Every process runs with one BLAS thread (OPENBLAS_NUM_THREADS=1, as the README's farm section asks of farm tasks):
with OpenBLAS's default of one thread per core its idle helper thread busy-waits beside the bake, which doubles a
one-process bake's CPU seconds here without making it faster, and would count as work in (a)-(c).

Run from the repository root:  .venv/bin/python benchmarks/farm.py [--part shards|dask] [--json [DIR]] [--quick]
(--part runs and prints only 1 or only 2; --quick is a smoke run: the demo scene without its torus, 2 shards at 16
and 32 rays, one round, one Dask pair; the goals are for the full run).
"""

import argparse
from dataclasses import asdict, dataclass
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (bpy before mathutils, which the core imports)
import numpy as np  # noqa: E402

from benchmarks import results as result_files  # noqa: E402
from prt_addon.blender import sample_scenes, storage  # noqa: E402

SETTINGS = ["--order", "4", "--mode", "shadowed", "--workers", "1"]
ENVIRONMENT = dict(os.environ, PYTHONPATH=ROOT, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
GOALS = {"shards_cpu_sum_to_one": 1.15, "dask_2_workers_to_one_wall": 0.65}


@dataclass(frozen=True)
class Config:
    samples: int             # rays per vertex of (a), (b) and the Dask bakes
    farm_scale_samples: int  # of (c)
    shards: int
    shard_rounds: int        # alternated rounds of the one process and the shards; medians over them
    dask_repeats: int        # pairs of one process and Dask; median of their ratios
    start_up_repeats: int    # `import bpy` alone; the median
    check_iterations: int    # the machine check's fixed pure-Python work per process


FULL = Config(256, 1024, 4, 3, 3, 3, 6_000_000)
QUICK = Config(16, 32, 2, 1, 1, 1, 500_000)


def prt(*arguments) -> tuple[float, float]:
    """Runs `python -m prt_addon ...` to its end; (wall seconds, CPU seconds of the process and its children)."""
    return timed([sys.executable, "-m", "prt_addon", *map(str, arguments)])


def timed(command) -> tuple[float, float]:
    """Runs the command to its end; (wall seconds, CPU seconds of the process and its children)."""
    before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    finished = subprocess.run(command, capture_output=True, text=True, env=ENVIRONMENT)
    wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
    if finished.returncode != 0:
        sys.exit(f"{' '.join(command)} failed: {finished.stderr.strip()}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def part_cpu_s(path) -> float:
    with np.load(path) as data:
        return json.loads(str(data["part"]))["cpu_s"]


def demo_file(folder, quick: bool) -> str:
    """The demo scene saved in `folder`; --quick leaves its torus out (2,775 vertices: the processes' fixed work)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sample_scenes.build_demo_scene()
    if quick:
        bpy.data.objects.remove(bpy.data.objects["Torus"])
    path = os.path.join(folder, "demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path


def shards_cpu(folder, scene, samples: int, config: Config) -> dict:
    """The one process and the shards, alternated `config.shard_rounds` times: each command's median CPU seconds
    (other tenants' load, which slows a process's CPU too, then falls on both sides alike)."""
    settings = [*SETTINGS, "--samples", samples]
    shards = ["1/1"] + [f"{shard}/{config.shards}" for shard in range(1, config.shards + 1)]
    parts = [os.path.join(folder, f"part-{shard.replace('/', '-of-')}-{samples}.npz") for shard in shards]
    process_cpu, bake_cpu = [[] for _ in shards], [[] for _ in shards]
    for _ in range(config.shard_rounds):
        for index, (shard, part) in enumerate(zip(shards, parts)):
            process_cpu[index].append(prt("bake", scene, "--shard", shard, "--out", part, *settings)[1])
            bake_cpu[index].append(part_cpu_s(part))
    _, merge_cpu = prt("merge", scene, *parts[1:], "--output", os.path.join(folder, "merged.blend"))
    process_cpu, bake_cpu = np.median(process_cpu, axis=1).tolist(), np.median(bake_cpu, axis=1).tolist()
    return {
        "samples": samples, "rounds": config.shard_rounds, "shards": config.shards,
        "one_process_cpu_s": process_cpu[0], "shard_process_cpu_s": process_cpu[1:],
        "shards_cpu_sum_to_one": sum(process_cpu[1:]) / process_cpu[0],
        "one_bake_cpu_s": bake_cpu[0], "shard_bake_cpu_s": bake_cpu[1:],
        "shard_bakes_cpu_sum_to_one": sum(bake_cpu[1:]) / bake_cpu[0],
        "merge_process_cpu_s": merge_cpu,
    }


def start_up_cpu_s(repeats: int) -> float:
    """The CPU seconds of starting Python and importing the bpy module, nothing else: the median of `repeats`."""
    return float(np.median([timed([sys.executable, "-c", "import bpy"])[1] for _ in range(repeats)]))


def dask_wall(folder, scene, config: Config) -> dict:
    one, on_dask = os.path.join(folder, "one.blend"), os.path.join(folder, "dask.blend")
    settings = [*SETTINGS, "--samples", config.samples]
    one_wall, dask_wall_s, checks = [], [], []
    for _ in range(config.dask_repeats):
        one_wall.append(prt("bake", scene, *settings, "--output", one)[0])
        dask_wall_s.append(prt("bake", scene, *settings, "--dask", "local:2", "--output", on_dask)[0])
        checks.append(machine_check(config.check_iterations))
    return {"one_process_wall_s": one_wall, "dask_2_workers_wall_s": dask_wall_s,
            "dask_2_workers_to_one_wall": float(np.median(np.divide(dask_wall_s, one_wall))),
            "bit_identical": stored_transfer(one) == stored_transfer(on_dask), "machine_check": checks}


def stored_transfer(path) -> dict:
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    return {ob.name: storage.read_transfer(ob.data)[0].tobytes() for ob in bpy.data.objects
            if ob.type == "MESH" and storage.METADATA_KEY in ob.data}


def machine_check(iterations: int) -> float:
    """Wall time of two CPU-bound processes at once ÷ one alone: 0.5 on two free cores."""
    busy = [sys.executable, "-c", f"sum(i * i for i in range({iterations}))"]
    start = time.perf_counter()
    subprocess.run(busy, check=True)
    alone = time.perf_counter() - start
    start = time.perf_counter()
    for process in [subprocess.Popen(busy) for _ in range(2)]:
        process.wait()
    return (time.perf_counter() - start) / (2 * alone)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--part", choices=["shards", "dask"], help="run only 1 (shards) or only 2 (dask)")
    result_files.add_argument(parser)
    parser.add_argument("--quick", action="store_true", help="a smoke run: " + ", ".join(
        f"{name} {value}" for name, value in asdict(QUICK).items()))
    args = parser.parse_args()
    result_files.check_folder(parser, args)
    config = QUICK if args.quick else FULL
    results = {"config": asdict(config)}
    with tempfile.TemporaryDirectory(prefix="prt_farm_bench_") as folder:
        scene = demo_file(folder, args.quick)
        if args.part != "dask":
            results.update(start_up_cpu_s=start_up_cpu_s(config.start_up_repeats),
                           shards=shards_cpu(folder, scene, config.samples, config),
                           shards_farm_scale=shards_cpu(folder, scene, config.farm_scale_samples, config))
        if args.part != "shards":
            results["dask"] = dask_wall(folder, scene, config)
    print(f"demo scene{' without its torus' if args.quick else ''}, order 4 shadowed; {os.cpu_count()} cores; one "
          f"BLAS thread per process" + ("  (quick: the goals are for the full run)" if args.quick else ""))
    if "shards" in results:
        print_shards(results)
    if "dask" in results:
        print_dask(results["dask"])
    if args.json:
        result_files.write("farm", args, results, goals(results))


def goals(results: dict) -> list:
    """The goals of the parts this run measured, as benchmarks/results.py records them."""
    found = []
    if "shards" in results:
        found.append(result_files.goal("4 shards' bake commands ÷ one, CPU", results["shards"][
            "shard_bakes_cpu_sum_to_one"], "<=", GOALS["shards_cpu_sum_to_one"]))
    if "dask" in results:
        dask = results["dask"]
        found.append(result_files.goal("Dask LocalCluster, 2 workers ÷ one process, wall",
                                       dask["dask_2_workers_to_one_wall"], "<=", GOALS["dask_2_workers_to_one_wall"]))
        found.append(result_files.goal("Dask bake bit-identical to one process's", dask["bit_identical"], "==", True))
    return found


def print_shards(results: dict):
    shards, farm_scale = results["shards"], results["shards_farm_scale"]
    print(f"1. shards' CPU, {shards['shards']} shards ÷ one process ({GOALS['shards_cpu_sum_to_one']:.2f} goal, judged "
          f"on (b)), medians of {shards['rounds']} alternated rounds:")
    print(f"   (a) whole processes, {shards['samples']} rays    {whole(shards)}")
    print(f"   (b) bake commands, {shards['samples']} rays      {sum(shards['shard_bake_cpu_s']):6.2f} s ÷ "
          f"{shards['one_bake_cpu_s']:6.2f} s"
          f" = {shards['shard_bakes_cpu_sum_to_one']:.3f}  {verdict(shards['shard_bakes_cpu_sum_to_one'], 'shards_cpu_sum_to_one')}"
          f"   (each {seconds(shards['shard_bake_cpu_s'])}; from the command's start to its part written)")
    print(f"   (c) whole processes, {farm_scale['samples']} rays  {whole(farm_scale)}")
    print(f"   Python + bpy start-up alone      {results['start_up_cpu_s']:6.2f} s CPU per process, in (a) and (c), "
          f"not in (b); merge process {shards['merge_process_cpu_s']:.2f} s CPU ({shards['samples']} rays)")


def print_dask(dask: dict):
    print(f"2. Dask LocalCluster, 2 workers ÷ one process, wall ({GOALS['dask_2_workers_to_one_wall']:.2f} goal), "
          f"median of {len(dask['one_process_wall_s'])} pairs: {dask['dask_2_workers_to_one_wall']:.3f}  "
          f"{verdict(dask['dask_2_workers_to_one_wall'], 'dask_2_workers_to_one_wall')}")
    print(f"   Dask {seconds(dask['dask_2_workers_wall_s'])}; one process {seconds(dask['one_process_wall_s'])}; "
          f"ratios {', '.join(f'{d / o:.3f}' for d, o in zip(dask['dask_2_workers_wall_s'], dask['one_process_wall_s']))}")
    print(f"   machine check after each pair (two processes ÷ one, 0.5 on free cores): "
          f"{', '.join(f'{check:.2f}' for check in dask['machine_check'])}; bit-identical: {dask['bit_identical']}")


def whole(shards: dict) -> str:
    return (f"{sum(shards['shard_process_cpu_s']):6.2f} s ÷ {shards['one_process_cpu_s']:6.2f} s = "
            f"{shards['shards_cpu_sum_to_one']:.3f}   (each {seconds(shards['shard_process_cpu_s'])})")


def seconds(values) -> str:
    return ", ".join(f"{value:.2f}" for value in values) + " s"


def verdict(value: float, goal: str) -> str:
    return result_files.verdict(value, "<=", GOALS[goal])


if __name__ == "__main__":
    main()
