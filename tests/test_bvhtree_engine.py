"""The BVHTree engine (mathutils) against the reference engine (numpy), ray by ray and point by point on a few
scenes: which rays are blocked, the triangle each hits first, its distance and barycentric weights, and the
triangles near a point (their nearest points, normals and distances). Where float32 rounding may decide (a ray
within 1e-4 of a triangle's edge, two hits at one distance, a point at the search radius) the engines may differ;
such rays and points are left out, and they are few."""

import bpy  # noqa: F401  (mathutils comes with bpy)
import numpy as np
import pytest
from mathutils import Vector

from ray_scenes import EDGE, SCENES, assert_agrees_with_the_reference, engine_and_reference, triangle_soup

@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_engines_agree_on_every_ray(name, dtype):
    assert_agrees_with_the_reference("bvhtree", name, dtype)


@pytest.mark.parametrize("name", SCENES)
def test_the_engines_find_the_same_surfaces_near_a_point(name):
    vertices, triangles = SCENES[name]()
    vertices, (tree, reference) = engine_and_reference("bvhtree", vertices, triangles)
    rng = np.random.default_rng(6)
    points = np.vstack([rng.uniform(vertices.min(0), vertices.max(0), (150, 3)),
                        vertices[rng.integers(0, len(vertices), 50)] + rng.normal(scale=1e-3, size=(50, 3))])
    radius = 0.1
    got, truth = tree.nearest(points, radius), reference.nearest(points, radius)
    found = {(p, t): i for i, (p, t) in enumerate(zip(got.point.tolist(), got.triangle.tolist()))}
    expected = {(p, t): i for i, (p, t) in enumerate(zip(truth.point.tolist(), truth.triangle.tolist()))}
    at_radius = {pair for pair, i in {**found, **expected}.items()
                 if abs((got.distance[found[pair]] if pair in found else truth.distance[expected[pair]]) - radius)
                 < EDGE * radius}
    assert set(found) - at_radius == set(expected) - at_radius and len(expected) > 100  # teeth: many to compare
    assert np.all(np.diff(got.point) >= 0)  # listed point by point
    pairs = sorted(set(found) & set(expected))
    mine, theirs = [found[pair] for pair in pairs], [expected[pair] for pair in pairs]
    np.testing.assert_allclose(got.location[mine], truth.location[theirs], atol=1e-6)
    np.testing.assert_allclose(got.normal[mine], truth.normal[theirs], atol=1e-6)
    np.testing.assert_allclose(got.distance[mine], truth.distance[theirs], atol=1e-6)


def test_the_tree_engines_normals_and_nearest_points_are_the_trees_own():
    """The engine computes the normals of the faces it finds rather than read them from the tree: bit for bit the
    tree's own, as are the nearest points and distances it reads."""
    vertices, triangles = triangle_soup()
    vertices, (tree, _) = engine_and_reference("bvhtree", vertices, triangles)
    points = np.random.default_rng(7).uniform(-0.5, 0.5, (100, 3))
    near = tree.nearest(points, 0.2)
    read = [found for point in points.tolist() for found in tree.tree.find_nearest_range(point, 0.2)]
    assert len(read) == len(near.triangle) > 200
    np.testing.assert_array_equal(near.triangle, [index for _, _, index, _ in read])
    np.testing.assert_array_equal(near.normal, [list(normal) for _, normal, _, _ in read])
    np.testing.assert_array_equal(near.location, [list(location) for location, _, _, _ in read])
    np.testing.assert_array_equal(near.distance, [distance for _, _, _, distance in read])
    assert isinstance(read[0][1], Vector)
