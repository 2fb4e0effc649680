"""The probes between vertices (core.interpolation): where they fall, and what they measure, against closed forms."""

import numpy as np
import pytest

from prt_addon.core import interpolation


def test_probes_fall_inside_triangles_in_proportion_to_area():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [5, 0, 0], [8, 0, 0], [5, 2, 0], [9, 9, 9]], float)
    normals = np.tile([0.0, 0.0, 1.0], (7, 1))
    triangles = np.array([[0, 1, 2], [3, 4, 5], [6, 6, 6]])  # areas 1, 3 and none
    probes = interpolation.face_probes(triangles, positions, normals, 4000, seed=3)
    first = (probes.corners == triangles[0]).all(axis=1)
    second = (probes.corners == triangles[1]).all(axis=1)
    assert (first | second).all()  # none on the triangle without area
    assert abs(first.sum() - 1000) < 100  # binomial, p = 1/4: σ ≈ 27
    assert (probes.weights >= 0).all() and np.allclose(probes.weights.sum(axis=1), 1.0)
    rebuilt = np.einsum("sk,skd->sd", probes.weights, positions[probes.corners])
    assert np.allclose(rebuilt, probes.positions) and np.allclose(probes.normals, [0, 0, 1])


def test_interpolation_errors_vanish_for_linear_transfer_and_take_noise_out():
    rng = np.random.default_rng(1)
    transfer = rng.normal(size=(300, 4))
    corners = rng.integers(0, 300, size=(500, 3))
    weights = rng.dirichlet(np.ones(3), size=500)
    probes = interpolation.Probes(np.zeros((500, 3)), np.zeros((500, 3)), corners, weights)
    linear = np.einsum("sk,skj->sj", weights, transfer[corners])
    exact = interpolation.interpolation_errors(probes, linear, np.zeros(500), transfer, np.zeros(300), 1.0)
    assert np.allclose(exact, 0.0)
    noise = 0.05
    noisy = linear + 0.1 + rng.normal(scale=noise / 2, size=linear.shape)  # 4 coefficients: noise of norm 0.05
    squared = interpolation.interpolation_errors(probes, noisy, np.full(500, noise), transfer, np.zeros(300), 1.0)
    assert interpolation.summarise(squared)[0] == pytest.approx(0.2, rel=0.05)  # the bias's norm, noise out
