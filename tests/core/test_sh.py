import math

import numpy as np
import pytest

from quadrature import random_directions, reference_sh, sphere_quadrature

from prt_addon.core import sh

POLES = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])


def test_index_and_coefficient_bands_follow_band_then_degree_order():
    order = sh.MAX_ORDER
    pairs = [(l, m) for l in range(order) for m in range(-l, l + 1)]  # k = 0, 1, 2, ...: (0, 0), (1, -1), ...
    assert [sh.index(l, m) for l, m in pairs] == list(range(order * order))
    assert sh.coefficient_bands(order).tolist() == [l for l, _ in pairs]
    assert sh.index(7, -7) == 49 and sh.index(7, 7) == 63  # band 7 is k = 7² … 8² - 1


def test_closed_form_bands_0_to_2():
    # Derived from K_lm P_l^m: Y00 = 1/(2√π), Y1m = √(3/4π)(-y, z, -x),
    # Y2,-2 = c2 xy, Y2,-1 = -c2 yz, Y2,1 = -c2 xz with c2 = (1/2)√(15/π),
    # Y20 = (1/4)√(5/π)(3z²-1), Y22 = (1/4)√(15/π)(x²-y²).
    c00 = 0.5 / math.sqrt(math.pi)
    c1 = math.sqrt(3 / (4 * math.pi))
    c2 = 0.5 * math.sqrt(15 / math.pi)
    c20 = 0.25 * math.sqrt(5 / math.pi)
    c22 = 0.25 * math.sqrt(15 / math.pi)
    quoted = {c00: 0.282095, c1: 0.488603, c2: 1.092548, c20: 0.315392, c22: 0.546274}
    for derived, rounded in quoted.items():
        assert abs(derived - rounded) < 5e-7
    d = np.vstack([random_directions(500), POLES, np.eye(3)])
    x, y, z = d.T
    expected = np.stack([
        np.full_like(x, c00),
        -c1 * y, c1 * z, -c1 * x,
        c2 * x * y, -c2 * y * z, c20 * (3 * z * z - 1),
        -c2 * x * z, c22 * (x * x - y * y),
    ], axis=-1)
    assert np.abs(sh.evaluate(3, d) - expected).max() < 1e-14


@pytest.mark.parametrize("order", range(1, 31))
def test_orthonormal_under_exact_quadrature(order):
    directions, weights = sphere_quadrature(order)
    y = sh.evaluate(order, directions)
    gram = y.T @ (weights[:, None] * y)
    assert np.abs(gram - np.eye(order * order)).max() < 1e-10


def test_matches_scipy_on_random_directions_and_poles_up_to_order_30():
    d = np.vstack([random_directions(300, seed=1), POLES])
    reference = reference_sh(30, d)
    for order in range(1, 31):
        values = sh.evaluate(order, d)
        assert np.abs(values - reference[:, :order * order]).max() < 1e-12, order
    assert np.abs(values[-2:] - reference[-2:]).max() < 1e-12


def test_order_64_finite_at_and_near_poles_and_exact_on_them():
    order = sh.MAX_ORDER
    eps = np.array([1e-12, 1e-100, 1e-300])
    near = np.concatenate([
        np.stack([np.sin(eps), np.zeros(3), np.cos(eps)], axis=-1),
        np.stack([np.zeros(3), np.sin(eps), -np.cos(eps)], axis=-1),
    ])
    values = sh.evaluate(order, np.vstack([POLES, near]))
    assert np.isfinite(values).all()
    # On ±Z only m = 0 survives: Y_l0(±Z) = (±1)^l sqrt((2l+1)/4π).
    bands = np.arange(order)
    expected = np.zeros((2, order * order))
    expected[0, bands * (bands + 1)] = np.sqrt((2 * bands + 1) / (4 * np.pi))
    expected[1, bands * (bands + 1)] = (-1.0) ** bands * np.sqrt((2 * bands + 1) / (4 * np.pi))
    assert np.abs(values[:2] - expected).max() < 1e-12
    assert np.abs(values[2:5] - expected[0]).max() < 1e-9  # continuous into the pole
    assert np.abs(values[5:] - expected[1]).max() < 1e-9


def test_order_64_matches_scipy():
    d = random_directions(100, seed=2)
    assert np.abs(sh.evaluate(64, d) - reference_sh(64, d)).max() < 1e-11


def test_leading_shapes_are_kept():
    d = random_directions(24, seed=3)
    flat = sh.evaluate(5, d)
    assert sh.evaluate(5, d.reshape(2, 3, 4, 3)).shape == (2, 3, 4, 25)
    assert np.array_equal(sh.evaluate(5, d.reshape(2, 3, 4, 3)).reshape(24, 25), flat)
    assert np.array_equal(sh.evaluate(5, d[7]), flat[7])
    assert sh.evaluate(5, np.zeros((0, 3))).shape == (0, 25)


def test_evaluation_in_blocks_matches_small_batches():
    d = random_directions(300_000, seed=4)  # many internal cache-sized blocks at order 4
    pieces = np.array_split(d, 997)  # each piece is a single block, boundaries misaligned
    assert np.array_equal(sh.evaluate(4, d), np.vstack([sh.evaluate(4, p) for p in pieces]))


@pytest.mark.parametrize("order", [1, 4, 10])
def test_components_are_the_transpose_of_evaluate_exactly(order):
    d = random_directions(5000, seed=5)
    d[:2] = [[0, 0, 1.0], [0, 0, -1.0]]
    components = sh.evaluate_components(order, d)
    assert components.shape == (order * order, 5000) and components.flags.c_contiguous
    assert np.array_equal(components.T, sh.evaluate(order, d))
    strided = np.moveaxis(np.ascontiguousarray(d.T).reshape(3, 50, 100), 0, -1)  # a bake round's layout
    assert np.array_equal(sh.evaluate_components(order, strided), components)


@pytest.mark.parametrize("order, tolerance", [(4, 1e-6), (16, 2e-5)])
def test_components_in_float32_match_float64_to_float32_rounding(order, tolerance):
    """A shared ray group evaluates its rays' SH in float32 (core.ray_groups.weight_dtype): within about 1e-6 of float64
    at the default order 4, up to the bake's highest order 16, poles included."""
    d = np.vstack([POLES, random_directions(5000, seed=7)])
    components = sh.evaluate_components(order, d.astype(np.float32), np.float32)
    assert components.dtype == np.float32 and components.shape == (order * order, 5002)
    np.testing.assert_allclose(components, sh.evaluate_components(order, d), rtol=0, atol=tolerance)


def test_rejects_order_beyond_max():
    with pytest.raises(ValueError):
        sh.evaluate(sh.MAX_ORDER + 1, POLES)
    with pytest.raises(ValueError):
        sh.evaluate_components(sh.MAX_ORDER + 1, POLES)
