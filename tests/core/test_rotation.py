import math

import numpy as np
import pytest

from quadrature import sphere_quadrature
from rotations import matrix_from_euler_zyz, quaternion_from_axis_angle, rotation_matrix

from prt_addon.core import rotation, sh

X_AXIS, Y_AXIS, Z_AXIS = np.eye(3)


def project(order, function):
    """SH coefficients of a function of (N, 3) directions, exact if f·Y has degree < 2·order."""
    directions, weights = sphere_quadrature(order)
    return (weights * function(directions)) @ sh.evaluate(order, directions)


def projected_rotation_matrix(order, matrix):
    """Reference by quadrature: M[k, k'] = ∫ Y_k(ω) Y_k'(Rᵀω) dω (rows ωᵀR are Rᵀω)."""
    directions, weights = sphere_quadrature(order)
    basis = sh.evaluate(order, directions)
    return (weights[:, None] * basis).T @ sh.evaluate(order, directions @ matrix)


def random_rotations(count, seed=0):
    rng = np.random.default_rng(seed)
    return [rotation.quaternion_to_matrix(q) for q in rng.normal(size=(count, 4))]


def axis_angle_matrix(axis, angle):
    return rotation.quaternion_to_matrix(quaternion_from_axis_angle(axis, angle))


def max_block_difference(blocks_a, blocks_b):
    return max(np.abs(a - b).max() for a, b in zip(blocks_a, blocks_b, strict=True))


def band_limited_function(directions):
    """A polynomial of degree 9 in x, y, z, so exactly order 10; not built from SH."""
    a = np.array([0.3, -0.8, 0.5])
    b = np.array([-0.6, 0.1, 0.7])
    x, y, z = directions.T
    return (directions @ a) ** 9 + 0.5 * (directions @ b) ** 4 * x + 0.3 * x * y * z + 0.2


def test_quaternion_to_matrix_matches_rodrigues_and_normalises():
    axis = np.array([1.0, -2.0, 0.5]) / math.sqrt(5.25)
    angle = 2.1
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rodrigues = math.cos(angle) * np.eye(3) + math.sin(angle) * cross
    rodrigues += (1 - math.cos(angle)) * np.outer(axis, axis)
    q = quaternion_from_axis_angle(3 * axis, angle)
    assert np.abs(rotation.quaternion_to_matrix(q) - rodrigues).max() < 1e-15
    assert np.abs(rotation.quaternion_to_matrix(3.7 * q) - rodrigues).max() < 1e-15


def test_band_blocks_are_orthogonal_up_to_order_20():
    for matrix in random_rotations(5):
        for l, block in enumerate(rotation.band_matrices(20, matrix)):
            assert block.shape == (2 * l + 1, 2 * l + 1)
            assert np.abs(block @ block.T - np.eye(2 * l + 1)).max() < 1e-12


def test_blocks_of_a_product_are_products_of_blocks():
    for first, second in zip(random_rotations(4, seed=2), random_rotations(4, seed=3)):
        product_blocks = rotation.band_matrices(20, first @ second)
        pairs = zip(rotation.band_matrices(20, first), rotation.band_matrices(20, second))
        blocks = [a @ b for a, b in pairs]
        assert max_block_difference(product_blocks, blocks) < 1e-12


SPECIAL_ROTATIONS = {
    "random": random_rotations(1, seed=4)[0],
    "x 0": axis_angle_matrix(X_AXIS, 0.0),
    "x pi": axis_angle_matrix(X_AXIS, math.pi),
    "x 1e-12": axis_angle_matrix(X_AXIS, 1e-12),
    "y 0": matrix_from_euler_zyz(0.0, 0.0, 0.0),
    "y pi": matrix_from_euler_zyz(0.0, math.pi, 0.0),
    "y 1e-12": matrix_from_euler_zyz(0.0, 1e-12, 0.0),
    # Where Euler-angle methods are singular: alpha and gamma merge.
    "zyz beta 0": matrix_from_euler_zyz(0.3, 0.0, 1.1),
    "zyz beta pi": matrix_from_euler_zyz(0.3, math.pi, 1.1),
    "zyz beta 1e-12": matrix_from_euler_zyz(0.3, 1e-12, 1.1),
    "zyz beta pi-1e-12": matrix_from_euler_zyz(0.3, math.pi - 1e-12, 1.1),
}


@pytest.mark.parametrize("name", SPECIAL_ROTATIONS)
def test_matches_projection_of_rotated_basis(name):
    matrix = SPECIAL_ROTATIONS[name]
    dense = rotation_matrix(20, matrix)
    assert np.isfinite(dense).all()
    assert np.abs(dense - projected_rotation_matrix(20, matrix)).max() < 1e-12


def test_tiny_angle_is_resolved_not_rounded_to_identity():
    matrix = SPECIAL_ROTATIONS["x 1e-12"]
    change = rotation_matrix(20, matrix) - np.eye(400)
    # Differencing two quadratures on the same nodes cancels their common rounding.
    reference = projected_rotation_matrix(20, matrix) - projected_rotation_matrix(20, np.eye(3))
    assert np.abs(change).max() > 1e-11  # the rotation is visible at this order ...
    assert np.abs(change - reference).max() < 1e-14  # ... and resolved to ~1e-3 relative


def test_half_turns_about_axes_are_exact_sign_flips():
    # f(-x, y, -z) and f(x, -y, -z) map each Y_lm to ±Y_lm (θ -> π-θ and φ -> π-φ or -φ).
    l, m = np.array([(l, m) for l in range(20) for m in range(-l, l + 1)]).T  # coefficient k's band and degree
    about_y = np.where(m >= 0, 1.0, -1.0) * (-1.0) ** l
    about_x = np.where(m >= 0, 1.0, -1.0) * (-1.0) ** (l + np.abs(m))
    half_turns = [(np.diag([-1.0, 1.0, -1.0]), about_y), (np.diag([1.0, -1.0, -1.0]), about_x)]
    for half_turn, signs in half_turns:
        assert np.abs(rotation_matrix(20, half_turn) - np.diag(signs)).max() < 1e-14


def test_rotation_about_z_turns_each_degree_by_m_alpha():
    alpha = 0.7
    blocks = rotation.band_matrices(12, matrix_from_euler_zyz(alpha, 0.0, 0.0))
    for l, block in enumerate(blocks):
        expected = np.zeros_like(block)
        expected[l, l] = 1.0
        for m in range(1, l + 1):
            c, s = math.cos(m * alpha), math.sin(m * alpha)
            # a cos mφ + b sin mφ, evaluated at φ - α.
            expected[l + m, l + m], expected[l + m, l - m] = c, -s
            expected[l - m, l + m], expected[l - m, l - m] = s, c
        assert np.abs(block - expected).max() < 1e-14


def test_rotating_coefficients_equals_projecting_the_rotated_function():
    order = 10
    coeffs = project(order, band_limited_function)
    probe = np.random.default_rng(5).normal(size=(50, 3))
    probe /= np.linalg.norm(probe, axis=1, keepdims=True)
    assert np.abs(sh.evaluate(order, probe) @ coeffs - band_limited_function(probe)).max() < 1e-12
    for matrix in random_rotations(3, seed=6) + [SPECIAL_ROTATIONS["zyz beta pi"]]:
        rotated = project(order, lambda d: band_limited_function(d @ matrix))
        assert np.abs(rotation.rotate(coeffs, matrix) - rotated).max() < 1e-10


def test_rotate_keeps_leading_dims_and_accepts_quaternions():
    rng = np.random.default_rng(7)
    rgb = rng.normal(size=(2, 3, 49))
    q = rng.normal(size=4)
    matrix = rotation.quaternion_to_matrix(q)
    rotated = rotation.rotate(rgb, matrix)
    dense = rotation_matrix(7, matrix)
    assert rotated.shape == (2, 3, 49)
    assert np.abs(rotated - rgb @ dense.T).max() < 1e-14
    assert np.abs(rotation.rotate(rgb, q) - rotated).max() < 1e-15


def test_rotate_rejects_bad_shapes_and_non_rotations():
    with pytest.raises(ValueError):
        rotation.rotate(np.zeros(10), np.eye(3))
    for not_a_rotation in [1.01 * np.eye(3), np.diag([1.0, 1.0, -1.0]), np.eye(2)]:
        with pytest.raises(ValueError):
            rotation.band_matrices(3, not_a_rotation)


ZONAL = np.array([0.9, -0.4, 0.25, 0.1, -0.05, 0.02])


def test_rotated_lobe_points_at_rotated_direction():
    direction = np.array([0.48, -0.6, 0.64])
    for matrix in random_rotations(3, seed=8):
        rotated = rotation.rotate(rotation.zonal_to_sh(ZONAL, direction), matrix)
        assert np.abs(rotated - rotation.zonal_to_sh(ZONAL, matrix @ direction)).max() < 1e-14


@pytest.mark.parametrize("direction", [[0.48, -0.6, 0.64], [0, 0, 1], [0, 0, -1], [1, 0, 0]])
def test_zonal_to_sh_equals_rotating_the_lobe_from_z(direction):
    direction = np.array(direction)
    on_z = np.zeros(36)
    on_z[[sh.index(l, 0) for l in range(6)]] = ZONAL
    axis = np.cross(Z_AXIS, direction)
    angle = math.atan2(np.linalg.norm(axis), direction[2])
    axis = axis if np.linalg.norm(axis) > 0 else X_AXIS
    expected = rotation.rotate(on_z, axis_angle_matrix(axis, angle))
    assert np.abs(rotation.zonal_to_sh(ZONAL, direction) - expected).max() < 1e-14


def test_zonal_to_sh_matches_quadrature():
    def profile(t):
        return t**5 - 0.4 * t**2 + 0.3 * t + 0.1

    zonal = project(6, lambda d: profile(d[:, 2]))[[sh.index(l, 0) for l in range(6)]]
    directions = np.random.default_rng(9).normal(size=(4, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    expected = np.stack([project(6, lambda d, axis=axis: profile(d @ axis)) for axis in directions])
    assert np.abs(rotation.zonal_to_sh(zonal, directions) - expected).max() < 1e-12



def test_the_full_matrix_is_the_dense_rotation():
    matrix = rotation.quaternion_to_matrix(np.random.default_rng(4).normal(size=4))
    assert np.abs(rotation.sh_matrix(5, matrix) - rotation_matrix(5, matrix)).max() < 1e-14
