"""Interreflections gathered over the shadow pass's hits: the stiff closed box and colour bleeding."""

import functools
import sys

import numpy as np
import pytest

from prt_addon.core import bake, executors, interreflect, job, lobes, scheduling

ENGINE = "reference"  # the estimator's tests need no Blender


def closed_box(cuts=4, size=2.0):
    """A cube of (6 × cuts²) quads facing inwards, vertices shared along edges, as one receiver + occluder."""
    ticks = np.linspace(-size / 2, size / 2, cuts + 1)
    points, quads = {}, []

    def index(p):
        key = tuple(np.round(p, 9))
        if key not in points:
            points[key] = len(points)
        return points[key]

    for axis in range(3):
        for side in (-1.0, 1.0):
            u_axis, v_axis = [a for a in range(3) if a != axis]
            for i in range(cuts):
                for j in range(cuts):
                    corners = []
                    for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.zeros(3)
                        p[axis], p[u_axis], p[v_axis] = side * size / 2, ticks[i + du], ticks[j + dv]
                        corners.append(index(p))
                    # wind so the face normal points into the box
                    normal_out = np.zeros(3)
                    normal_out[axis] = side
                    a, b, c = (np.array(list(points)[k]) for k in corners[:3])
                    if np.dot(np.cross(b - a, c - a), normal_out) > 0:
                        corners.reverse()
                    quads.append(corners)
    vertices = np.array(list(points))
    triangles = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    normals = np.zeros_like(vertices)
    for t in triangles:
        a, b, c = vertices[t]
        normals[t] += np.cross(b - a, c - a)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return vertices, triangles, normals


def interreflected_job(vertices, triangles, normals, albedo, **settings):
    receiver = bake.Receiver("box", vertices, normals, 9)
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), solved_vertices=len(vertices), engine=ENGINE)
    the_job = job.TransferJob([receiver], occluders, bake.BakeSettings(mode="interreflected", **settings),
                              albedo=[albedo])
    return the_job, the_job.run()


@pytest.mark.parametrize("albedo", [0.95, 0.99])
def test_closed_box_sums_the_neumann_series_exactly(albedo):
    """Inside a closed box every ray hits a front face, so each row of G sums to 1 and (ρG)^b keeps a
    constant: a constant direct transfer c must total c / (1 − ρ), with no Monte Carlo error at all."""
    vertices, triangles, normals = closed_box()
    the_job, (result,) = interreflected_job(vertices, triangles, normals, np.full((len(vertices), 1), albedo),
                                            order=2, samples=64)
    np.testing.assert_allclose(result.transfer, 0.0, atol=1e-12)  # no sky is visible from inside
    records = interreflect.HitRecords.concatenate(the_job.records)
    operator = interreflect.bounce_operator(records, triangles, len(vertices))
    np.testing.assert_allclose(operator.apply(np.ones((len(vertices), 1))), 1.0, atol=1e-12)
    direct = np.zeros((len(vertices), 4))
    direct[:, 0] = 0.25
    total, report = interreflect.interreflect(direct, np.full((len(vertices), 1), albedo), operator,
                                              tolerance=1e-4)
    assert np.isfinite(total).all() and report.converged
    np.testing.assert_allclose(total[:, 0, 0], 0.25 / (1 - albedo), rtol=1e-4)
    np.testing.assert_allclose(total[:, 0, 1:], 0.0, atol=1e-12)
    assert 1 <= report.bounces < 200  # the geometric tail makes even ρ = 0.99 quick


def random_records(rng, vertices, hits_per_row):
    """Hit records of `vertices` casting vertices, row i with hits_per_row[i] hits on random triangles."""
    rows = np.repeat(np.arange(vertices), hits_per_row)
    count = len(rows)
    return interreflect.HitRecords(rows, rng.integers(0, 2 * vertices, count), rng.dirichlet([1, 1, 1], count),
                                   rng.random(count) / np.maximum(hits_per_row[rows], 1),
                                   rng.integers(0, 4, count))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_bounce_operator_is_the_sum_over_the_hits(seed):
    """G @ x against the sum, hit by hit and corner by corner, of weight · β · x[corner] into the casting vertex's
    row, one weighted bincount per column: equal to rounding, on rows full enough to be held dense, rows too
    sparse for that, empty rows and hits on corners beyond the solved vertices."""
    rng = np.random.default_rng(seed)
    vertices = 300
    hits_per_row = np.where(np.arange(vertices) < 150, rng.integers(200, 400, vertices), rng.integers(0, 4, vertices))
    records = random_records(rng, vertices, hits_per_row)
    triangles = rng.integers(0, vertices + 20, (2 * vertices, 3))  # some corners are instances', beyond the solved
    operator = interreflect.bounce_operator(records, triangles, vertices)
    assert operator.dense and operator.sparse
    values = rng.standard_normal((vertices, 3, 16))
    flat = values.reshape(vertices, -1)
    corners = triangles[records.triangle].ravel()
    inside = corners < vertices
    rows = np.repeat(records.vertex, 3)[inside]
    weights = (records.weight[:, None] * records.barycentric).ravel()[inside]
    expected = np.stack([np.bincount(rows, weights * flat[corners[inside], column], minlength=vertices)
                         for column in range(flat.shape[1])], axis=1)
    bound = np.stack([np.bincount(rows, weights * np.abs(flat[corners[inside], column]), minlength=vertices)
                      for column in range(flat.shape[1])], axis=1)  # |G| @ |x|: the scale of the sums' rounding
    found = operator.apply(values).reshape(vertices, -1)
    assert np.all(np.abs(found - expected) <= 1e-12 * bound)
    assert not found[hits_per_row == 0].any()


def test_auto_bounces_match_many_fixed_bounces_on_a_non_constant_transfer():
    vertices, triangles, normals = closed_box(cuts=3)
    the_job, _ = interreflected_job(vertices, triangles, normals, np.full((len(vertices), 1), 0.9),
                                    order=3, samples=64)
    operator = interreflect.bounce_operator(interreflect.HitRecords.concatenate(the_job.records), triangles,
                                            len(vertices))
    direct = lobes.unshadowed_transfer(3, normals)  # any non-constant start
    albedo = np.full((len(vertices), 1), 0.9)
    auto, report = interreflect.interreflect(direct, albedo, operator, tolerance=1e-6)
    many, _ = interreflect.interreflect(direct, albedo, operator, bounces=600)
    assert report.bounces < 600
    np.testing.assert_allclose(auto, many, atol=1e-5 * np.abs(many).max())


def test_albedo_one_stays_bounded():
    vertices, triangles, normals = closed_box(cuts=2)
    the_job, _ = interreflected_job(vertices, triangles, normals, np.ones((len(vertices), 1)), order=2, samples=32)
    operator = interreflect.bounce_operator(interreflect.HitRecords.concatenate(the_job.records), triangles,
                                            len(vertices))
    direct = np.zeros((len(vertices), 4))
    direct[:, 0] = 1.0
    total, report = interreflect.interreflect(direct, np.ones((len(vertices), 1)), operator, tolerance=1e-4)
    assert report.albedo_clamped and np.isfinite(total).all()
    np.testing.assert_allclose(total[:, 0, 0], 1 / (1 - interreflect.MAX_ALBEDO), rtol=1e-3)


@pytest.mark.parametrize("limit", [3, interreflect.MAX_BOUNCES])
def test_auto_bounces_stopped_at_the_limit_tell_the_user(monkeypatch, limit):
    """A box open at the top lets the sky in; at ρ = 0.95 three bounces leave much of the series out, so a bake
    that hits that limit must say it did not converge, and one under the real limit must not."""
    vertices, triangles, normals = closed_box(cuts=2)
    open_top = triangles[~np.all(vertices[triangles][:, :, 2] > 0.0, axis=1)]
    monkeypatch.setattr(interreflect, "MAX_BOUNCES", limit)
    the_job, results = interreflected_job(vertices, open_top, normals, np.full((len(vertices), 1), 0.95),
                                          order=2, samples=32)
    summary = the_job.summary(results)
    stopped = limit == 3
    assert the_job.bounce_report.converged is summary.bounces_converged is (not stopped)
    assert (summary.bounces == 3) is stopped and np.any(results[0].transfer)
    assert ("NOT converged" in summary.line()) is stopped


def test_white_floor_turns_red_beside_a_red_wall():
    """A floor with a red wall standing on one side: floor vertices near the wall gather red light."""
    ticks = np.linspace(-1.0, 1.0, 11)
    floor = np.array([(x, y, 0.0) for y in ticks for x in ticks])
    wall = np.array([(1.0, y, z) for z in np.linspace(0.0, 2.0, 11) for y in ticks])
    quads_floor = [(r * 11 + c, r * 11 + c + 1, (r + 1) * 11 + c + 1, (r + 1) * 11 + c) for r in range(10)
                   for c in range(10)]
    quads_wall = [(121 + r * 11 + c + 1, 121 + r * 11 + c, 121 + (r + 1) * 11 + c, 121 + (r + 1) * 11 + c + 1)
                  for r in range(10) for c in range(10)]  # facing −X, into the room
    vertices = np.vstack([floor, wall])
    quads = quads_floor + quads_wall
    triangles = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (121, 1)), np.tile([-1.0, 0.0, 0.0], (121, 1))])
    albedo = np.vstack([np.tile([0.8, 0.8, 0.8], (121, 1)), np.tile([0.8, 0.05, 0.05], (121, 1))])
    receiver = bake.Receiver("room", vertices, normals, 4)
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), solved_vertices=len(vertices), engine=ENGINE)
    the_job = job.TransferJob([receiver], occluders,
                              bake.BakeSettings(mode="interreflected", order=3, samples=256, bounces=3), albedo=[albedo])
    (result,) = the_job.run()
    assert result.transfer.shape == (242, 3, 9)
    near, far = 5 * 11 + 9, 5 * 11 + 0  # floor vertices at x = 0.8 and x = −1
    red_over_green = result.transfer[:, 0, 0] / result.transfer[:, 1, 0]
    assert red_over_green[near] > 1.05 and red_over_green[near] > red_over_green[far] + 0.03
    summary = the_job.summary([result])
    assert summary.bounces == 3 and len(summary.bounce_relative_changes) == 3 and summary.bounces_converged  # as asked
    assert summary.bounce_relative_changes[0] > summary.bounce_relative_changes[1] > summary.bounce_relative_changes[2] > 0


def records_in_chunk_order(the_job):
    """The job's hit records as (vertex, triangle, barycentric, weight), chunk by chunk, whichever process baked
    each chunk and whenever its records arrived (a stable sort keeps each chunk's own order)."""
    records = interreflect.HitRecords.concatenate(the_job.records)
    order = np.argsort(records.vertex // scheduling.CHUNK_VERTICES, kind="stable")
    return [getattr(records, name)[order] for name in interreflect.HitRecords.FIELDS]


@pytest.mark.parametrize("launch", [functools.partial(executors.SpawnedWorkers, 2, [sys.executable, "-c"]),
                                    functools.partial(executors.ForkedWorkers, 2)], ids=["spawned", "forked"])
def test_workers_bring_back_the_hit_records_bit_identically(launch, chunks_baked_here):
    """The bounces gather over every chunk's hit records, so the records must come back from the workers whole."""
    vertices, triangles, normals = closed_box(cuts=8)  # 386 vertices: 4 chunks
    settings = bake.BakeSettings(mode="interreflected", order=3, samples=64, bounces=2)
    albedo = np.full((len(vertices), 1), 0.7)
    one_process, (one,) = interreflected_job(vertices, triangles, normals, albedo, order=3, samples=64, bounces=2)
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), solved_vertices=len(vertices), engine=ENGINE)
    executor = launch(owners=[1, 0, 1, 0])
    executor.min_rays = 0  # a job this small would otherwise stay in one process
    two_workers = job.TransferJob([bake.Receiver("box", vertices, normals, 9)], occluders, settings, executor,
                                  albedo=[albedo])
    chunks_baked_here.clear()
    (two,) = two_workers.run()
    assert chunks_baked_here == [128, 384]  # this process baked chunks 1 and 3, the worker 0 and 2
    # No sky is visible from inside the box, so the transfer is 0 either way: the records must be compared.
    expected, returned = records_in_chunk_order(one_process), records_in_chunk_order(two_workers)
    assert len(expected[0]) > 0
    for expected_field, returned_field in zip(expected, returned):
        np.testing.assert_array_equal(expected_field, returned_field)
    np.testing.assert_array_equal(one.transfer, two.transfer)
    np.testing.assert_array_equal(one.std_error, two.std_error)


def open_box(cuts=6):
    """A box of 5 walls open at +Y (a Cornell box without its light), each a cuts × cuts grid facing inwards with
    its own vertices, and the walls as flat polygons: (vertices, triangles, normals, polygons)."""
    ticks = np.linspace(-1.0, 1.0, cuts + 1)
    u, v = (grid.ravel() for grid in np.meshgrid(ticks, ticks, indexing="ij"))
    quads = [(i * (cuts + 1) + j, (i + 1) * (cuts + 1) + j, (i + 1) * (cuts + 1) + j + 1, i * (cuts + 1) + j + 1)
             for i in range(cuts) for j in range(cuts)]
    walls = {(2, -1.0): (0, 1), (2, 1.0): (0, 1), (1, -1.0): (0, 2), (0, -1.0): (1, 2), (0, 1.0): (1, 2)}
    vertices, triangles, normals, polygons = [], [], [], []
    for (axis, side), (first, second) in walls.items():
        wall = np.zeros((len(u), 3))
        wall[:, axis], wall[:, first], wall[:, second] = side, u, v
        inward = np.zeros(3)
        inward[axis] = -side
        base = sum(len(w) for w in vertices)
        for a, b, c, d in quads:
            for tri in ((a, b, c), (a, c, d)):
                p = wall[list(tri)]
                facing = np.dot(np.cross(p[1] - p[0], p[2] - p[0]), inward) > 0
                triangles.append([base + k for k in (tri if facing else tri[::-1])])
        vertices.append(wall)
        normals.append(np.tile(inward, (len(wall), 1)))
        corners = wall[[0, cuts, len(wall) - 1, len(wall) - 1 - cuts]]
        polygons.append(corners)
    return np.concatenate(vertices), np.array(triangles), np.concatenate(normals), polygons


def test_the_estimate_covers_the_bounces_noise():
    """Flat walls are exact closed-form occluders, so the direct transfer has no noise at all; the bounces gather
    over Monte Carlo hits and do. Two seeds must differ as much as their estimates say (within 1.5 ×), and a
    shadowed bake of the same walls estimates exactly zero away from the walls' seams (at a seam the next wall's
    plane grazes the ray origins, where its rays and its closed form may disagree)."""
    vertices, triangles, normals, polygons = open_box()
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), polygons, solved_vertices=len(vertices),
                               engine=ENGINE)
    albedo = np.full((len(vertices), 1), 0.7)
    results = []
    for seed in (0, 1):
        the_job = job.TransferJob([bake.Receiver("box", vertices, normals, 9)], occluders,
                                  bake.BakeSettings(mode="interreflected", order=3, samples=256, bounces=None,
                                                    seed=seed), albedo=[albedo])
        results.append(the_job.run()[0])
    shadowed = job.TransferJob([bake.Receiver("box", vertices, normals, 9)], occluders,
                               bake.BakeSettings(order=3, samples=256)).run()[0]
    inside = (np.abs(vertices) > 1.0 - 1e-9).sum(axis=1) == 1
    assert inside.sum() > 100 and shadowed.std_error[inside].max() == 0.0
    assert results[0].std_error[inside].min() > 0.0
    difference = np.linalg.norm(results[0].transfer - results[1].transfer, axis=-1)
    expected = np.hypot(results[0].std_error, results[1].std_error)
    ratio = np.sqrt(np.mean(difference ** 2) / np.mean(expected ** 2))
    assert 1 / 1.5 <= ratio <= 1.5, ratio
