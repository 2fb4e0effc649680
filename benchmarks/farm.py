"""Farm bakes, measured side by side in one run on the demo scene (order 4, shadowed, 256 rays per vertex):

1. Shards' fixed work: the CPU time of the 4 processes of `prt bake --shard K/4` summed ÷ one process baking the
   whole scene, `--shard 1/4`'s twin `--shard 1/1` (the same command with the same fixed work: starting Python and
   bpy, opening the file, gathering the scene, building the ray tree). Twice: whole processes, and the bake alone
   (the part's CPU seconds: from gathering to the part written). The merge's CPU time is printed beside them.
2. Dask: the wall time of `prt bake --dask local:2` (a LocalCluster of 2 workers, its start and the merge
   included) ÷ `prt bake --workers 1`, alternated DASK_REPEATS times, the median of the paired ratios (other
   tenants' load cancels in a pair); whether both stored the same bits; and a machine check: how much longer two
   CPU-bound processes take together than one alone (0.5 on two free cores; other tenants raise it).

Run from the repository root:  .venv/bin/python benchmarks/farm.py [--json PATH]
"""

import argparse
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

from prt_addon.blender import sample_scenes, storage  # noqa: E402

SETTINGS = ["--order", "4", "--mode", "shadowed", "--samples", "256", "--workers", "1"]
SHARDS = 4
DASK_REPEATS = 3
GOALS = {"shards_cpu_sum_to_one": 1.15, "dask_2_workers_to_one_wall": 0.65}


def prt(*arguments) -> tuple[float, float]:
    """Runs `python -m prt_addon ...` to its end; (wall seconds, CPU seconds of the process and its children)."""
    before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    finished = subprocess.run([sys.executable, "-m", "prt_addon", *map(str, arguments)], capture_output=True,
                              text=True, env=dict(os.environ, PYTHONPATH=ROOT))
    wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
    if finished.returncode != 0:
        sys.exit(f"prt {' '.join(map(str, arguments))} failed: {finished.stderr.strip()}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def part_cpu_s(path) -> float:
    with np.load(path) as data:
        return json.loads(str(data["part"]))["cpu_s"]


def demo_file(folder) -> str:
    bpy.ops.wm.read_homefile(use_empty=True)
    sample_scenes.build_demo_scene()
    path = os.path.join(folder, "demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path


def shards_cpu(folder, scene) -> dict:
    one_part = os.path.join(folder, "whole.npz")
    _, one_process_cpu = prt("bake", scene, "--shard", "1/1", "--out", one_part, *SETTINGS)
    parts, process_cpu = [], []
    for shard in range(1, SHARDS + 1):
        parts.append(os.path.join(folder, f"part-{shard}.npz"))
        process_cpu.append(prt("bake", scene, "--shard", f"{shard}/{SHARDS}", "--out", parts[-1], *SETTINGS)[1])
    _, merge_cpu = prt("merge", scene, *parts, "--output", os.path.join(folder, "merged.blend"))
    return {
        "one_process_cpu_s": one_process_cpu, "shard_process_cpu_s": process_cpu,
        "shards_cpu_sum_to_one": sum(process_cpu) / one_process_cpu,
        "one_bake_cpu_s": part_cpu_s(one_part), "shard_bake_cpu_s": [part_cpu_s(part) for part in parts],
        "shard_bakes_cpu_sum_to_one": sum(map(part_cpu_s, parts)) / part_cpu_s(one_part),
        "merge_process_cpu_s": merge_cpu,
    }


def dask_wall(folder, scene) -> dict:
    one, on_dask = os.path.join(folder, "one.blend"), os.path.join(folder, "dask.blend")
    one_wall, dask_wall_s = [], []
    for _ in range(DASK_REPEATS):
        one_wall.append(prt("bake", scene, *SETTINGS, "--output", one)[0])
        dask_wall_s.append(prt("bake", scene, *SETTINGS, "--dask", "local:2", "--output", on_dask)[0])
    return {"one_process_wall_s": one_wall, "dask_2_workers_wall_s": dask_wall_s,
            "dask_2_workers_to_one_wall": float(np.median(np.divide(dask_wall_s, one_wall))),
            "bit_identical": stored_transfer(one) == stored_transfer(on_dask), "machine_check": machine_check()}


def stored_transfer(path) -> dict:
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    return {ob.name: storage.read_transfer(ob.data)[0].tobytes() for ob in bpy.data.objects
            if ob.type == "MESH" and storage.METADATA_KEY in ob.data}


def machine_check() -> float:
    """Wall time of two CPU-bound processes at once ÷ one alone: 0.5 on two free cores."""
    busy = [sys.executable, "-c", "sum(i * i for i in range(6_000_000))"]
    start = time.perf_counter()
    subprocess.run(busy, check=True)
    alone = time.perf_counter() - start
    start = time.perf_counter()
    for process in [subprocess.Popen(busy) for _ in range(2)]:
        process.wait()
    return (time.perf_counter() - start) / (2 * alone)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", help="also write the numbers here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="prt_farm_bench_") as folder:
        scene = demo_file(folder)
        results = {"shards": shards_cpu(folder, scene), "dask": dask_wall(folder, scene)}
    shards, dask = results["shards"], results["dask"]
    print(f"demo scene, order 4 shadowed, 256 rays per vertex; {os.cpu_count()} cores")
    print(f"1. shards' CPU, {SHARDS} shards ÷ one process ({GOALS['shards_cpu_sum_to_one']:.2f} goal):")
    print(f"   whole processes  {sum(shards['shard_process_cpu_s']):6.2f} s ÷ {shards['one_process_cpu_s']:6.2f} s"
          f" = {shards['shards_cpu_sum_to_one']:.3f}  {verdict(shards['shards_cpu_sum_to_one'], 'shards_cpu_sum_to_one')}"
          f"   (each {', '.join(f'{s:.2f}' for s in shards['shard_process_cpu_s'])} s)")
    print(f"   the bakes alone  {sum(shards['shard_bake_cpu_s']):6.2f} s ÷ {shards['one_bake_cpu_s']:6.2f} s"
          f" = {shards['shard_bakes_cpu_sum_to_one']:.3f}   (gathering to part written)")
    print(f"   merge process    {shards['merge_process_cpu_s']:6.2f} s CPU")
    print(f"2. Dask LocalCluster, 2 workers ÷ one process, wall ({GOALS['dask_2_workers_to_one_wall']:.2f} goal), "
          f"median of {DASK_REPEATS} pairs: {dask['dask_2_workers_to_one_wall']:.3f}  "
          f"{verdict(dask['dask_2_workers_to_one_wall'], 'dask_2_workers_to_one_wall')}")
    print(f"   Dask {seconds(dask['dask_2_workers_wall_s'])}; one process {seconds(dask['one_process_wall_s'])}")
    print(f"   bit-identical: {dask['bit_identical']}; machine check (two processes ÷ one, 0.5 on free cores): "
          f"{dask['machine_check']:.2f}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as out:
            json.dump(results, out, indent=2)


def seconds(values) -> str:
    return ", ".join(f"{value:.2f}" for value in values) + " s"


def verdict(value: float, goal: str) -> str:
    return "PASS" if value <= GOALS[goal] else "MISS"


if __name__ == "__main__":
    main()
