"""Flat convex occluders in closed form, against quadrature over the polygon and against rays."""

import math

import numpy as np
import pytest

from quadrature import polygon_directions, polygon_transfer, random_directions, reference_sh

from prt_addon.core import polygons, sh

SQUARE = np.array([[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])
PENTAGON = np.array([[math.cos(a), math.sin(a), 0.0] for a in np.linspace(0, 2 * math.pi, 6)[:-1]]) * 1.5 \
    + [0.2, -0.1, 0.7]


CASES = [  # (polygon, apex, normal): in front, seen from behind, cut by the horizon, nearly edge-on
    (SQUARE, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
    (SQUARE, [0.3, 0.2, 2.0], [0.6, 0.0, -0.8]),
    (SQUARE, [0.3, 0.2, 0.5], [0.6, 0.0, 0.8]),
    (PENTAGON, [2.5, 0.4, 0.9], [-0.6, 0.48, 0.64]),
    (PENTAGON, [0.1, 0.2, -0.4], [0.0, 0.8, 0.6]),
]


@pytest.mark.parametrize("order", [1, 4, 10])
@pytest.mark.parametrize("polygon, apex, normal", CASES)
def test_blocked_transfer_matches_quadrature(order, polygon, apex, normal):
    apex, normal = np.array(apex), np.array(normal)
    _, blocked = polygons.cones_and_blocked_transfer(order, apex[None], normal[None], [polygon])
    exact = blocked[0]
    truth = polygon_transfer(order, apex, normal, polygon)
    assert np.abs(exact - truth).max() < 1e-9


def test_double_axis_moments_and_solid_angle_match_quadrature():
    axes = random_directions(7, seed=3)
    normal = np.array([0.36, -0.48, 0.8])
    unit = SQUARE / np.linalg.norm(SQUARE, axis=1, keepdims=True)
    moments = polygons._cosine_moments(unit[None], normal[None], axes, 12)[0]
    directions, weights = polygon_directions(np.zeros(3), SQUARE)
    truth = np.stack([(weights * (directions @ normal)) @ (directions @ axes.T) ** p for p in range(13)], axis=1)
    assert abs(polygons._solid_angle(unit[None])[0] - 2 * math.pi / 3) < 1e-13  # a cube face from its centre: 4π/6
    assert np.abs(moments - truth).max() < 1e-11


def test_lobe_tables_are_well_conditioned_to_order_ten():
    _, to_sh, _ = polygons._zonal_tables(11)
    assert max(np.linalg.cond(table) for table in to_sh) < 1e3


def test_polygon_behind_the_tangent_plane_or_edge_on_blocks_nothing():
    apexes = np.array([[0.0, 0.0, 1.0 + 1e-3], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    planes, blocked = polygons.cones_and_blocked_transfer(6, apexes, normals, [SQUARE])
    assert np.all(blocked == 0.0)
    directions = random_directions(1000)[None].repeat(3, axis=0)
    assert not polygons.hits(directions[1:2], planes[1:2]).any()  # in its plane


def test_hits_are_the_directions_the_transfer_integrates():
    """The estimator is unbiased only if G integrates exactly the rays that `hits` counts: a million
    cosine-distributed rays agree with G within their own standard error."""
    rng = np.random.default_rng(5)
    apex, normal = np.array([0.3, 0.2, 0.5]), np.array([0.6, 0.0, 0.8])
    directions = rng.normal(size=(1_000_000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    directions[directions @ normal < 0] *= -1.0
    cosine = directions @ normal  # uniform on the hemisphere: weight 2π (n·ω)/π per ray
    planes, blocked = polygons.cones_and_blocked_transfer(4, apex[None], normal[None], [SQUARE])
    hit = polygons.hits(directions[None], planes)[0] == 1
    samples = 2.0 * (hit * cosine)[:, None] * sh.evaluate(4, directions)
    exact = blocked[0]
    error = samples.std(0) / math.sqrt(len(samples))
    assert np.all(np.abs(samples.mean(0) - exact) < 5 * error + 1e-12)


def grid(corners_u, corners_v, origin, edge_u, edge_v):
    """A flat grid of quads, two triangles each, counter-clockwise about edge_u × edge_v."""
    i, j = np.meshgrid(np.arange(corners_u), np.arange(corners_v), indexing="ij")
    vertices = (np.asarray(origin) + (i / (corners_u - 1))[..., None] * edge_u
                + (j / (corners_v - 1))[..., None] * edge_v).reshape(-1, 3)
    index = (i * corners_v + j)[:-1, :-1].ravel()
    triangles = np.concatenate([np.stack([index, index + corners_v, index + corners_v + 1], 1),
                                np.stack([index, index + corners_v + 1, index + 1], 1)])
    return vertices, triangles


def test_a_tiled_rectangle_is_found_with_its_four_corners():
    vertices, triangles = grid(7, 5, [1.0, 2.0, 3.0], np.array([2.0, 0.0, 1.0]), np.array([0.0, 3.0, 0.0]))
    polygon = polygons.convex_polygon(vertices, triangles)
    expected = np.array([[1.0, 2.0, 3.0], [3.0, 2.0, 4.0], [3.0, 5.0, 4.0], [1.0, 5.0, 3.0]])
    assert polygon is not None and len(polygon) == 4
    start = int(np.argmin(np.linalg.norm(polygon - expected[0], axis=1)))
    assert np.allclose(np.roll(polygon, -start, axis=0), expected, atol=1e-12)  # counter-clockwise about the normal


def test_shapes_that_are_not_one_convex_tiled_polygon_are_refused():
    vertices, triangles = grid(5, 5, [0.0, 0.0, 0.0], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    holed = np.delete(triangles, [5, 5 + 16], axis=0)  # one quad's two triangles
    notched = np.delete(triangles, [0, 16], axis=0)  # a corner quad: not convex
    flipped = triangles.copy()
    flipped[3] = flipped[3, ::-1]
    bent = vertices.copy()
    bent[12, 2] = 0.01
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    cube_triangles = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    nan = vertices.copy()
    nan[0, 0] = np.nan
    for candidate in [(vertices, holed), (vertices, notched), (vertices, flipped), (bent, triangles),
                      (cube, cube_triangles), (nan, triangles), (vertices, triangles[:0])]:
        assert polygons.convex_polygon(*candidate) is None
    assert polygons.convex_polygon(vertices + 1e-9 * random_directions(len(vertices)), triangles) is not None


def test_largest_keeps_the_biggest_polygons():
    small, large = SQUARE * 0.5, SQUARE * 2.0
    assert [len(p) for p in polygons.largest([small, PENTAGON, large], 2)] == [4, 5]
    assert np.array_equal(polygons.largest([small, PENTAGON, large], 2)[0], large)


def lune_quadrature(order, n, m, nodes=40):
    """(1/π) ∫ (n·ω) Y_k(ω) dω over n's hemisphere in front of m's plane, with scipy's SH: about the axis the two
    planes share the lune is a range of azimuths, whose integrand is a trigonometric polynomial in the polar angle
    and in the azimuth, which Gauss-Legendre in each integrates to round-off."""
    e = np.cross(n, m)
    e /= np.linalg.norm(e)
    a, b = n, np.cross(e, n)  # azimuth 0 at n: its hemisphere is |φ| < π/2
    turn = math.atan2(m @ b, m @ a)
    low, high = max(-math.pi / 2, turn - math.pi / 2), min(math.pi / 2, turn + math.pi / 2)
    x, w = np.polynomial.legendre.leggauss(nodes)
    theta, phi = math.pi * (x + 1) / 2, low + (high - low) * (x + 1) / 2
    t, p = np.meshgrid(theta, phi, indexing="ij")
    directions = (np.cos(t)[..., None] * e + (np.sin(t) * np.cos(p))[..., None] * a
                  + (np.sin(t) * np.sin(p))[..., None] * b).reshape(-1, 3)
    weights = (np.outer(w * math.pi / 2, w * (high - low) / 2) * np.sin(t)).ravel()
    return (weights * (directions @ n)) @ reference_sh(order, directions) / np.pi


@pytest.mark.parametrize("order", [1, 4, 8])
def test_the_lune_a_plane_leaves_of_a_cosine_lobe_matches_quadrature_and_its_share_of_the_sky(order):
    normals, planes = random_directions(6, seed=11), random_directions(6, seed=12)
    planes[0] = -normals[0] + 0.01 * planes[0]  # nearly reversed: a thin lune
    planes[0] /= np.linalg.norm(planes[0])
    exact = polygons.lune_transfer(order, normals, planes)
    truth = np.stack([lune_quadrature(order, n, m) for n, m in zip(normals, planes)])
    assert np.abs(exact - truth).max() < 1e-12
    # its DC coefficient: Y_0 times the cosine-weighted share of the hemisphere, (1 + n·m)/2
    shares = (1 + np.einsum("ij,ij->i", normals, planes)) / 2
    np.testing.assert_allclose(exact[:, 0], shares / (2 * math.sqrt(math.pi)), rtol=1e-12, atol=1e-15)


def test_a_plane_a_rounding_away_from_the_tangent_plane_leaves_the_whole_lobe():
    """A fin corner's normal and its face's plane, one direction computed twice from a mesh's float32 values and
    3.7e-9 rad apart (the benchmark's fender): the lune is the whole lobe within that rounding, every band."""
    normal = np.array([[0.19509047265361584, 0.0, 0.9807852504395591]])
    plane = np.array([[0.1950904762720202, 0.0, 0.9807852497198133]])
    np.testing.assert_allclose(polygons.lune_transfer(4, normal, plane), polygons.lobes.unshadowed_transfer(4, normal),
                               atol=1e-8)


def test_a_plane_along_the_tangent_plane_leaves_the_whole_lobe_or_none():
    normals = random_directions(3, seed=5)
    np.testing.assert_allclose(polygons.lune_transfer(4, normals, normals),
                               polygons.lobes.unshadowed_transfer(4, normals), atol=1e-15)
    assert not polygons.lune_transfer(4, normals, -normals).any()
