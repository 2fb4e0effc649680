"""Farm shards of a scene bake (core.shards): one shard baked into a part file, and parts merged into the scene,
stored as a one-process bake stores it."""

from dataclasses import asdict
import os

import bpy

from ..core import executors, part_file, shards
from ..core.bake import BakeSettings
from ..core.errors import InputError
from .scene_bake import SceneBake


def bake_shard(context, settings: BakeSettings, names, shard, out: str, stopwatch: shards.Stopwatch,
               workers: int = 1, log=None) -> shards.PartInfo:
    """Bakes shard (K, N) of the scene's bake and writes its part file, its seconds read from `stopwatch` (started
    with the command); nothing in the scene changes."""
    scene_bake = SceneBake(context, settings, names, workers=workers, farm=True)
    return bake_share(scene_bake, shard, out, stopwatch, log)


def bake_share(scene_bake: SceneBake, shard, out: str, stopwatch: shards.Stopwatch, log=None) -> shards.PartInfo:
    """Bakes shard (K, N) of a gathered farm bake and writes its part file, its seconds read from `stopwatch`."""
    scene_bake.bake_only(shard)
    scene_bake.sequence.run(log=log)  # its vertices' chunks and its probes'
    results, probe_results = (scene_bake.executor.kept.get(name, {}) for name in ("bake", "probes"))
    info = part_info(scene_bake, shard)
    info.rays = int(sum(int(result.rays.sum()) for result in [*results.values(), *probe_results.values()]))
    info.rays_s, info.workers = scene_bake.levels.progress.elapsed, scene_bake.job.workers
    shards.write_part(out, info, results, probe_results, stopwatch)
    return info


def merge_parts(context, paths, log=None, scene_bake: SceneBake | None = None) -> SceneBake:
    """Merges the part files (or every part in a folder given) into the scene as one bake (stored, not saved), into
    `scene_bake` where the scene was gathered for them already (a farm bake, `farm`). Refuses, before changing
    anything, parts from another scene or selection, stale ones, duplicates and missing shards, naming them all,
    then a part whose arrays are not the scene's or hold values no bake makes, naming it (core.part_file)."""
    if not paths:
        raise InputError("no part files to merge")
    parts = [(path, part_file.read_part(path)) for path in shards.part_paths(paths)]
    chosen = shards.chosen_bake([info for _, info in parts])
    if scene_bake is None:
        scene_bake = SceneBake(context, BakeSettings(**chosen.settings), chosen.receivers, farm=True)
    problems = shards.refusals(parts, part_info(scene_bake, (0, chosen.shards)))
    if problems:
        raise InputError("cannot merge: " + "; ".join(problems) + "; nothing was written")
    shape = part_file.PartShape.of(scene_bake.job, scene_bake.probe_job)
    loaded = dict(zip(("bake", "probes"), zip(*[part_file.load_part(path, info, shape) for path, info in parts])))
    infos = [info for _, info in parts]
    from_parts = executors.FromParts(lambda name: (result for chunks in loaded[name] for result in chunks),
                                     sum(info.time_s for info in infos), sum(info.rays_s for info in infos),
                                     sum(info.workers for info in infos))
    scene_bake.job.run_by(from_parts)
    scene_bake.probe_job.run_by(from_parts)
    scene_bake.run(log=log)
    return scene_bake


def part_info(scene_bake: SceneBake, shard) -> shards.PartInfo:
    """What a part says of the bake it belongs to, for this scene as it is now."""
    return shards.PartInfo(
        shard=shard[0], shards=shard[1], chunks=len(scene_bake.job.chunks),
        probe_chunks=len(scene_bake.probe_job.chunks),
        scene=os.path.basename(bpy.data.filepath), surfaces=[s.receiver.name for s in scene_bake.surfaces.all],
        receivers=[ob.name for ob in scene_bake.objects], settings=asdict(scene_bake.settings),
        fingerprints=scene_bake.fingerprints)
