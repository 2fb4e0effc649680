"""Scenes on which the ray engines are compared with the reference engine (numpy) ray by ray, and the rays that
float32 rounding may decide (a ray within 1e-4 of a triangle's edge, two hits at one distance), which the
comparisons leave out: they are few."""

import numpy as np

from prt_addon.core import engines

EDGE = 1e-4  # barycentric weight (or relative distance) within which float32 rounding may decide


def sphere_on_floor():
    """A UV sphere of radius 0.5 resting on a floor of two triangles."""
    rings, segments = 12, 24
    theta, phi = np.meshgrid(np.linspace(0, np.pi, rings + 1)[1:-1], np.linspace(0, 2 * np.pi, segments + 1)[:-1],
                             indexing="ij")
    points = np.column_stack([np.sin(theta).ravel() * np.cos(phi).ravel(), np.sin(theta).ravel() * np.sin(phi).ravel(),
                              np.cos(theta).ravel()])
    vertices = np.vstack([[0, 0, 1.0], points, [0, 0, -1.0]]) * 0.5 + [0, 0, 0.5]
    south, triangles = len(vertices) - 1, []
    for s in range(segments):
        t = (s + 1) % segments
        triangles += [[0, 1 + s, 1 + t], [south, 1 + (rings - 2) * segments + t, 1 + (rings - 2) * segments + s]]
        for r in range(rings - 2):
            a, b = 1 + r * segments + s, 1 + r * segments + t
            triangles += [[a, a + segments, b], [b, a + segments, b + segments]]
    floor = np.array([[-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [2.0, 2.0, 0.0], [-2.0, 2.0, 0.0]])
    triangles += [[south + 1, south + 2, south + 3], [south + 1, south + 3, south + 4]]
    return np.vstack([vertices, floor]), np.array(triangles)


def room_with_a_cube():
    """A closed box 4 × 4 × 3 and a cube of side 1 standing on its floor, 24 triangles."""
    def box(low, high):
        corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
        faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
        return corners, np.array([t for f in faces for t in ([f[0], f[1], f[2]], [f[0], f[2], f[3]])])
    room, room_triangles = box([-2.0, -2.0, 0.0], [2.0, 2.0, 3.0])
    cube, cube_triangles = box([-0.3, 0.2, 0.0], [0.7, 1.2, 1.0])
    return np.vstack([room, cube]), np.vstack([room_triangles, cube_triangles + 8])


def triangle_soup():
    """200 random triangles of all sizes in a unit cube, crossing each other."""
    rng = np.random.default_rng(4)
    centres = rng.uniform(-0.5, 0.5, (200, 1, 3))
    vertices = (centres + rng.normal(size=(200, 3, 3)) * rng.uniform(0.02, 0.3, (200, 1, 1))).reshape(-1, 3)
    return vertices, np.arange(600).reshape(200, 3)


SCENES = {"sphere on a floor": sphere_on_floor, "room with a cube": room_with_a_cube, "triangle soup": triangle_soup}


def engine_and_reference(engine, vertices, triangles, reach=None):
    """The engine named `engine` and the reference engine over the scene recentred on its bounding box, as the
    bake's ray caster gives them, their rays reaching `reach` (twice the diagonal, as the bake's)."""
    low, high = vertices.min(0), vertices.max(0)
    vertices = vertices - 0.5 * (low + high)
    reach = reach or 2.0 * float(np.linalg.norm(high - low))
    return vertices, [engines.build(name, vertices, triangles, reach) for name in (engine, "reference")]


def every_crossing(origins, directions, corners):
    """(u, v, t) (n, T) of each ray (origins, directions (n, 3)) with each triangle's plane (Möller–Trumbore, written
    out here), to find the rays that float32 rounding may decide."""
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    pvec = np.cross(directions[:, None], e2[None])
    det = np.einsum("td,ntd->nt", e1, pvec)
    s = origins[:, None] - corners[None, :, 0]
    qvec = np.cross(s, e1[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        return (np.einsum("ntd,ntd->nt", s, pvec) / det, np.einsum("nd,ntd->nt", directions, qvec) / det,
                np.einsum("td,ntd->nt", e2, qvec) / det)


def uncertain_rays(origins, directions, corners):
    """(n,) bool: rays ahead of which some triangle's edge passes within EDGE (in its barycentric weights), or two
    triangles lie at distances within EDGE of each other."""
    u, v, t = every_crossing(origins, directions, corners)
    ahead = t > 0
    margin = np.minimum.reduce([u, v, 1.0 - u - v])
    near_edge = (ahead & (np.abs(margin) < EDGE)).any(axis=1)
    hit_t = np.sort(np.where(ahead & (margin >= 0), t, np.inf), axis=1)[:, :2]
    with np.errstate(invalid="ignore"):  # no hit: inf − inf
        tied = np.isfinite(hit_t[:, 1]) & (hit_t[:, 1] - hit_t[:, 0] < EDGE * np.maximum(hit_t[:, 0], 1.0))
    return near_edge | tied | ~np.isfinite(u).all(axis=1)


def assert_agrees_with_the_reference(engine, scene, dtype):
    """Random rays from inside the scene `scene` (of SCENES), 80 % of them live: the engine `engine` finds the
    reference's hits, ray by ray, but for the few rays float32 rounding may decide."""
    vertices, triangles = SCENES[scene]()
    vertices, (tested, reference) = engine_and_reference(engine, vertices, triangles)
    rng = np.random.default_rng(5)
    origins = rng.uniform(vertices.min(0), vertices.max(0), (40, 3))
    directions = rng.normal(size=(40, 100, 3))
    directions = (directions / np.linalg.norm(directions, axis=2, keepdims=True)).astype(dtype)
    live = rng.random((40, 100)) < 0.8
    got, truth = tested.hits(origins, directions, live), reference.hits(origins, directions, live)
    corners = vertices.astype(np.float32).astype(np.float64)[triangles]
    uncertain = uncertain_rays(np.repeat(origins, 100, axis=0).astype(np.float32).astype(np.float64),
                               directions.reshape(-1, 3).astype(np.float32).astype(np.float64),
                               corners).reshape(40, 100)
    sure = live & ~uncertain
    assert sure.sum() > 0.95 * live.sum() and truth.found[sure].mean() > 0.2  # teeth: most rays compared, many hit
    np.testing.assert_array_equal(got.found[sure], truth.found[sure])
    np.testing.assert_array_equal(got.triangle[sure], truth.triangle[sure])
    both = sure & truth.found
    np.testing.assert_allclose(got.distance[both], truth.distance[both], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(got.barycentric[both], truth.barycentric[both], atol=1e-5)
    assert not got.found[~live].any() and (got.triangle[~live] == -1).all()
    np.testing.assert_array_equal(tested.occluded(origins, directions, live), got.found)
