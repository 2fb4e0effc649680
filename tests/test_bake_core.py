"""The shadowed estimator against closed forms, its error estimate against its actual error."""

import functools
import itertools
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from numpy.polynomial import legendre

from quadrature import polygon_transfer

from prt_addon.core import bake, estimator, executors, job, lobes, polygons, ray_caster, scheduling, sh, workers

ENGINE = "reference"  # the estimator's tests need no Blender
# Segments of the disc in tests that compare bakes with each other, not with the disc's closed form: the reference
# engine's cost grows with the triangles.
COARSE_DISC = 64


def disc(radius, height, segments=720):
    """A horizontal disc (polygon fan) centred above the origin, facing down at a receiver below."""
    angles = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(segments, height)], 1)
    vertices = np.vstack([[0.0, 0.0, height], ring])
    triangles = np.array([[0, 1 + i, 1 + (i + 1) % segments] for i in range(segments)])
    return bake.Occluders(vertices, triangles, vertices.copy(), engine=ENGINE)


def capped_transfer_zonal(order, cap_half_angle):
    """T_l0 for a +Z normal under a centred disc: (1/π)∫ V cos Y_l0 = 2·sqrt((2l+1)/4π)·∫_0^{cos α} t P_l(t) dt,
    by Gauss-Legendre quadrature of Legendre polynomials (numpy's), independent of the code under test."""
    nodes, weights = legendre.leggauss(64)
    top = np.cos(cap_half_angle)
    t = 0.5 * top * (nodes + 1.0)
    values = []
    for l in range(order):
        p_l = legendre.legval(t, [0] * l + [1])
        values.append(2 * np.sqrt((2 * l + 1) / (4 * np.pi)) * 0.5 * top * np.sum(weights * t * p_l))
    return np.array(values)


def receiver_copies(count, position=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), name="probe"):
    """`count` vertices at one point: independent replicates of one integral (each has its own key)."""
    return bake.Receiver(name, np.tile(position, (count, 1)).astype(float),
                         np.tile(normal, (count, 1)).astype(float), bake.Receiver.key_for(name))


def run(receivers, occluders, **settings):
    the_job = job.TransferJob(receivers, occluders, bake.BakeSettings(**settings))
    return the_job.run(), the_job


ZONAL = [sh.index(l, 0) for l in range(4)]


def test_unshadowed_is_the_closed_form_without_rays():
    normals = np.random.default_rng(1).normal(size=(50, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    receiver = bake.Receiver("r", np.zeros((50, 3)), normals, 7)
    (result,), _ = run([receiver], None, mode="unshadowed", order=3)
    assert result.rays.sum() == 0
    c0, c1 = np.sqrt(1 / (4 * np.pi)), np.sqrt(3 / (4 * np.pi))
    x, y, z = normals.T
    # Exact up to the float32 rounding of storage (≤ 2⁻²⁴ relative).
    np.testing.assert_allclose(result.transfer[:, 0], c0, rtol=2 ** -24, atol=0)  # Â_0/π · Y_00
    np.testing.assert_allclose(result.transfer[:, 1:4], (2 / 3) * c1 * np.stack([-y, z, -x], 1), atol=1e-7)
    np.testing.assert_allclose(result.transfer[:, 6], (1 / 4) * 0.315391565252520 * (3 * z * z - 1), atol=1e-7)


def test_shadowed_matches_the_closed_form_under_a_disc():
    radius, height = 1.0, 1.5
    (result,), _ = run([receiver_copies(256)], disc(radius, height), order=4, samples=64)
    expected = capped_transfer_zonal(4, np.arctan(radius / height))
    mean = result.transfer[:, ZONAL].mean(0)
    spread = result.transfer[:, ZONAL].std(0) / np.sqrt(256)
    assert np.all(np.abs(mean - expected) <= 4 * spread + 1e-4), (mean, expected, spread)
    off_axis = [k for k in range(16) if k not in ZONAL]
    assert np.abs(result.transfer[:, off_axis].mean(0)).max() < 5 * result.std_error.mean() / 16 ** 0.5 + 1e-3


def roof(half=1.0, height=1.0):
    """A flat square of two triangles facing down, found as a polygon like any flat occluder."""
    vertices = np.array([[-half, -half, height], [-half, half, height], [half, half, height], [half, -half, height]])
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    return vertices, triangles, polygons.convex_polygon(vertices, triangles)


def test_a_flat_occluder_is_exact_without_noise():
    """Under a flat roof every ray is explained by the closed form: the transfer is the quadrature truth to
    float32 storage, and the estimated error is zero."""
    vertices, triangles, polygon = roof()
    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, -0.8, 0.6], [0.0, 0.0, 1.0]])
    positions = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2], [-1.5, 0.4, 0.5], [1.2, 1.1, -0.3]])
    receiver = bake.Receiver("r", positions, normals, 5)
    occluders = bake.Occluders(vertices, triangles, vertices, [polygon], engine=ENGINE)
    (result,), _ = run([receiver], occluders, order=6, samples=64)
    origins = positions + ray_caster.OFFSET_FRACTION * occluders.diagonal * normals  # where the rays start
    unshadowed = lobes.unshadowed_transfer(6, normals)
    truth = [u - polygon_transfer(6, o, n, polygon) for u, o, n in zip(unshadowed, origins, normals)]
    assert result.rays.min() == 64
    np.testing.assert_allclose(result.transfer, truth, atol=1e-6)
    assert result.std_error.max() < 1e-6


def test_any_polygon_keeps_the_estimate_unbiased():
    """The closed form is a control variate: a polygon that is not there, half over a real disc's shadow, still
    leaves the mean over 256 independent vertices on the disc's closed form."""
    radius, height = 1.0, 1.5
    occluders = disc(radius, height)
    phantom = np.array([[0.2, -1.0, 1.0], [1.8, -1.0, 1.0], [1.8, 1.0, 1.0], [0.2, 1.0, 1.0]])
    occluders.polygons = [phantom]
    (result,), _ = run([receiver_copies(256)], occluders, order=4, samples=64)
    expected = capped_transfer_zonal(4, np.arctan(radius / height))
    mean = result.transfer[:, ZONAL].mean(0)
    spread = result.transfer[:, ZONAL].std(0) / np.sqrt(256)
    assert np.all(np.abs(mean - expected) <= 4 * spread + 1e-4), (mean, expected, spread)
    # Teeth: the phantom's closed form is far larger than the tolerance, so a wrong sign or a missing term fails.
    _, blocked = polygons.cones_and_blocked_transfer(4, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), [phantom])
    assert np.abs(blocked).max() > 0.05


def test_a_row_clipped_by_its_face_plane_gathers_only_above_it():
    """Under an open sky (the only occluder far below), a +Z normal clipped by a plane 60° from it gathers
    (1 + cos 60°)/2 of its cosine-weighted sky (docs/cycles_conventions.md, R1): T_00 = 0.75·Y_00, and band 1 from
    a quadrature of the lune over 2 M Fibonacci directions, with Y_1 = sqrt(3/4π)·(−y, z, −x)."""
    tilt = np.radians(60.0)
    receiver = receiver_copies(256)
    receiver.clip = np.tile([np.sin(tilt), 0.0, np.cos(tilt)], (256, 1))
    (result,), _ = run([receiver], disc(0.1, -5.0, segments=16), order=2, samples=64)
    count = 2_000_000
    z = 1.0 - (2.0 * np.arange(count) + 1.0) / count
    azimuth = np.pi * (3.0 - np.sqrt(5.0)) * np.arange(count)
    directions = np.stack([np.sqrt(1 - z * z) * np.cos(azimuth), np.sqrt(1 - z * z) * np.sin(azimuth), z], 1)
    weight = np.where(directions @ receiver.clip[0] > 0, np.maximum(z, 0.0), 0.0) * 4.0 / count  # (1/π)·4π/n
    c0, c1 = np.sqrt(1 / (4 * np.pi)), np.sqrt(3 / (4 * np.pi))
    x, y = directions[:, 0], directions[:, 1]
    expected = np.array([c0 * weight.sum(), *(c1 * np.array([-y, z, -x]) @ weight)])
    assert abs(expected[0] - 0.75 * c0) < 1e-4
    mean = result.transfer[:, :4].mean(0)
    spread = result.transfer[:, :4].std(0) / np.sqrt(256)
    assert np.all(np.abs(mean - expected) <= 4 * spread + 1e-4), (mean, expected, spread)
    assert result.rays.min() > 0 and not result.skipped.any()


def test_a_clipped_row_under_a_shadow_in_its_lune_is_unbiased_and_honest():
    """A +Z normal clipped by a plane 60° from it, under a disc whose shadow (a cap of 22° about +Z) lies wholly in
    front of that plane: its transfer is the lune's closed form (polygons.lune_transfer, the rays' control variate)
    less what the disc blocks, the unshadowed transfer less the disc's Legendre quadrature. Over 256 independent
    vertices the mean is on that truth and the estimated errors are honest."""
    radius, height, order, tilt = 0.6, 1.5, 3, np.radians(60.0)
    receiver = receiver_copies(256)
    receiver.clip = np.tile([np.sin(tilt), 0.0, np.cos(tilt)], (256, 1))
    (result,), _ = run([receiver], disc(radius, height), order=order, samples=64)
    up = np.array([[0.0, 0.0, 1.0]])
    blocked = lobes.unshadowed_transfer(order, up)[0]
    blocked[ZONAL[:order]] -= capped_transfer_zonal(order, np.arctan(radius / height))
    truth = polygons.lune_transfer(order, up, receiver.clip[:1])[0] - blocked
    mean, spread = result.transfer.mean(0), result.transfer.std(0) / np.sqrt(256)
    assert np.all(np.abs(mean - truth) <= 4 * spread + 1e-4), (mean, truth, spread)
    ratio = np.linalg.norm(result.transfer - truth, axis=1) / result.std_error
    assert 0.7 <= np.sqrt(np.mean(ratio ** 2)) <= 1.4
    assert np.abs(blocked).max() > 0.05  # teeth: the shadow is far larger than the tolerance


def test_estimated_error_is_honest():
    """Actual error ÷ estimated standard error over 400 independent vertices has an RMS near 1."""
    radius, height = 1.0, 1.0
    (result,), _ = run([receiver_copies(400)], disc(radius, height), order=3, samples=64)
    expected = np.zeros(9)
    expected[[0, 2, 6]] = capped_transfer_zonal(3, np.arctan(radius / height))
    actual = np.linalg.norm(result.transfer - expected, axis=1)
    z = actual / result.std_error
    # For a 9-vector, |error| / sqrt(Σ var) has RMS 1 when the estimate is honest.
    assert 0.7 <= np.sqrt(np.mean(z ** 2)) <= 1.4


def test_the_core_bakes_where_neither_bpy_nor_mathutils_can_be_imported():
    """With the reference engine the estimator is numpy alone: a process in which bpy and mathutils cannot be
    imported bakes the disc's shadow, bit for bit as this process does."""
    script = ("import sys\n"
              "sys.modules['bpy'] = sys.modules['mathutils'] = None  # an import of either raises ImportError\n"
              f"sys.path[:0] = [{str(Path(__file__).parents[1])!r}, {str(Path(__file__).parent)!r}]\n"
              "from test_bake_core import disc, receiver_copies, run\n"
              "(result,), _ = run([receiver_copies(8)], disc(1.0, 1.5, COARSE_DISC), order=3, samples=32)\n"
              "sys.stdout.buffer.write(result.transfer.tobytes())\n").replace("COARSE_DISC", str(COARSE_DISC))
    there = subprocess.run([sys.executable, "-c", script], capture_output=True, check=True, timeout=300).stdout
    (here,), _ = run([receiver_copies(8)], disc(1.0, 1.5, COARSE_DISC), order=3, samples=32)
    assert there == here.transfer.tobytes() and here.rays.sum() > 0


def test_provably_unoccluded_vertices_cast_no_rays_and_are_exact():
    above = receiver_copies(10, position=(0.0, 0.0, 2.0), name="above")
    below = receiver_copies(10, position=(0.0, 0.0, 0.0), name="below")
    (top, bottom), the_job = run([above, below], disc(1.0, 1.5), order=4, samples=64)
    assert top.skipped.all() and top.rays.sum() == 0 and not bottom.skipped.any()
    np.testing.assert_array_equal(top.transfer, lobes.unshadowed_transfer(4, above.normals).astype(np.float32))
    summary = the_job.summary([top, bottom])
    assert summary.skipped_vertices == 10 and summary.rays == 10 * 64


@pytest.mark.parametrize("scale, shift", [(1e-4, 0.0), (1e4, 0.0), (1.0, 1e5)])
def test_scaled_and_moved_scenes_bake_the_same(scale, shift):
    occluders = disc(1.0, 1.0)
    probe = bake.Receiver("p", np.array([[0.3, -0.2, 0.0], [0.9, 0.9, 0.0]]), np.array([[0, 0, 1.0]] * 2), 3)
    (reference,), _ = run([probe], occluders, order=4, samples=256)
    moved_occluders = bake.Occluders(occluders.vertices * scale + shift, occluders.triangles,
                                     occluders.hull * scale + shift, engine=ENGINE)
    moved = bake.Receiver("p", probe.positions * scale + shift, probe.normals, 3)
    (result,), _ = run([moved], moved_occluders, order=4, samples=256)
    np.testing.assert_allclose(result.transfer, reference.transfer, atol=1e-12)


def test_target_error_is_met_per_vertex():
    receiver = bake.Receiver("t", np.array([[0.0, 0, 0], [0.8, 0, 0], [1.6, 0, 0], [4.0, 0, 0]]),
                             np.array([[0, 0, 1.0]] * 4), 11)
    (result,), _ = run([receiver], disc(1.0, 1.0), order=4, samples=64, target_error=0.01, max_samples=65536)
    assert np.all(result.rel_error <= 0.01)
    assert result.rays.max() > result.rays.min()  # rays went where the error was


SPAWNED = functools.partial(executors.SpawnedWorkers, 2, [sys.executable, "-c"])
FORKED = functools.partial(executors.ForkedWorkers, 2)


def bake_alone_and_with_a_worker(launch, owners=None):
    """The same 600 vertices (5 chunks) baked by this process alone, then with one worker: `launch(owners)` makes
    the executor (SPAWNED or FORKED)."""
    rng = np.random.default_rng(5)
    positions = np.column_stack([rng.uniform(-1.5, 1.5, (600, 2)), np.zeros(600)])
    receiver = bake.Receiver("w", positions, np.tile([0.0, 0.0, 1.0], (600, 1)), 21)
    settings = bake.BakeSettings(order=4, samples=64, target_error=0.05, max_samples=1024)
    one = job.TransferJob([receiver], disc(1.0, 1.0, COARSE_DISC), settings).run()[0]
    executor = launch(owners=owners)
    executor.min_rays = 0  # a job this small would otherwise stay in one process
    executor.start_s = 0.0  # and a spawned worker's share is not cut for its start-up
    two_workers = job.TransferJob([receiver], disc(1.0, 1.0, COARSE_DISC), settings, executor)
    return one, two_workers


def assert_bit_identical(one, two):
    np.testing.assert_array_equal(one.transfer, two.transfer)
    np.testing.assert_array_equal(one.std_error, two.std_error)
    np.testing.assert_array_equal(one.rays, two.rays)


@pytest.mark.parametrize("launch, owners, starts_here", [
    (SPAWNED, None, [0, 256, 512]),           # chunk_owners' split: interleaved when workers start at once
    (FORKED, [1, 0, 1, 1, 0], [128, 512]),    # a fixed split instead of the shared queue
], ids=["spawned", "forked"])
def test_workers_give_bit_identical_results(launch, owners, starts_here, chunks_baked_here):
    one, two_workers = bake_alone_and_with_a_worker(launch, owners)
    chunks_baked_here.clear()
    two = two_workers.run()[0]
    assert_bit_identical(one, two)
    assert chunks_baked_here == starts_here  # this process baked its chunks and no other, the worker the rest
    assert two_workers.done_vertices == 600  # the worker's progress lines arrived, each chunk counted once


def test_forked_workers_taking_chunks_from_the_shared_queue_give_bit_identical_results(chunks_baked_here):
    """Who takes which chunk depends on the machine's load; the results and the count of vertices do not."""
    one, two_workers = bake_alone_and_with_a_worker(FORKED)
    chunks_baked_here.clear()
    two = two_workers.run()[0]
    assert_bit_identical(one, two)
    assert len(set(chunks_baked_here)) == len(chunks_baked_here)
    assert two_workers.done_vertices == 600  # each chunk baked exactly once, here or in the worker


def test_the_chunk_queue_hands_each_chunk_to_exactly_one_process():
    chunks = workers.ChunkQueue(range(50_000))  # more records than a pipe holds: the filler waits for readers
    taken_by_the_worker, taken_here_meanwhile = 1_000, 20_000  # together fewer than all: neither runs short
    read_back, write_back = os.pipe()
    child = os.fork()
    if child == 0:  # a forked worker: takes its chunks while this process takes others, reports them, leaves
        try:
            chunks.in_worker()
            os.close(read_back)
            taken = np.fromiter(itertools.islice(chunks, taken_by_the_worker), dtype=np.int64)
            with os.fdopen(write_back, "wb") as out:
                out.write(taken.tobytes())
        finally:
            os._exit(0)  # never back into pytest: a failure shows as a short report
    os.close(write_back)
    chunks.fill()
    taking = iter(chunks)
    here = list(itertools.islice(taking, taken_here_meanwhile))
    with os.fdopen(read_back, "rb") as back:
        there = np.frombuffer(back.read(), dtype=np.int64)  # the worker has taken its chunks
    here = np.array(here + list(taking))  # the rest, until the queue ends
    os.waitpid(child, 0)
    chunks.close()
    assert len(there) == taken_by_the_worker and len(here) == 50_000 - taken_by_the_worker
    np.testing.assert_array_equal(np.sort(np.concatenate([here, there])), np.arange(50_000))
    assert np.all(np.diff(here) > 0) and np.all(np.diff(there) > 0)  # in order, none twice


def test_an_abandoned_chunk_queue_stops_filling():
    abandoned = workers.ChunkQueue(range(50_000))  # more records than a pipe holds: the filler blocks
    abandoned.fill()
    first = next(iter(abandoned))
    abandoned.close()  # a cancelled bake: the filler, maybe blocked on a full pipe, must end
    abandoned.filler.join(timeout=5.0)  # a bound for a filler that never ends, not a race
    assert first == 0 and not abandoned.filler.is_alive()


def test_batching_a_round_never_changes_a_result(monkeypatch):
    """Rounds weigh WEIGHT_BYTES_PER_BATCH of weights at a time; each vertex keeps its own random streams, so any
    batch size gives the same bits, target-error rounds included."""
    rng = np.random.default_rng(6)
    positions = np.column_stack([rng.uniform(-1.5, 1.5, (200, 2)), np.zeros(200)])
    receiver = bake.Receiver("b", positions, np.tile([0.0, 0.0, 1.0], (200, 1)), 22)
    settings = dict(order=4, samples=64, target_error=0.03, max_samples=1024)
    (whole,), _ = run([receiver], disc(1.0, 1.0, COARSE_DISC), **settings)
    monkeypatch.setattr(estimator, "WEIGHT_BYTES_PER_BATCH", 2400)  # a few vertices per batch, uneven last batches
    yields = []
    work = estimator.bake_chunk(ray_caster.RayCaster(disc(1.0, 1.0, COARSE_DISC)), receiver,
                                np.arange(scheduling.CHUNK_VERTICES), bake.BakeSettings(**settings))
    try:
        while True:
            yields.append(next(work))
    except StopIteration:
        pass
    assert len(yields) > 20 and np.median(yields) <= 300 and max(yields) <= 1024  # a vertex's round is never split
    (batched,), _ = run([receiver], disc(1.0, 1.0, COARSE_DISC), **settings)
    np.testing.assert_array_equal(whole.transfer, batched.transfer)
    np.testing.assert_array_equal(whole.std_error, batched.std_error)
    np.testing.assert_array_equal(whole.rays, batched.rays)
    assert whole.rays.max() > 64  # the target made more rounds


@pytest.mark.parametrize("field, value", [("order", 0), ("order", 17), ("samples", 4), ("mode", "glossy"),
                                          ("target_error", float("nan")), ("replicates", 1)])
def test_settings_out_of_range_are_named(field, value):
    problems = bake.BakeSettings(**{field: value}).problems()
    assert len(problems) == 1 and field.split("_")[0] in problems[0]


def test_chunk_split_gives_this_process_the_workers_start_up_time():
    owners = workers.chunk_owners(200, 2, estimated_s=10.0, start_s=1.0)
    assert owners.count(0) == 110 and owners.count(1) == 90  # t = 5.5 s: 55 % here, 45 % in the worker
    assert workers.chunk_owners(6, 3, estimated_s=10.0, start_s=0.0) == [0, 1, 2, 0, 1, 2]  # interleaved
    assert set(workers.chunk_owners(10, 2, estimated_s=0.1, start_s=1.0)) == {0}  # not worth starting one
