"""Farm shards without Blender: which chunks each shard bakes, part files written and read back, and the merge's
refusals, each naming what is wrong."""

from dataclasses import replace
import time

import numpy as np
import pytest

from prt_addon.core import shards
from prt_addon.core.bake import ChunkResult
from prt_addon.core.errors import InputError
from prt_addon.core.workers import shard_chunks

CHUNKS, PROBE_CHUNKS = 7, 2
FINGERPRINT = {"geometry": "g", "transform": "t", "occluders": "o", "materials": "m", "settings": "s"}


def info(shard, count=3, **changed) -> shards.PartInfo:
    fields = dict(shard=shard, shards=count, chunks=CHUNKS, probe_chunks=PROBE_CHUNKS, scene="room.blend", surfaces=["Floor", "Cube"],
                  receivers=["Floor", "Cube"], settings={"order": 3}, fingerprints={"Floor": FINGERPRINT,
                                                                                    "Cube": FINGERPRINT})
    return shards.PartInfo(**{**fields, **changed})


def part(path, shard, count=3, **changed):
    return path, info(shard, count, **changed), (shard_chunks(CHUNKS, shard, count),
                                                 shard_chunks(PROBE_CHUNKS, shard, count))


def test_shards_split_the_chunks_into_interleaved_shares_that_cover_each_once():
    for chunks in range(14):
        for count in range(1, 6):
            taken = [shard_chunks(chunks, shard, count) for shard in range(1, count + 1)]
            assert sorted(sum(taken, [])) == list(range(chunks))
            assert all(index % count == shard for shard, share in enumerate(taken) for index in share)


def test_shard_of_reads_k_of_n_from_1_to_n():
    assert shards.shard_of("2/8") == (2, 8)
    for text in ("0/3", "4/3", "x/3", "1/2/3", "3"):
        with pytest.raises(InputError, match="--shard"):
            shards.shard_of(text)


def test_a_part_is_written_atomically_into_a_new_folder_and_reads_back(tmp_path):
    result = ChunkResult(np.arange(6.0).reshape(2, 3), np.ones(2), np.array([4, 5]), np.array([False, True]))
    path = tmp_path / "new" / "folder" / "part.npz"
    started = shards.Stopwatch(time.perf_counter() - 10.0, shards.cpu_seconds() - 2.0)  # a command 10 s ago
    probe = ChunkResult(np.full((1, 3), 7.0), np.zeros(1), np.array([9]), np.array([False]))
    shards.write_part(str(path), info(2), {5: result, 1: result}, {1: probe}, started)
    read, chunks = shards.read_part(str(path))
    assert chunks == ([1, 5], [1]) and 10.0 <= read.time_s < 60.0 and 2.0 <= read.cpu_s < 60.0
    assert replace(read, time_s=0.0, cpu_s=0.0) == info(2)
    (index, loaded), _ = shards.load_chunks(str(path))
    assert index == 1 and np.array_equal(loaded.transfer, result.transfer) and loaded.records is None
    [(index, loaded)] = shards.load_chunks(str(path), shards.PROBES)
    assert index == 1 and np.array_equal(loaded.transfer, probe.transfer) and loaded.rays.tolist() == [9]
    assert [p.name for p in path.parent.iterdir()] == ["part.npz"]


def test_what_is_not_a_part_is_refused_by_name(tmp_path):
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(2))
    for path in (other, tmp_path / "missing.npz"):
        with pytest.raises(InputError, match=str(path)):
            shards.read_part(str(path))


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
    without_probes = ("p2", info(2), (shard_chunks(CHUNKS, 2, 3), []))
    assert shards.refusals([part("p1", 1), without_probes, part("p3", 3)], current)[0] == (
        "p2 does not hold shard 2/3's chunks")
    too_far = ("p5", info(5), ([], []))
    assert shards.refusals([part("p1", 1), part("p2", 2), part("p3", 3), too_far], current) == [
        "p5 is shard 5/3: K must be from 1 to N"]


def test_the_merge_bakes_what_most_parts_belong_to():
    infos = [info(1), info(2, settings={"order": 4}), info(3)]
    assert shards.chosen_bake(infos).settings == {"order": 3}
