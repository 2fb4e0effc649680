"""What float32 storage (mesh attributes hold float32) adds to the error, and rotation properties on random input.

Measured here and documented in the README: float32 storage of the basis keeps orthonormality to ~1e-7
(orders 1-30) and a stored transfer changes a shaded value by at most n²·2⁻²⁴ of Σ|L_k T_k|.
"""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quadrature import sphere_quadrature
from rotations import quaternion_from_axis_angle

from prt_addon.core import lobes, rotation, sh

FLOAT32_UNIT = 2.0 ** -24


@pytest.mark.parametrize("order", [1, 2, 4, 8, 16, 30])
def test_float32_basis_stays_orthonormal(order):
    directions, weights = sphere_quadrature(order + 1)
    basis = sh.evaluate(order, directions).astype(np.float32).astype(np.float64)
    gram = (basis * weights[:, None]).T @ basis
    # Rounding each value to float32 perturbs each Gram entry by at most 2·2⁻²⁴·Σ w|Y_i Y_j| ≤ 2·2⁻²⁴
    # (Cauchy-Schwarz with orthonormality); measured here: 1.04e-7 against the bound 1.19e-7.
    assert np.abs(gram - np.eye(order * order)).max() <= 2 * FLOAT32_UNIT * 1.01


@pytest.mark.parametrize("order", [2, 4, 10, 20, 30])
def test_float32_rotation_blocks_stay_orthogonal(order):
    matrix = rotation.quaternion_to_matrix([0.3, -0.5, 0.7, 0.2])
    for l, block in enumerate(rotation.band_matrices(order, matrix)):
        block32 = block.astype(np.float32).astype(np.float64)
        # Each entry carries a relative rounding error ≤ 2⁻²⁴; a row has 2l+1 entries.
        assert np.abs(block32 @ block32.T - np.eye(2 * l + 1)).max() < 2 * FLOAT32_UNIT * (2 * l + 1)


def test_float32_transfer_changes_a_shaded_value_by_at_most_its_rounding():
    rng = np.random.default_rng(4)
    normals = rng.normal(size=(2000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    transfer = lobes.cosine_transfer(6, normals) * rng.uniform(0.0, 1.0, (2000, 1))
    light = rng.normal(size=36)
    exact = transfer @ light
    stored = transfer.astype(np.float32).astype(np.float64) @ light
    bound = FLOAT32_UNIT * np.abs(transfer * light).sum(1)
    assert np.all(np.abs(stored - exact) <= bound)
    assert np.abs(stored - exact).max() > 0  # float32 storage does round


quaternions = st.tuples(*[st.floats(-1.0, 1.0, allow_nan=False)] * 4).filter(
    lambda q: np.linalg.norm(q) > 1e-3)


@settings(max_examples=60, deadline=None)
@given(quaternions, quaternions)
def test_random_rotations_compose_and_stay_orthogonal(a, b):
    ra, rb = rotation.quaternion_to_matrix(a), rotation.quaternion_to_matrix(b)
    blocks_a, blocks_b = rotation.band_matrices(8, ra), rotation.band_matrices(8, rb)
    for l, (block_a, block_b, block_ab) in enumerate(zip(blocks_a, blocks_b, rotation.band_matrices(8, ra @ rb))):
        assert np.abs(block_a @ block_a.T - np.eye(2 * l + 1)).max() < 1e-12
        assert np.abs(block_a @ block_b - block_ab).max() < 1e-12


@settings(max_examples=60, deadline=None)
@given(quaternions, st.tuples(*[st.floats(-1.0, 1.0, allow_nan=False)] * 3).filter(lambda d: np.linalg.norm(d) > 1e-3))
def test_rotating_a_lobe_moves_it_to_the_rotated_direction(q, direction):
    direction = np.array(direction) / np.linalg.norm(direction)
    matrix = rotation.quaternion_to_matrix(q)
    zonal = lobes.clamped_cosine_zonal(6)
    rotated = rotation.rotate(rotation.zonal_to_sh(zonal, direction), matrix)
    np.testing.assert_allclose(rotated, rotation.zonal_to_sh(zonal, matrix @ direction), atol=1e-12)


@pytest.mark.parametrize("angle", [np.pi, np.pi - 1e-12, 1e-12, 0.0])
@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)])
def test_half_turns_gimbal_poles_and_near_identity_are_finite_and_orthogonal(angle, axis):
    blocks = rotation.band_matrices(12, quaternion_from_axis_angle(np.array(axis, float), angle))
    for l, block in enumerate(blocks):
        assert np.isfinite(block).all()
        assert np.abs(block @ block.T - np.eye(2 * l + 1)).max() < 1e-12
