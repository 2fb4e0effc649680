"""The Embree engine (embreex) against the reference engine (numpy), ray by ray: which rays are blocked, the triangle
each hits first, its distance and barycentric weights, on the scenes the BVHTree engine is held to, and on rays
that graze a surface, cross a shared edge or a corner, meet a face from behind, or end short of it; rays left out
by a mask; the BVHTree engine's contact search; a process forked after the scene is built. Skipped only where
embreex is not installed (CI installs it)."""

import os

import bpy  # noqa: F401  (the contact search's BVHTree comes with bpy)
import numpy as np
import pytest

from ray_scenes import SCENES, assert_agrees_with_the_reference, engine_and_reference, room_with_a_cube
from prt_addon.core import engines

pytest.importorskip("embreex")


def floor_and_roofs():
    """A floor of two triangles 2 × 2 sharing the diagonal x = y, under two more such squares at z = 0.3 and 0.6."""
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    vertices = np.vstack([np.column_stack([square, np.full(4, height)]) for height in (0.0, 0.3, 0.6)])
    triangles = np.vstack([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * level for level in range(3)])
    return vertices, triangles


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_embree_agrees_with_the_reference_on_every_ray(name, dtype):
    assert_agrees_with_the_reference("embree", name, dtype)


def test_rays_through_a_shared_edge_or_corner_find_a_face_and_rays_from_behind_hit_it():
    """Embree is watertight: a ray through the diagonal two triangles share, or through their corners, hits one of
    them and never slips between; a ray meets a face from either side (no back-face culling)."""
    vertices, triangles = floor_and_roofs()
    vertices, (embree, _) = engine_and_reference("embree", vertices[:4], triangles[:2])
    along = np.linspace(-0.99, 0.99, 199)
    targets = np.vstack([np.column_stack([along, along, np.zeros_like(along)]),  # the shared edge
                         vertices[:4] * 0.999999])  # the corners, just inside
    for side in (1.0, -1.0):  # from above, and from below (behind the faces' winding)
        origins = targets + [0.013, -0.007, side * 0.5]
        directions = (targets - origins) / np.linalg.norm(targets - origins, axis=1, keepdims=True)
        got = embree.hits(origins, directions[:, None])
        assert got.found.all()
        assert set(got.triangle.ravel().tolist()) <= {0, 1}
        np.testing.assert_allclose(got.distance[:, 0], np.linalg.norm(targets - origins, axis=1), rtol=1e-5)
        points = np.einsum("rk,rkd->rd", got.barycentric[:, 0], vertices[triangles[got.triangle[:, 0]]])
        np.testing.assert_allclose(points, targets, atol=1e-5)
        assert embree.occluded(origins, directions[:, None]).all()


def test_rays_in_the_plane_of_a_face_miss_it_and_rays_grazing_it_hit_it_where_the_reference_does():
    vertices, triangles = floor_and_roofs()
    vertices, (embree, reference) = engine_and_reference("embree", vertices[:4], triangles[:2])
    angles = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    flat = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    origins = np.array([[-3.0, 0.2, 0.0], [0.1, 0.2, 0.0]])
    assert not embree.occluded(origins, np.stack([flat, flat])).any()  # in the plane: parallel to both faces
    grazing = flat * np.cos(1e-3) + [0.0, 0.0, -np.sin(1e-3)]  # 1 mrad below the horizon from just above
    origins = np.array([[0.1, 0.2, 5e-4], [-0.8, 0.3, 5e-4]])
    directions = np.stack([grazing, grazing])
    got, truth = embree.hits(origins, directions), reference.hits(origins, directions)
    np.testing.assert_array_equal(got.found, truth.found)
    assert got.found.mean() > 0.5
    np.testing.assert_allclose(got.distance[got.found], truth.distance[truth.found], rtol=1e-4)


def test_rays_end_at_the_engines_reach():
    vertices, triangles = floor_and_roofs()
    origins, up = np.array([[0.2, -0.3, 0.1]]), np.array([[[0.0, 0.0, 1.0]]])  # 0.2 below the first roof
    for reach, blocked in [(0.1, False), (0.25, True), (1.0, True)]:
        embree = engines.build("embree", vertices, triangles, reach)
        hits = embree.hits(origins, up)
        assert embree.occluded(origins, up)[0, 0] == hits.found[0, 0] == blocked
        if blocked:
            assert hits.triangle[0, 0] in (2, 3) and hits.distance[0, 0] == pytest.approx(0.2, rel=1e-6)


def test_masked_rays_miss_everything_and_the_rest_are_as_unmasked():
    vertices, triangles = room_with_a_cube()
    vertices, (embree, _) = engine_and_reference("embree", vertices, triangles)
    rng = np.random.default_rng(8)
    origins = rng.uniform(-1.0, 1.0, (30, 3))
    directions = rng.normal(size=(30, 50, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    live = rng.random((30, 50)) < 0.6
    live[3] = False  # a group with no live ray
    every, masked = embree.hits(origins, directions), embree.hits(origins, directions, live)
    assert every.found.all()  # inside a closed room
    np.testing.assert_array_equal(masked.triangle, np.where(live, every.triangle, -1))
    np.testing.assert_array_equal(masked.distance[live], every.distance[live])
    np.testing.assert_array_equal(masked.barycentric[live], every.barycentric[live])
    assert np.isnan(masked.distance[~live]).all() and np.isnan(masked.barycentric[~live]).all()
    np.testing.assert_array_equal(embree.occluded(origins, directions, live), live)


def test_the_engines_give_the_same_weights_for_the_same_hit():
    """Barycentric weights come from the hit's triangle and distance (core.ray_engine.hits_at), whichever engine
    found them: where Embree and BVHTree find one triangle at one float32 distance (a fifth of the hits; the rest
    differ in its last bits), their weights are the same bits."""
    vertices, triangles = SCENES["triangle soup"]()
    vertices, (embree, _) = engine_and_reference("embree", vertices, triangles)
    tree = engines.build("bvhtree", vertices, triangles, embree.max_distance)
    rng = np.random.default_rng(9)
    origins = rng.uniform(-0.5, 0.5, (20, 3))
    directions = rng.normal(size=(20, 200, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    mine, theirs = embree.hits(origins, directions), tree.hits(origins, directions)
    same = mine.found & (mine.triangle == theirs.triangle) & (mine.distance == theirs.distance)
    assert (mine.triangle == theirs.triangle).all() and same.sum() > 500
    np.testing.assert_array_equal(mine.barycentric[same], theirs.barycentric[same])


def test_the_contact_search_is_the_bvhtree_engines():
    vertices, triangles = SCENES["sphere on a floor"]()
    vertices, (embree, _) = engine_and_reference("embree", vertices, triangles)
    tree = engines.build("bvhtree", vertices, triangles, embree.max_distance)
    points = np.random.default_rng(10).uniform(vertices.min(0), vertices.max(0), (200, 3))
    mine, theirs = embree.nearest(points, 0.2), tree.nearest(points, 0.2)
    assert len(mine.triangle) > 100
    for name in ("point", "triangle", "location", "normal", "distance"):
        np.testing.assert_array_equal(getattr(mine, name), getattr(theirs, name))


def test_a_process_forked_after_the_scene_is_built_casts_the_same_rays():
    """Forked bake workers inherit the engine: Embree's BVH is built with the scene (its builder's threads are not
    in a child), and tracing in the child needs none."""
    vertices, triangles = SCENES["room with a cube"]()
    vertices, (embree, _) = engine_and_reference("embree", vertices, triangles)
    rng = np.random.default_rng(11)
    origins = rng.uniform(-1.0, 1.0, (50, 3))
    directions = rng.normal(size=(50, 100, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    read_back, write_back = os.pipe()
    child = os.fork()
    if child == 0:
        try:
            os.close(read_back)
            hits = embree.hits(origins, directions)
            with os.fdopen(write_back, "wb") as out:
                out.write(hits.triangle.tobytes() + hits.distance.tobytes())
        finally:
            os._exit(0)  # never back into pytest
    os.close(write_back)
    with os.fdopen(read_back, "rb") as back:
        answer = back.read()
    os.waitpid(child, 0)
    here = embree.hits(origins, directions)
    assert answer == here.triangle.tobytes() + here.distance.tobytes() and here.found.all()
