"""Farm shards of a scene bake (core.shards), through the bake's public steps: one shard executed into a part file
(core.executors.FarmShard), and parts merged into the scene (core.executors.FromParts), stored as a one-process
bake stores it."""

from dataclasses import asdict
import os

import bpy

from ..core import executors, part_file, scheduling, settings as spec, shards
from ..core.bake import BakeSettings
from ..core.errors import InputError
from .execute import between_job, execute, first_job, local_executor
from .plan import BakePlan, plan_bake
from .request import read_request
from .store import BakeReport, store

PART_JOBS = ("bake", "probes")  # the jobs whose chunks a part holds, by name: the vertices', the probes'


def farm_plan(context, settings: BakeSettings, names, casts: bool = True) -> BakePlan:
    """The plan of a bake that farm shards bake and a merge stores: every receiver per vertex. `casts`: False for
    the merge's, which casts no ray (blender.request.read_request)."""
    return plan_bake(read_request(context, settings, names, farm=True, casts=casts))


def bake_shard(context, settings: BakeSettings, names, shard, out: str, stopwatch: shards.Stopwatch,
               workers: int = 1, log=None) -> shards.PartInfo:
    """Bakes shard (K, N) of the scene's bake and writes its part file, its seconds read from `stopwatch` (started
    with the command); nothing in the scene changes."""
    return bake_share(farm_plan(context, settings, names), shard, out, stopwatch, log,
                      local_executor(spec.worker_count(workers)))


def bake_share(plan: BakePlan, shard, out: str, stopwatch: shards.Stopwatch, log=None,
               local=None) -> shards.PartInfo:
    """Bakes shard (K, N) of a farm plan with `local` (this process alone by default) and writes its part file, its
    seconds read from `stopwatch`: its share of the vertices' chunks and of the probes'."""
    executor = executors.FarmShard(shard, local)
    execution = execute(plan, executor)
    execution.run(log=log)
    results, probe_results = (executor.kept.get(name, {}) for name in PART_JOBS)
    info = part_info(plan, shard)
    info.rays = int(sum(int(result.rays.sum()) for result in [*results.values(), *probe_results.values()]))
    info.rays_s, info.workers = execution.progress.elapsed, executor.workers
    shards.write_part(out, info, results, probe_results, stopwatch)
    return info


def merge_parts(context, paths, log=None, plan: BakePlan | None = None) -> BakeReport:
    """Merges the part files (or every part in a folder given) into the scene as one bake (stored, not saved), of
    `plan` where the scene was planned for them already (a farm bake). Refuses, before changing anything, parts from
    another scene or selection, stale ones, duplicates and missing shards, naming them all, then a part whose
    arrays are not the scene's or hold values no bake makes, naming it (core.part_file)."""
    if not paths:
        raise InputError("no part files to merge")
    parts = [(path, part_file.read_part(path)) for path in shards.part_paths(paths)]
    chosen = shards.chosen_bake([info for _, info in parts])
    if plan is None:
        plan = farm_plan(context, BakeSettings(**chosen.settings), chosen.receivers, casts=False)
    problems = shards.refusals(parts, part_info(plan, (0, chosen.shards)))
    if problems:
        raise InputError("cannot merge: " + "; ".join(problems) + "; nothing was written")
    sizing = executors.InProcess()
    shape = part_file.PartShape.of(first_job(plan, sizing), between_job(plan, sizing))
    loaded = [part_file.load_part(path, info, shape) for path, info in parts]
    chunks = {name: [result for held in loaded for result in held[index]] for index, name in enumerate(PART_JOBS)}
    infos = [info for _, info in parts]
    plan.request.ray_engine = chosen.ray_engine  # the shards cast the rays
    from_parts = executors.FromParts(chunks.__getitem__, sum(info.time_s for info in infos),
                                     sum(info.rays_s for info in infos), sum(info.workers for info in infos))
    return store(plan, execute(plan, from_parts).run(log=log))


def part_info(plan: BakePlan, shard) -> shards.PartInfo:
    """What a part says of the bake it belongs to, for this scene as it is now."""
    solved = plan.solved_surfaces()
    return shards.PartInfo(
        shard=shard[0], shards=shard[1], chunks=len(scheduling.chunk_rows([surface.receiver for surface in solved])),
        probe_chunks=len(scheduling.chunk_rows(plan.between.receivers)),
        scene=os.path.basename(bpy.data.filepath), surfaces=[surface.receiver.name for surface in solved],
        receivers=plan.names, settings=asdict(plan.settings), fingerprints=plan.request.fingerprints,
        ray_engine=plan.request.ray_engine)


def build_ray_tree(plan: BakePlan):
    """Builds the occluders' ray tree now (they keep it), so that shards forked afterwards share it."""
    if plan.occluders is not None:
        plan.occluders.ray_caster()
