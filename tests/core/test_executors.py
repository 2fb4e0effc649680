"""The executors (core.executors) give one job the same bits however its chunks are run: in this process, or as
farm shards whose kept chunks another process takes from their parts; a shard bounces nothing, its merge does."""

import numpy as np
import pytest

from prt_addon.core import bake, executors, job, scheduling
from prt_addon.core.workers import shard_chunks

ENGINE = "reference"  # needs no Blender


def scene(mode: str):
    """A floor of 600 points (5 chunks) under a square occluder facing down, its corners solved too, so that an
    interreflected bake bounces light between the two."""
    rng = np.random.default_rng(3)
    floor = np.column_stack([rng.uniform(-1.5, 1.5, (600, 2)), np.zeros(600)])
    square = np.array([[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])
    vertices = np.vstack([floor, square])
    triangles = np.array([[600, 602, 601], [600, 603, 602]])  # wound to face the floor
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (600, 1)), np.tile([0.0, 0.0, -1.0], (4, 1))])
    receiver = bake.Receiver("floor", vertices, normals, 5)
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), solved_vertices=len(vertices), engine=ENGINE)
    settings = bake.BakeSettings(mode=mode, order=3, samples=32)
    albedo = [np.full((len(vertices), 1), 0.6)] if mode == "interreflected" else None
    return [receiver], occluders, settings, albedo


@pytest.mark.parametrize("mode", ["shadowed", "interreflected"])
def test_farm_shards_merged_from_their_parts_give_the_one_process_bake_bit_for_bit(mode):
    receivers, occluders, settings, albedo = scene(mode)
    (one,) = job.TransferJob(receivers, occluders, settings, executors.InProcess(), albedo).run()
    chunks = len(scheduling.chunk_rows(receivers))
    parts = []
    for shard in (1, 2, 3):
        executor = executors.FarmShard((shard, 3))
        baked = job.TransferJob(receivers, occluders, settings, executor, albedo)
        baked.run()
        assert sorted(executor.kept["bake"]) == shard_chunks(chunks, shard, 3)  # its share, kept by the job's name
        assert baked.bounce_report is None  # a shard holds a third of the hits: the merge bounces
        parts += executor.kept["bake"].items()
    assert sorted(index for index, _ in parts) == list(range(chunks))
    merge = job.TransferJob(receivers, occluders, settings, executors.FromParts(lambda name: parts, time_s=9.0),
                            albedo)
    (merged,) = merge.run()
    assert merge.rays == int(one.rays.sum()) > 0 and merge.phase_times["shards_s"] == 9.0
    assert (merge.bounce_report is not None) == (mode == "interreflected")
    for name in ("transfer", "std_error", "rays", "skipped"):
        np.testing.assert_array_equal(getattr(merged, name), getattr(one, name))


def test_workers_bake_in_one_process_where_they_would_not_repay_their_start():
    """Forked workers start in milliseconds and are worth fewer rays than spawned ones (a second to start); too
    few chunks, or no rays, and the job stays in one process."""
    settings = bake.BakeSettings(order=3, samples=256)
    forked, spawned = executors.ForkedWorkers(4), executors.SpawnedWorkers(4, ["python", "-c"])
    points = -(-executors.FORK_MIN_RAYS // settings.samples)  # just enough rays for forked workers
    assert forked.processes(8, points, settings) == 4
    assert spawned.processes(8, points, settings) == 1  # WORKER_MIN_RAYS: ten times as many rays
    assert forked.processes(3, points, settings) == 1  # fewer chunks than processes
    assert forked.processes(8, points, bake.BakeSettings(mode="unshadowed")) == 1
    assert executors.FarmShard((1, 2), forked).processes(8, points, settings) == 4  # its local executor's
