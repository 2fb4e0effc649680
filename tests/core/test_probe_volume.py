"""PRT probes against closed forms: the transfer matrix of a probe in the open (the identity, the arriving light's
orders above the distant light's empty), above an infinite floor
(the upper hemisphere's SH product integrals, by Gauss-Legendre quadrature here, with scipy's SH) and above a floor
that reflects a known exitant transfer (plus the lower hemisphere's integrals times it); probes inside a closed box;
the grid's probe positions, trilinear weights and incoming light against hand values."""

import numpy as np
import pytest

from quadrature import reference_sh
from prt_addon.core import bake, probe_grid, probe_transfer

ORDER = 4
SIZE = ORDER * ORDER
RECEIVED = probe_transfer.received_order(ORDER) ** 2  # rows: the arriving light's coefficients
FLOOR = 1000.0  # half the floor's side: rays that miss it lie within 1e-5 rad of the horizon
HEIGHT = 0.01


def caster(vertices, triangles):
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    return bake.Occluders(vertices, triangles, vertices.copy(), engine="reference").ray_caster()


def bake_probes(*arguments, **options):
    return probe_transfer.ProbeJob(*arguments, **options).run()


def floor_caster():
    """Two triangles of the plane z = 0 facing up (+Z)."""
    s = FLOOR
    return caster([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], [[0, 1, 2], [0, 2, 3]])


def closed_box(low, high):
    """A cube's 12 triangles, wound to face outwards."""
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    centre = corners.mean(0)
    for t in triangles:  # outward by construction; checked, as the test depends on it
        a, b, c = corners[list(t)]
        assert np.dot(np.cross(b - a, c - a), a - centre) > 0
    return corners, triangles


def hemisphere_integrals(upper: bool, nodes=32):
    """(directions, weights) on one hemisphere: Gauss-Legendre in z over [0, 1] (or [−1, 0]) × uniform φ, exact
    for the products of two SH of order < nodes (each a polynomial in z after integrating over φ)."""
    z, w = np.polynomial.legendre.leggauss(nodes)
    z, w = 0.5 * (z + 1.0), 0.5 * w
    z = z if upper else -z
    count = 2 * nodes
    phi = 2 * np.pi * (np.arange(count) + 0.5) / count
    r = np.sqrt(1 - z * z)[:, None]
    directions = np.stack(np.broadcast_arrays(r * np.cos(phi), r * np.sin(phi), z[:, None]), axis=-1)
    return directions.reshape(-1, 3), np.repeat(w, count) * (2 * np.pi / count)


def within_noise(matrices, expected, std_error):
    """‖T − expected‖_F within 3 standard errors, for each probe; the errors small enough to mean something."""
    difference = np.linalg.norm((matrices - expected).reshape(len(matrices), -1), axis=1)
    assert np.all(std_error < 0.08), std_error  # against ‖I‖ = 4
    np.testing.assert_array_less(difference, 3.0 * std_error)


def test_a_probe_with_nothing_around_has_the_identity():
    found = bake_probes(caster(np.zeros((0, 3)), np.zeros((0, 3))), [[0, 0, 0], [4.0, -2, 7]],
                                          ORDER, 1024)
    within_noise(found.matrices[:, 0], np.eye(RECEIVED, SIZE), found.std_error)
    assert not found.inside.any()


def test_a_probe_above_an_infinite_floor_has_the_upper_hemisphere_products():
    directions, weights = hemisphere_integrals(upper=True)
    y = reference_sh(probe_transfer.received_order(ORDER), directions)
    upper = np.einsum("k,ki,kj->ij", weights, y, y[:, :SIZE])
    assert np.abs(upper[SIZE:]).max() > 0.1  # the floor's shadow puts light above the distant light's order
    found = bake_probes(floor_caster(), [[0, 0, HEIGHT], [3.0, -5.0, HEIGHT]], ORDER, 2048)
    within_noise(found.matrices[:, 0], upper, found.std_error)
    assert np.allclose(found.back_share, 0.0) and not found.inside.any()


def test_a_floor_that_reflects_adds_its_exitant_transfer_over_the_lower_hemisphere():
    """A floor whose every point sends back Σ_j E_j L_j (coloured): T = ∫₊ y_i y_j + (∫₋ y_i) E_j per channel."""
    exitant = np.random.default_rng(3).uniform(-0.3, 0.5, (4, 3, SIZE))
    exitant[:] = exitant[0]  # the same at every corner: the closed form needs it uniform
    upper_directions, upper_weights = hemisphere_integrals(upper=True)
    lower_directions, lower_weights = hemisphere_integrals(upper=False)
    y = reference_sh(probe_transfer.received_order(ORDER), upper_directions)
    upper = np.einsum("k,ki,kj->ij", upper_weights, y, y[:, :SIZE])
    lower = lower_weights @ reference_sh(probe_transfer.received_order(ORDER), lower_directions)  # ∫₋ y_i
    expected = upper[None] + np.einsum("i,cj->cij", lower, exitant[0])
    found = bake_probes(floor_caster(), [[0, 0, HEIGHT], [1.0, 2.0, 0.5]], ORDER, 2048,
                                          exitant=exitant)
    assert found.matrices.shape == (2, 3, RECEIVED, SIZE)
    within_noise(found.matrices, expected, found.std_error)


def test_a_probe_below_a_floor_gets_no_reflection_from_its_back():
    exitant = np.ones((4, 1, SIZE))
    found = bake_probes(floor_caster(), [[0, 0, -HEIGHT]], ORDER, 1024, exitant=exitant)
    directions, weights = hemisphere_integrals(upper=False)
    y = reference_sh(probe_transfer.received_order(ORDER), directions)
    within_noise(found.matrices[:, 0], np.einsum("k,ki,kj->ij", weights, y, y[:, :SIZE]), found.std_error)


def test_probes_inside_a_closed_box_are_found_and_those_outside_or_above_a_floor_are_not():
    corners, triangles = closed_box((-1, -1, 0), (1, 1, 2))
    floor = np.array([[-9, -9, 0], [9, -9, 0], [9, 9, 0], [-9, 9, 0]])
    scene = caster(np.vstack([corners, floor]), triangles + [[8, 9, 10], [8, 10, 11]])
    points = [[0, 0, 1], [0.9, -0.9, 0.1], [1.5, 0, 1], [0, 0, 2.5], [3, 3, 0.5], [5, 0, -0.5]]
    found = bake_probes(scene, points, ORDER, 256)
    np.testing.assert_array_equal(found.inside, [True, True, False, False, False, True])
    assert np.allclose(found.back_share[:2], 1.0)
    assert 0.3 < found.back_share[5] < 0.7  # below a one-sided floor, its back fills the upper half


def test_probes_sit_at_the_volume_cells_centres():
    np.testing.assert_allclose(probe_grid.probe_points((2, 1, 3)), [
        [-0.5, 0, -2 / 3], [-0.5, 0, 0], [-0.5, 0, 2 / 3], [0.5, 0, -2 / 3], [0.5, 0, 0], [0.5, 0, 2 / 3]])
    matrix = np.array([[2, 0, 0, 10], [0, 0, -1, 0], [0, 3, 0, 1], [0, 0, 0, 1]], dtype=float)  # scale, turn, move
    np.testing.assert_allclose(probe_grid.probe_positions(matrix, (2, 1, 1)), [[9, 0, 1], [11, 0, 1]])


@pytest.mark.parametrize("point, valid, expected", [
    ((0, 0, 0), None, {index: 1 / 8 for index in range(8)}),
    ((0.25, -0.5, 0.5), None, {1: 0.25, 5: 0.75}),           # x 3/4 of the way, y on probe 0, z on probe 1
    ((0.25, -0.5, 0.5), [5], {1: 1.0}),                      # its valid neighbour alone
    ((0.25, -0.5, 0.5), [1, 5], {}),                         # none valid: no light
    ((5, 5, 5), None, {7: 1.0}),                             # outside: clamped onto the last probe
    ((0, 0, 0), [0, 1, 2, 3], {4: 0.25, 5: 0.25, 6: 0.25, 7: 0.25}),  # a wall of invalid probes at x < 0
])
def test_trilinear_weights_over_the_valid_probes(point, valid, expected):
    mask = np.ones(8, dtype=bool)
    mask[valid or []] = False
    indices, weights = probe_grid.trilinear_weights(point, (2, 2, 2), mask)
    found = {}
    for index, weight in zip(indices, weights):
        if weight:
            found[int(index)] = found.get(int(index), 0.0) + weight
    assert found.keys() == expected.keys()
    np.testing.assert_allclose([found[k] for k in expected], list(expected.values()))


def test_an_axis_of_one_probe_gives_it_the_weight():
    indices, weights = probe_grid.trilinear_weights((0.7, -0.2, 0.9), (1, 1, 1), np.ones(1, dtype=bool))
    assert set(indices[weights > 0]) == {0} and weights.sum() == pytest.approx(1.0)


def incoming(matrices, indices, weights, light):
    return probe_grid.blend(probe_grid.probe_lights(matrices, light), np.asarray(indices), np.asarray(weights))


def test_incoming_light_is_the_weighted_sum_of_the_probes_products():
    light = np.arange(3 * SIZE, dtype=float).reshape(3, SIZE)
    grey = np.stack([np.eye(SIZE)[None], 3 * np.eye(SIZE)[None]])           # (2, 1, n², n²)
    np.testing.assert_allclose(incoming(grey, [0, 1], [0.5, 0.5], light), 2 * light)
    coloured = np.zeros((1, 3, SIZE, SIZE))
    coloured[0, :, 0, 0] = (1.0, 2.0, 4.0)  # each channel keeps only its own constant term, scaled
    shown = incoming(coloured, [0, 0], [0.25, 0.75], light)
    expected = np.zeros((3, SIZE))
    expected[:, 0] = light[:, 0] * (1.0, 2.0, 4.0)
    np.testing.assert_allclose(shown, expected)


def test_weights_of_many_points_are_each_points_own():
    rng = np.random.default_rng(3)
    points = rng.uniform(-1.2, 1.2, (50, 3))
    valid = rng.random(3 * 4 * 2) > 0.3
    indices, weights = probe_grid.trilinear_weights(points, (3, 4, 2), valid)
    assert indices.shape == weights.shape == (50, 8)
    for point, row_indices, row_weights in zip(points, indices, weights):
        one_indices, one_weights = probe_grid.trilinear_weights(point, (3, 4, 2), valid)
        np.testing.assert_array_equal(one_indices, row_indices)
        np.testing.assert_allclose(one_weights, row_weights)


@pytest.mark.parametrize("channels", [1, 3])
def test_shading_points_by_cell_is_each_points_transfer_against_its_blended_light(channels):
    """Against the sum written out point by point: Σ_k w_k Σ_j t_j (T_{p_k} L)_j, channel by channel."""
    rng = np.random.default_rng(channels)
    resolution = (4, 3, 3)
    matrices = rng.standard_normal((36, channels, SIZE, SIZE))
    light = rng.standard_normal((3, SIZE))
    points = rng.uniform(-1.1, 1.1, (300, 3))
    indices, weights = probe_grid.trilinear_weights(points, resolution, rng.random(36) > 0.2)
    transfer = rng.standard_normal((300, SIZE) if channels == 1 else (300, 3, SIZE))
    shown = probe_grid.shade_points(transfer, probe_grid.probe_lights(matrices, light), indices, weights)
    expected = np.zeros((300, 3))
    for n in range(300):
        for k in range(8):
            for c in range(3):
                arriving = matrices[indices[n, k], min(c, channels - 1)] @ light[c]
                row = transfer[n] if channels == 1 else transfer[n, c]
                expected[n, c] += weights[n, k] * row @ arriving
    np.testing.assert_allclose(shown, expected, rtol=1e-4, atol=1e-4 * np.abs(expected).max())


def points_in_and_around(rng, count):
    """Points over a few cells, most of them crowded into two (more than one product's piece each), some outside
    the lattice (clamped onto its faces) and some outside the cube."""
    return np.vstack([rng.uniform(-1.3, 1.3, (count // 4, 3)), rng.normal(0.3, 0.05, (count // 3, 3)),
                      rng.normal(-0.4, 0.05, (count // 3, 3)), [[0.0, 0.0, 0.0], [5.0, -5.0, 5.0]]])


@pytest.mark.parametrize("size", [16, 36])
@pytest.mark.parametrize("channels", [1, 3])
@pytest.mark.parametrize("turned", [False, True])
def test_shade_points_is_each_points_transfer_against_its_blend(size, channels, turned):
    """Against blend() point by point, dotted with the point's transfer row (channel by channel where coloured),
    the probes' lights taken through `turn` first where given; a corner of probes inside geometry, and a cell all of
    whose probes are."""
    rng = np.random.default_rng(size + channels + turned)
    resolution = (4, 3, 2)
    count = int(np.prod(resolution))
    lights = rng.standard_normal((count, 3, size))
    valid = rng.random(count) > 0.2
    valid[[0, 1, 2, 3, 6, 7, 8, 9]] = False  # every probe of the lowest cell
    points = points_in_and_around(rng, 2000)
    indices, weights = probe_grid.trilinear_weights(points, resolution, valid)
    transfer = rng.standard_normal((len(points), size) if channels == 1 else (len(points), 3, size))
    turn = np.linalg.qr(rng.standard_normal((size, size)))[0] if turned else None
    shown = probe_grid.shade_points(transfer.astype(np.float32), lights, indices, weights, turn)
    reached = lights if turn is None else lights @ turn.T
    expected = np.array([(row * probe_grid.blend(reached, point_indices, point_weights)).sum(axis=-1)
                         for row, point_indices, point_weights in zip(transfer, indices, weights)])
    assert shown.shape == (len(points), 3) and shown.dtype == np.float32
    assert np.any(np.all(weights == 0.0, axis=1))  # some point of the lowest cell, with no light
    np.testing.assert_allclose(shown, expected, rtol=0, atol=2e-5 * np.abs(expected).max())


def test_shade_points_reads_the_rows_it_is_given_of_a_larger_transfer():
    """An object partly in a volume: its points there shade from their own rows of the whole transfer, as from a
    copy of those rows."""
    rng = np.random.default_rng(9)
    resolution, size = (3, 3, 2), 36
    lights = rng.standard_normal((18, 3, size))
    transfer = rng.standard_normal((500, size)).astype(np.float32)
    rows = np.sort(rng.choice(500, 300, replace=False))
    indices, weights = probe_grid.trilinear_weights(rng.uniform(-1, 1, (300, 3)), resolution, np.ones(18, bool))
    np.testing.assert_array_equal(probe_grid.shade_points(transfer, lights, indices, weights, rows=rows),
                                  probe_grid.shade_points(transfer[rows], lights, indices, weights))


@pytest.mark.parametrize("resolution", [(16, 12, 10), (1, 6, 2)])
def test_the_probes_spanned_hold_every_probe_around_every_point(resolution):
    """Every probe trilinear_weights picks for a cluster of points, once each; on a fine lattice, a few of all."""
    rng = np.random.default_rng(resolution[0])
    for centre in ((0.0, 0.0, 0.0), (0.8, -0.7, 0.9), (-1.2, 0.3, 0.0)):
        points = (rng.normal(centre, 0.05, (400, 3))).astype(np.float32)
        indices, _ = probe_grid.trilinear_weights(points, resolution, np.ones(np.prod(resolution), dtype=bool))
        spanned = probe_grid.probes_spanned(points, resolution)
        assert set(indices.ravel().tolist()) <= set(spanned.tolist())
        assert len(spanned) == len(set(spanned.tolist()))
        if resolution[0] > 1:
            assert len(spanned) < np.prod(resolution) / 4


def test_shade_points_of_no_points():
    shown = probe_grid.shade_points(np.zeros((0, SIZE)), np.ones((8, 3, SIZE)), np.zeros((0, 8), dtype=int),
                                    np.zeros((0, 8)))
    assert shown.shape == (0, 3)


@pytest.mark.parametrize("channels", [1, 3])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_probe_lights_are_each_probes_matrix_times_the_light(channels, dtype):
    """Rectangular matrices (P, C, 36, 16) take an order-4 light to each probe's order-6 light, channel by channel
    where coloured, in the matrices' precision."""
    rng = np.random.default_rng(channels)
    matrices = rng.standard_normal((7, channels, 36, 16)).astype(dtype)
    light = rng.standard_normal((3, 16))
    found = probe_grid.probe_lights(matrices, light)
    expected = np.array([[matrices[p, min(c, channels - 1)].astype(np.float64) @ light[c] for c in range(3)]
                         for p in range(7)])
    assert found.shape == (7, 3, 36) and found.dtype == dtype and found.flags.c_contiguous
    np.testing.assert_allclose(found, expected, rtol=0, atol=(1e-5 if dtype == np.float32 else 1e-12) * 10)


def test_points_placed_in_float32_are_the_affine_map_of_them():
    rng = np.random.default_rng(4)
    matrix = np.vstack([rng.standard_normal((3, 4)), [0.0, 0.0, 0.0, 1.0]])
    points = rng.uniform(-2.0, 2.0, (100_000, 3))  # several single-thread pieces
    placed = probe_grid.placed_points(points, matrix)
    assert placed.shape == (100_000, 3) and placed.dtype == np.float32
    np.testing.assert_allclose(placed, points @ matrix[:3, :3].T + matrix[:3, 3], rtol=0, atol=5e-6)


def test_weights_of_float32_points_are_those_of_float64_points():
    """In float32 for a moving object's vertices: the same probes, the weights within float32's rounding."""
    rng = np.random.default_rng(6)
    points = points_in_and_around(rng, 3000).astype(np.float32)
    valid = rng.random(4 * 3 * 2) > 0.3
    indices, weights = probe_grid.trilinear_weights(points, (4, 3, 2), valid)
    exact_indices, exact_weights = probe_grid.trilinear_weights(points.astype(np.float64), (4, 3, 2), valid)
    assert weights.dtype == np.float32 and exact_weights.dtype == np.float64
    np.testing.assert_array_equal(indices, exact_indices)
    np.testing.assert_allclose(weights, exact_weights, rtol=0, atol=1e-5)
