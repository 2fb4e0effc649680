"""The reference ray engine (numpy alone) against closed forms: where a ray meets a triangle, the nearest of stacked
triangles, the rays a mask leaves out, and the nearest point of a triangle against a dense sampling of it."""

import numpy as np
import pytest

from prt_addon.core import engines

# One triangle in the plane z = 0.5: its corners at (0, 0), (1, 0), (0, 1); float32-exact, as an engine holds them.
TRIANGLE = np.array([[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [0.0, 1.0, 0.5]])


def engine_of(vertices, triangles, max_distance=100.0):
    return engines.build("reference", np.asarray(vertices, dtype=np.float64), np.asarray(triangles), max_distance)


def float32_exact(values):
    return np.asarray(values, dtype=np.float32).astype(np.float64)


def test_a_ray_meets_a_triangle_where_the_plane_says_from_either_side():
    """Rays through random points of the triangle's plane, from above and from below, at random slopes: a ray hits
    where its point lies inside the triangle (barycentric weights (1 − x − y, x, y)), at the distance to that point."""
    rng = np.random.default_rng(1)
    targets = np.column_stack([rng.uniform(-0.2, 1.2, (400, 2)), np.full(400, 0.5)])
    directions = rng.normal(size=(400, 3)) * [0.4, 0.4, 1.0]
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    directions = float32_exact(directions)
    lengths = rng.uniform(0.5, 2.0, 400)
    origins = targets - lengths[:, None] * directions  # half start below the plane, half above
    inside = (targets[:, 0] >= 0) & (targets[:, 1] >= 0) & (targets[:, 0] + targets[:, 1] <= 1)
    clear = np.minimum.reduce([targets[:, 0], targets[:, 1], 1 - targets[:, 0] - targets[:, 1]])
    clear = np.abs(clear) > 1e-5  # not on an edge, where float32 rounding decides
    engine = engine_of(TRIANGLE, [[0, 1, 2]])
    hits = engine.hits(origins, directions[:, None])
    assert hits.found.shape == (400, 1) and 60 < inside.sum() < 340
    np.testing.assert_array_equal(hits.found[clear, 0], inside[clear])
    np.testing.assert_array_equal(engine.occluded(origins, directions[:, None]), hits.found)
    hit = hits.found[:, 0]
    assert (hits.triangle[hit] == 0).all() and (hits.triangle[~hit] == -1).all()
    assert np.isnan(hits.distance[~hit]).all() and np.isnan(hits.barycentric[~hit]).all()
    # where the ray from the origin as the engine reads it, in float32, meets the plane
    starts = float32_exact(origins)
    distance = (0.5 - starts[:, 2]) / directions[:, 2]
    points = starts + distance[:, None] * directions
    np.testing.assert_allclose(hits.distance[hit, 0], distance[hit], rtol=1e-12)
    weights = np.column_stack([1 - points[:, 0] - points[:, 1], points[:, 0], points[:, 1]])
    np.testing.assert_allclose(hits.barycentric[hit, 0], weights[hit], atol=1e-12)


def test_a_ray_hits_the_nearest_of_stacked_triangles_within_its_reach():
    """Copies of the triangle at z = 0.5, 1.5, 2.5 (listed far to near): a ray up from z = 0 hits the one at 0.5;
    from z = 1 the one at 1.5; from z = 3 nothing above; and with a reach of 0.4 nothing at all."""
    stacked = np.vstack([TRIANGLE + [0, 0, 2.0], TRIANGLE + [0, 0, 1.0], TRIANGLE])
    triangles = np.arange(9).reshape(3, 3)
    origins = np.array([[0.2, 0.2, 0.0], [0.2, 0.2, 1.0], [0.2, 0.2, 3.0]])
    up = np.tile([[[0.0, 0.0, 1.0]]], (3, 1, 1))
    hits = engine_of(stacked, triangles).hits(origins, up)
    np.testing.assert_array_equal(hits.triangle[:, 0], [2, 1, -1])
    np.testing.assert_allclose(hits.distance[:2, 0], [0.5, 0.5])
    assert not engine_of(stacked, triangles, max_distance=0.4).occluded(origins, up).any()


def test_rays_left_out_by_the_mask_miss_and_the_others_are_cast_as_without_it():
    rng = np.random.default_rng(2)
    origins = np.column_stack([rng.uniform(0.0, 0.5, (6, 2)), np.zeros(6)])
    directions = rng.normal(size=(6, 50, 3)) * [0.3, 0.3, 1.0]
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    live = rng.random((6, 50)) < 0.6
    engine = engine_of(TRIANGLE, [[0, 1, 2]])
    every, masked = engine.hits(origins, directions), engine.hits(origins, directions, live)
    assert every.found[live].sum() > 20 and every.found[~live].sum() > 10  # teeth: hits both in and out of the mask
    np.testing.assert_array_equal(masked.triangle, np.where(live, every.triangle, -1))
    np.testing.assert_array_equal(masked.distance, np.where(live, every.distance, np.nan))
    np.testing.assert_array_equal(masked.barycentric, np.where(live[..., None], every.barycentric, np.nan))
    np.testing.assert_array_equal(engine.occluded(origins, directions, live), every.found & live)


def test_an_engine_without_triangles_answers_nothing():
    engine = engine_of(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    assert not engine.occluded(np.zeros((2, 3)), np.ones((2, 4, 3)) / np.sqrt(3)).any()
    assert len(engine.nearest(np.zeros((5, 3)), 1.0).triangle) == 0


@pytest.mark.parametrize("tilt", [0.0, 0.7])
def test_the_nearest_point_of_a_triangle_is_the_nearest_of_a_dense_sampling(tilt):
    """Points all around a triangle (beyond each corner and edge, above and below its face): the nearest point and
    distance match the nearest of 300,000 points spread over the triangle, within the sampling's spacing; the normal
    is the triangle's unit normal; a point is listed only within the radius."""
    turn = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(tilt), -np.sin(tilt)], [0.0, np.sin(tilt), np.cos(tilt)]])
    corners = float32_exact(TRIANGLE @ turn.T)
    rng = np.random.default_rng(3)
    points = (np.column_stack([rng.uniform(-1.0, 2.0, (300, 2)), rng.uniform(-0.5, 1.5, 300)])) @ turn.T
    u, v = np.meshgrid(np.linspace(0, 1, 775), np.linspace(0, 1, 775))
    keep = u + v <= 1
    samples = corners[0] + u[keep, None] * (corners[1] - corners[0]) + v[keep, None] * (corners[2] - corners[0])
    truth = np.array([np.min(np.linalg.norm(samples - point, axis=1)) for point in float32_exact(points)])
    spacing = np.sqrt(2) / 774
    near = engine_of(corners, [[0, 1, 2]]).nearest(points, 10.0)
    np.testing.assert_array_equal(near.point, np.arange(300))
    assert (near.triangle == 0).all()
    np.testing.assert_allclose(near.distance, truth, atol=spacing)
    np.testing.assert_allclose(np.linalg.norm(near.location - float32_exact(points), axis=1), near.distance,
                               rtol=1e-12)
    on_triangle = np.linalg.norm(samples[:, None] - near.location[None, :50], axis=2).min(axis=0)
    assert on_triangle.max() < spacing  # the nearest point lies on the triangle
    np.testing.assert_allclose(near.normal, np.tile(turn @ [0.0, 0.0, 1.0], (300, 1)), atol=1e-7)
    radius = np.median(truth)
    within = engine_of(corners, [[0, 1, 2]]).nearest(points, radius)
    np.testing.assert_array_equal(within.point, np.flatnonzero(near.distance < radius))
