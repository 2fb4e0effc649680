"""Farm shards without Blender: which chunks each shard bakes, part files written and read back, and the merge's
refusals, each naming what is wrong."""

from dataclasses import asdict, replace
import os
import stat
import time

import numpy as np
import pytest

from prt_addon.core import bake, error_curve, executors, job, part_file, rules, shards
from prt_addon.core.bake import BakeSettings, ChunkResult
from prt_addon.core.errors import InputError
from prt_addon.core.progress import Progress
from prt_addon.core.workers import chunk_owners, chunks_of, shard_chunks

CHUNKS, PROBE_CHUNKS = 7, 2
SETTINGS = asdict(BakeSettings(order=3, samples=16))
FINGERPRINT = {"geometry": "g", "transform": "t", "occluders": "o", "materials": "m", "settings": "s"}


def info(shard, count=3, **changed) -> shards.PartInfo:
    fields = dict(shard=shard, shards=count, chunks=CHUNKS, probe_chunks=PROBE_CHUNKS, scene="room.blend",
                  surfaces=["Floor", "Cube"], receivers=["Floor", "Cube"], settings=SETTINGS,
                  fingerprints={"Floor": FINGERPRINT, "Cube": FINGERPRINT})
    return shards.PartInfo(**{**fields, **changed})


def part(path, shard, count=3, **changed):
    return path, info(shard, count, **changed)


def test_shards_split_the_chunks_into_interleaved_shares_that_cover_each_once():
    for chunks in range(14):
        for count in range(1, 6):
            taken = [shard_chunks(chunks, shard, count) for shard in range(1, count + 1)]
            assert sorted(sum(taken, [])) == list(range(chunks))
            assert all(index % count == shard for shard, share in enumerate(taken) for index in share)
            assert taken == [chunks_of(chunk_owners(chunks, count, 0.0, 0.0), shard) for shard in range(count)]
    assert shard_chunks(5, 3, 10 ** 12) == [2]  # in the share's size, whatever N is


def test_shard_of_reads_k_of_n_from_1_to_n():
    assert shards.shard_of("2/8") == (2, 8)
    for text in ("0/3", "4/3", "x/3", "1/2/3", "3"):
        with pytest.raises(InputError, match="--shard"):
            shards.shard_of(text)


def test_a_part_is_written_atomically_into_a_new_folder_with_the_umasks_mode_and_reads_back(tmp_path):
    result = ChunkResult(np.arange(18.0).reshape(2, 9), np.ones(2), np.array([4, 5]), np.array([False, True]),
                         np.array([0, rules.LYING], np.uint8), np.array([0.0, 0.01]), np.array([[0.25, 9.0, 2.0]]))
    path = tmp_path / "new" / "folder" / "part.npz"
    started = shards.Stopwatch(time.perf_counter() - 10.0, shards.cpu_seconds() - 2.0)  # a command 10 s ago
    probe = ChunkResult(np.full((1, 9), 7.0), np.zeros(1), np.array([9]), np.array([False]), rules.measured(1),
                        np.zeros(1), np.array([[0.5, 9.0, 0.0]]))
    written = info(2, rays_s=1.5, workers=2)
    umask = os.umask(0o027)
    try:
        shards.write_part(str(path), written, {4: result, 1: result}, {1: probe}, started)
    finally:
        os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o640  # 0666 less the umask, as any new file
    read = part_file.read_part(str(path))
    assert 10.0 <= read.time_s < 60.0 and 2.0 <= read.cpu_s < 60.0
    assert replace(read, time_s=0.0, cpu_s=0.0) == replace(written, time_s=0.0, cpu_s=0.0)
    shape = part_file.PartShape([2] * CHUNKS, [1] * PROBE_CHUNKS, 9, False, 0, 4, 16)
    ((index, loaded), (other, _)), [(probe_index, probe_loaded)] = part_file.load_part(str(path), read, shape)
    assert (index, other) == (1, 4) and np.array_equal(loaded.transfer, result.transfer) and loaded.records is None
    assert probe_index == 1 and np.array_equal(probe_loaded.transfer, probe.transfer)
    assert probe_loaded.rays.tolist() == [9] and loaded.rules.tolist() == [0, rules.LYING]
    assert [p.name for p in path.parent.iterdir()] == ["part.npz"]


def test_what_is_not_a_part_is_refused_by_name(tmp_path):
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(2))
    missing = tmp_path / "missing.npz"
    for path, told in [(other, f"{other} is not a PRT part file (written by prt bake --shard): it holds no "
                               f"description"), (missing, f"no such part file: {missing}")]:
        with pytest.raises(InputError) as refused:
            part_file.read_part(str(path))
        assert str(refused.value) == told


def test_parts_that_make_the_bake_are_not_refused():
    assert shards.refusals([part(f"p{k}", k) for k in (3, 1, 2)], info(0)) == []


def test_each_refusal_names_the_part_or_the_shard():
    current = info(0)
    assert shards.refusals([part("p1", 1), part("p3", 3)], current) == ["missing shard 2/3"]
    assert shards.refusals([part("p1", 1), part("p2", 2), part("again", 2), part("p3", 3)], current) == [
        "duplicate shard 2/3: p2, again"]
    moved = dict(FINGERPRINT, transform="t2", occluders="o2")
    found = shards.refusals([part("p1", 1), part("p2", 2, fingerprints={"Floor": FINGERPRINT, "Cube": moved}),
                             part("p3", 3)], current)
    assert found == ["p2 is stale (moved, occluders changed since it was baked)", "missing shard 2/3"]
    found = shards.refusals([part("p1", 1), part("p2", 2, receivers=["Suzanne"]), part("p3", 3)], current)
    assert found[0].startswith("p2 is from another scene or selection (room.blend: Suzanne)")
    found = shards.refusals([part("p1", 1), part("p2", 2, count=4), part("p3", 3)], current)
    assert found[0] == "p2 is shard 2/4, the others are of 3"
    embree = dict(SETTINGS, ray_engine="embree")  # the engines' bakes agree, but not bit for bit
    bvhtree = dict(SETTINGS, ray_engine="bvhtree")
    found = shards.refusals([part("p1", 1, settings=embree), part("p2", 2, settings=bvhtree),
                             part("p3", 3, settings=embree)], info(0, settings=embree))
    assert found == ["p2 was baked with the ray engine bvhtree, the others with embree: bake every shard with one "
                     "(--ray-engine)", "missing shard 2/3"]
    too_far = ("p5", info(5))
    assert shards.refusals([part("p1", 1), part("p2", 2), part("p3", 3), too_far], current) == [
        "p5 is shard 5/3: K must be from 1 to N"]


def test_a_billion_shards_are_told_missing_in_one_short_line_at_once():
    started = time.perf_counter()
    found = shards.refusals([part("p1", 1, count=10 ** 9), part("p3", 3, count=10 ** 9)], info(0, 10 ** 9))
    assert found == ["missing shards 2/1000000000, 4/1000000000, 5/1000000000, 6/1000000000, 7/1000000000, "
                     "8/1000000000, 9/1000000000, 10/1000000000 and 999999990 more (N = 1000000000 in p1 and 1 "
                     "other part)"]
    assert time.perf_counter() - started < 1.0  # not a list of N shards (minutes and 23 GB to build)
    assert shards.refusals([part("p1", 1, count=2)], info(0, 2)) == ["missing shard 2/2"]


def test_a_foreign_parts_names_are_told_on_one_line_and_short():
    line = shards.refusals([part("p1", 1, count=1, scene="a\nb.blend", receivers=["x" * 500, "y\r"])],
                           info(0, 1))[0]
    assert line == f"p1 is from another scene or selection (a?b.blend: {'x' * 59}…, y?)"


def test_the_merge_bakes_what_most_parts_belong_to():
    infos = [info(1), info(2, settings={**SETTINGS, "order": 4}), info(3)]
    assert shards.chosen_bake(infos).settings == SETTINGS


def test_a_merges_rays_per_second_and_workers_are_its_shards():
    """A merge casts no ray: its rate is the rays ÷ the shards' seconds baking and its own (bounces), its workers
    the shards' in all; its time adds the shards' commands' seconds."""
    receivers = [bake.Receiver("Floor", np.zeros((300, 3)), np.tile([0.0, 0.0, 1.0], (300, 1)), 1)]
    parts = []
    merge = job.TransferJob(receivers, None, BakeSettings(order=2, mode="unshadowed"),
                            executors.FromParts(lambda name: parts, time_s=30.0, rays_s=12.0, workers=6))
    now = [100.0]
    merge.progress = Progress("PRT bake", clock=lambda: now[0])  # the merge's own seconds, told by this clock
    parts += [(index, ChunkResult(np.zeros((len(rows), 4)), np.zeros(len(rows)), np.full(len(rows), 64),
                                  np.zeros(len(rows), bool), rules.measured(len(rows)), np.zeros(len(rows)),
                                  np.array([[1.0, 64.0 * len(rows), 0.0]])))
              for index, (_, rows) in enumerate(merge.chunks)]
    merge.run()
    now[0] = 103.0
    summary = merge.summary(merge.results())
    assert summary.rays == 300 * 64 and summary.workers == 6
    assert summary.rays_per_s == 300 * 64 / (12.0 + 3.0) and summary.time_s == 30.0 + 3.0
    assert summary.phases_s["shards_rays_s"] == 12.0
    # one round, cast in the shards' 12 s of rays and the merge's own 0 s before its clock moved
    assert summary.error_curve == [error_curve.Row("round 1", 12.0, 300 * 64, 0.0, 300)]
