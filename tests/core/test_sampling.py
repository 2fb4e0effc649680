"""Sampling: hash quality, the cosine lattice and frames, convergence and honest replicate errors."""

import numpy as np
from numpy.polynomial.legendre import leggauss
from scipy import stats

from quadrature import reference_sh

from prt_addon.core import sampling


def random_unit_vectors(count, seed):
    v = np.random.default_rng(seed).standard_normal((count, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def polar_cosine_hemisphere(u):
    """The polar map written out: u[..., 0] = sin²θ, u[..., 1] the azimuth in turns."""
    radius, azimuth = np.sqrt(u[..., 0]), 2 * np.pi * u[..., 1]
    return np.stack([radius * np.cos(azimuth), radius * np.sin(azimuth), np.sqrt(1 - u[..., 0])], axis=-1)


def shifted_cosine_directions(seed, normals, replicates, points):
    """(N, R, S, 3) world directions: a Cranley-Patterson-rotated lattice per (vertex, replicate)."""
    keys = np.arange(len(normals) * replicates)
    shifts = sampling.hash_uniform(seed, keys, 2).reshape(len(normals), replicates, 2)
    tangents, bitangents = sampling.orthonormal_basis(normals)
    frames = np.stack([tangents, bitangents, normals], axis=1)
    return sampling.cosine_lattice_directions(sampling.fibonacci_lattice(points), shifts, frames[:, None])


# --- hash ---------------------------------------------------------------------------------------------------

def test_hash_is_deterministic_and_depends_on_seed_key_and_counter():
    keys = np.arange(1000, dtype=np.int64)
    first = sampling.hash_uniform(7, keys, 4)
    np.testing.assert_array_equal(first, sampling.hash_uniform(7, keys.copy(), 4))
    assert first.shape == (1000, 4) and first.dtype == np.float64
    assert np.mean(first == sampling.hash_uniform(8, keys, 4)) < 1e-3
    assert np.mean(first[1:] == first[:-1]) < 1e-3
    assert np.mean(first[:, 1:] == first[:, :-1]) < 1e-3


def test_hash_is_bit_identical_however_keys_are_chunked_or_counted():
    keys = np.random.default_rng(0).integers(-2 ** 62, 2 ** 62, 5000)
    whole = sampling.hash_uniform(3, keys, 6)
    chunks = np.vstack([sampling.hash_uniform(3, part, 6) for part in np.array_split(keys, [1, 17, 2500, 4999])])
    np.testing.assert_array_equal(whole, chunks)
    np.testing.assert_array_equal(whole[:, :2], sampling.hash_uniform(3, keys, 2))


def test_hash_values_lie_in_the_half_open_unit_interval():
    values = sampling.hash_uniform(-5, np.array([-1, 0, 1, 2 ** 63 - 1, -2 ** 63]), 10000)
    assert values.min() >= 0.0 and values.max() < 1.0


def test_hash_is_uniform_and_pairs_are_independent():
    values = sampling.hash_uniform(11, np.arange(50000), 4)
    assert stats.kstest(values.ravel(), "uniform").pvalue > 0.01
    bins = 16
    for first, second in [(values[:, 0], values[:, 1]),      # two counters of one key
                          (values[:-1, 0], values[1:, 0])]:  # neighbouring keys
        counts, _, _ = np.histogram2d(first, second, bins=bins, range=[[0, 1], [0, 1]])
        assert stats.chisquare(counts.ravel()).pvalue > 0.01


# --- lattice and maps ---------------------------------------------------------------------------------------

def test_fibonacci_lattice_points():
    points = sampling.fibonacci_lattice(8)
    golden = (np.sqrt(5) - 1) / 2
    np.testing.assert_allclose(points[:, 0], np.arange(8) / 8, rtol=0, atol=0)
    np.testing.assert_allclose(points[:, 1], (np.arange(8) * golden) % 1, rtol=0, atol=1e-15)
    big = sampling.fibonacci_lattice(4096)
    counts, _, _ = np.histogram2d(big[:, 0], big[:, 1], bins=8, range=[[0, 1], [0, 1]])
    assert counts.min() >= 62 and counts.max() <= 66  # 64 per cell: far more even than random points


def test_cranley_patterson_shifts_every_point_modulo_one():
    points = sampling.fibonacci_lattice(13)
    shifts = np.random.default_rng(1).random((4, 3, 2))
    shifted = sampling.cranley_patterson(points, shifts)
    assert shifted.shape == (4, 3, 13, 2)
    np.testing.assert_allclose(shifted, np.mod(points + shifts[..., None, :], 1.0), rtol=0, atol=1e-15)
    assert shifted.min() >= 0.0 and shifted.max() < 1.0
    edge = sampling.cranley_patterson(np.array([[0.5, 1 - 2 ** -53]]), np.array([0.5 - 2 ** -54, 2 ** -53]))
    assert edge.min() >= 0.0 and edge.max() < 1.0  # sums that round up to 1 still wrap


def test_cosine_lattice_directions_are_the_shifted_lattice_under_the_polar_map_in_each_frame():
    normals = random_unit_vectors(6, 5)
    normals[:2] = [[0, 0, 1], [0, 0, -1]]
    shifts = np.random.default_rng(6).random((6, 3, 2))
    shifts[0, 0] = [1 - 2 ** -53, 1 - 2 ** -53]  # sums that round up to 1 wrap
    points = sampling.fibonacci_lattice(21)
    tangents, bitangents = sampling.orthonormal_basis(normals)
    frames = np.stack([tangents, bitangents, normals], axis=1)
    directions = sampling.cosine_lattice_directions(points, shifts, frames[:, None])
    assert directions.shape == (6, 3, 21, 3)
    local = polar_cosine_hemisphere(np.mod(points + shifts[..., None, :], 1.0))
    np.testing.assert_allclose(directions, local @ frames[:, None], rtol=0, atol=2e-15)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, rtol=0, atol=2e-15)
    assert np.einsum("vrkc,vc->vrk", directions, normals).min() >= 0.0
    # each coordinate of all rays is contiguous, as the ray caster reads them
    assert np.moveaxis(directions, -1, 0).flags.c_contiguous


def test_cosine_lattice_directions_in_float32_are_the_float64_ones_rounded():
    """A shared ray group's directions are float32 (what the ray caster casts), with or without a cap floor."""
    normals = random_unit_vectors(6, 8)
    shifts = np.random.default_rng(8).random((6, 3, 2))
    frames = np.stack([*sampling.orthonormal_basis(normals), normals], axis=1)[:, None]
    points = sampling.fibonacci_lattice(34)
    for floor in (None, np.linspace(-0.9, 0.0, 6)[:, None]):
        exact = sampling.cosine_lattice_directions(points, shifts, frames, floor)
        single = sampling.cosine_lattice_directions(points, shifts, frames, floor, np.float32)
        assert single.dtype == np.float32 and np.moveaxis(single, -1, 0).flags.c_contiguous
        np.testing.assert_allclose(single, exact, rtol=0, atol=2e-6)
    edge = sampling.cranley_patterson(np.array([[0.5]], np.float32), np.array([0.5 - 2 ** -26], np.float32))
    assert edge.dtype == np.float32 and edge[0, 0] == 0.0  # a float32 sum that rounds up to 1 still wraps


def test_cosine_lattice_directions_have_the_cosine_density():
    shifts = np.random.default_rng(3).random((20000, 2))
    directions = sampling.cosine_lattice_directions(np.zeros((1, 2)), shifts, np.eye(3))[:, 0]
    assert stats.kstest(directions[:, 2] ** 2, "uniform").pvalue > 0.01  # density cos θ/π: z² is uniform
    azimuth = np.arctan2(directions[:, 1], directions[:, 0])
    assert stats.kstest(azimuth, "uniform", args=(-np.pi, 2 * np.pi)).pvalue > 0.01


def test_a_caps_directions_have_its_density():
    """Above a floor s the heights z fill the cap with density ∝ (z − s)^q: x = (z − s)/(1 − s) has the
    distribution function x^(q+1), and the azimuth is uniform."""
    floor, q = -0.6, sampling.CAP_EXPONENT
    shifts = np.random.default_rng(4).random((20000, 2))
    directions = sampling.cosine_lattice_directions(np.zeros((1, 2)), shifts, np.eye(3), floor)[:, 0]
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, rtol=0, atol=1e-14)
    above = (directions[:, 2] - floor) / (1.0 - floor)
    assert above.min() >= 0.0 and stats.kstest(above ** (q + 1.0), "uniform").pvalue > 0.01
    assert stats.kstest(above ** 2, "uniform").pvalue < 1e-6  # teeth: not the lowered cosine lobe (q = 1)
    azimuth = np.arctan2(directions[:, 1], directions[:, 0])
    assert stats.kstest(azimuth, "uniform", args=(-np.pi, 2 * np.pi)).pvalue > 0.01


def test_cap_weights_turn_a_caps_lattice_into_each_covered_normals_cosine_lobe():
    """A cap about n̄ with floor s = −√(1 − c²) covers the hemisphere of every normal n with n̄·n ≥ c: the mean over
    its lattice of (n·ω)₊·cap_weights·Y_k(ω) is n's clamped cosine transfer (Â_l/π)·Y_k(n), in float64 and float32."""
    order, closest = 4, np.cos(np.radians(50.0))
    floor = -np.sqrt(1.0 - closest ** 2)
    axis = np.array([0.0, 0.0, 1.0])
    tilts = np.radians([0.0, 20.0, 35.0, 50.0])
    normals = np.stack([np.sin(tilts) * np.cos(tilts * 7), np.sin(tilts) * np.sin(tilts * 7), np.cos(tilts)], axis=1)
    a_hat = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0])
    truth = reference_sh(order, normals) * np.repeat(a_hat / np.pi, 2 * np.arange(order) + 1)
    points, shifts = sampling.fibonacci_lattice(4096), np.random.default_rng(6).random((4, 2))
    for dtype, tolerance in ((np.float64, 3e-4), (np.float32, 5e-4)):
        directions = sampling.cosine_lattice_directions(points, shifts, np.eye(3), floor, dtype).reshape(-1, 3)
        weights = sampling.cap_weights(directions @ axis.astype(dtype) - dtype(floor), dtype(floor))
        assert weights.dtype == dtype
        cosines = np.maximum(directions.astype(np.float64) @ normals.T, 0.0) * weights[:, None]
        estimate = (cosines.T @ reference_sh(order, directions.astype(np.float64))) / len(directions)
        np.testing.assert_allclose(estimate, truth, rtol=0, atol=tolerance)
    # teeth: the lowered cosine lobe's weights (q = 1) on these directions are off by 100 times the tolerance
    directions = directions.astype(np.float64)
    wrong = np.maximum(directions @ normals.T, 0.0) * ((1.0 - floor) ** 2 / (directions @ axis - floor))[:, None]
    assert np.abs(wrong.T @ reference_sh(order, directions) / len(directions) - truth).max() > 0.02


def test_cosine_lattice_estimates_clamped_cosine_transfer_faster_than_monte_carlo():
    """mean Y_k(ω_i) over cosine-distributed ω_i estimates (1/π)∫ max(n·ω, 0)·Y_k = (Â_l/π)·Y_k(n)."""
    order, vertices = 4, 100
    normals = random_unit_vectors(vertices, 5)
    a_hat = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0])
    truth = reference_sh(order, normals) * np.repeat(a_hat / np.pi, 2 * np.arange(order) + 1)
    sizes = np.array([64, 256, 1024, 4096])
    errors = []
    for points in sizes:
        directions = shifted_cosine_directions(9, normals, 1, points)[:, 0]
        errors.append(np.sqrt(np.mean((reference_sh(order, directions).mean(1) - truth) ** 2)))
    slope = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert slope < -0.8  # Monte Carlo would give -0.5
    assert errors[-1] < 2e-4  # Monte Carlo's RMS error at 4096 points is about 4e-3


# --- frames ---------------------------------------------------------------------------------------------------

def test_orthonormal_basis_is_orthonormal_and_right_handed_everywhere():
    tiny = 1e-9
    special = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, -0.0], [0, 1.0, -0.0], [1.0, 0, 0], [0, 1.0, 0],
                        [tiny, 0, -1], [0, tiny, -1], [tiny, -tiny, -1], [-1e-300, 0, -1], [tiny, tiny, 1]])
    special /= np.linalg.norm(special, axis=1, keepdims=True)
    near_minus_z = np.array([[np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), -np.cos(t)]
                             for t in np.geomspace(1e-12, 1e-2, 20) for p in (0.3, 2.0, 4.0)])
    normals = np.vstack([special, near_minus_z, random_unit_vectors(2000, 6)])
    tangents, bitangents = sampling.orthonormal_basis(normals)
    frames = np.stack([tangents, bitangents, normals], axis=1)
    gram = frames @ frames.transpose(0, 2, 1)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(3), gram.shape), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.cross(tangents, bitangents), normals, rtol=0, atol=1e-12)


# --- estimators -----------------------------------------------------------------------------------------------

def cap_transfer(order, normals, axes, cos_half_angles):
    """(1/π)∫_cap (n·ω)·Y_k(ω) dω for caps that lie inside each normal's hemisphere: the integrand is a
    polynomial of degree ≤ order in ω, so Gauss-Legendre in cos (about the cap axis) × equal steps in
    azimuth is exact."""
    nodes, weights = leggauss(order + 2)
    azimuths = 2 * np.pi * np.arange(2 * order + 2) / (2 * order + 2)
    c = cos_half_angles[:, None]
    heights = c + (nodes + 1) / 2 * (1 - c)                       # (N, G)
    height_weights = weights * (1 - c) / 2
    across_1, across_2 = sampling.orthonormal_basis(axes)
    ring = (np.cos(azimuths)[:, None] * across_1[:, None, :]
            + np.sin(azimuths)[:, None] * across_2[:, None, :])   # (N, A, 3)
    directions = (np.sqrt(1 - heights ** 2)[:, :, None, None] * ring[:, None]
                  + heights[:, :, None, None] * axes[:, None, None, :])
    integrand = np.einsum("ngac,nc->nga", directions, normals)[..., None] * reference_sh(order, directions)
    return np.einsum("ngak,ng->nk", integrand, height_weights) * (2 * np.pi / len(azimuths)) / np.pi


def test_replicate_standard_errors_are_honest_for_a_visibility_integrand():
    """400 vertices, R = 8 replicates of 64 shifted lattice points each, estimating the transfer
    (1/π)∫ V·max(n·ω, 0)·Y_k with V = [ω·a > c] a cap of sky seen through an opening. With honest errors the
    z-scores (error / replicate standard error) follow Student's t with 7 degrees of freedom: RMS sqrt(7/5) ≈ 1.18;
    error bars half the true size would give 2.4, twice the true size 0.59. (t's heavy tails make the RMS of
    a single coefficient over 400 vertices too noisy to bound; the 8 coefficients are pooled.)

    Y_0 is left out of the per-coefficient check: V·Y_0 is a pure count, and a lattice often puts the same
    number of points in the cap for all 8 shifts, a zero spread with a nonzero error. The vector norm the
    bake reports includes it."""
    order, vertices, replicates, points = 3, 400, 8, 64
    rng = np.random.default_rng(8)
    normals = random_unit_vectors(vertices, 9)
    half_angles = rng.uniform(0.3, 0.8, vertices)
    tilts = rng.uniform(0, 1, vertices) * (np.pi / 2 - half_angles)  # keeps each cap above the horizon
    swing = rng.uniform(0, 2 * np.pi, vertices)[:, None]
    tangents, bitangents = sampling.orthonormal_basis(normals)
    axes = (np.cos(tilts)[:, None] * normals
            + np.sin(tilts)[:, None] * (np.cos(swing) * tangents + np.sin(swing) * bitangents))
    truth = cap_transfer(order, normals, axes, np.cos(half_angles))

    directions = shifted_cosine_directions(21, normals, replicates, points)
    visible = np.einsum("nrsc,nc->nrs", directions, axes) > np.cos(half_angles)[:, None, None]
    per_replicate = (visible[..., None] * reference_sh(order, directions)).mean(2)   # (N, R, K)
    estimate = per_replicate.mean(1)
    standard_error = per_replicate.std(1, ddof=1) / np.sqrt(replicates)

    z = (estimate - truth)[:, 1:] / standard_error[:, 1:]
    assert 0.7 < np.sqrt(np.mean(z ** 2)) < 1.4
    vector_z = np.linalg.norm(estimate - truth, axis=1) / np.linalg.norm(standard_error, axis=1)
    assert 0.7 < np.sqrt(np.mean(vector_z ** 2)) < 1.4


def test_unit_or_zero_scales_to_unit_length_and_leaves_short_vectors_zero():
    vectors = np.array([[3.0, 0.0, 4.0], [0.0, 0.0, 0.0], [1e-9, 0.0, 0.0], [0.0, -2.0, 0.0]])
    np.testing.assert_array_equal(sampling.unit_or_zero(vectors), [[0.6, 0.0, 0.8], [0, 0, 0], [1, 0, 0], [0, -1, 0]])
    np.testing.assert_array_equal(sampling.unit_or_zero(vectors, shortest=1e-6)[2], [0.0, 0.0, 0.0])
