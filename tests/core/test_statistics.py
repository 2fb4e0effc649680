"""Validation's statistics against closed forms: the 99th percentile of the per-vertex error with Cycles' noise
taken out, the worst vertices and the worst object, and how much noise the percentile keeps (core.statistics)."""

import numpy as np
import pytest
from scipy import integrate, optimize, stats

from prt_addon.core.statistics import compare, denoised_errors, rms, worst_object, worst_vertices


def known_errors_case(errors, noise, scale=2.0):
    """PRT and two Cycles passes whose per-vertex error, Cycles' noise taken out and relative to the RMS of
    ‖Cycles‖, is exactly `errors`, whatever the noise at each vertex (relative too).

    Cycles' mean is (0, 0, scale) everywhere, so its RMS is `scale`. The passes are the mean ± scale·a in red: the
    variance of their mean is (2 (scale·a)² ÷ 1) ÷ 2 = (scale·a)². PRT is off in green by scale·sqrt(e² + a²), so
    d² − σ² = (scale·e)²."""
    errors, noise = np.asarray(errors, dtype=float), np.asarray(noise, dtype=float)
    cycles = np.zeros((len(errors), 3))
    cycles[:, 2] = scale
    spread = np.zeros_like(cycles)
    spread[:, 0] = scale * noise
    prt = cycles.copy()
    prt[:, 1] += scale * np.sqrt(errors ** 2 + noise ** 2)
    return prt, np.stack([cycles + spread, cycles - spread])


def test_p99_and_worst_vertices_of_known_errors():
    """101 vertices whose errors are 0, 0.01, ..., 1.00 in a shuffled order: numpy's linear percentile puts the
    99th at rank 0.99 × 100 = 99 exactly, so p99 = 0.99; the five worst are the vertices holding 1.00 ... 0.96.
    Cycles' noise, up to three times the error at a vertex, is taken out exactly."""
    rng = np.random.default_rng(1)
    order = rng.permutation(101)
    errors = order / 100.0                      # vertex v holds error order[v] / 100
    prt, passes = known_errors_case(errors, rng.uniform(0.0, 3.0, 101))
    comparison = compare("Known", prt, passes)
    assert comparison.p99 == pytest.approx(0.99, abs=1e-12)
    expected = [(int(np.flatnonzero(order == rank)[0]), rank / 100.0) for rank in (100, 99, 98, 97, 96)]
    assert [index for index, _ in comparison.worst] == [index for index, _ in expected]
    np.testing.assert_allclose([error for _, error in comparison.worst], [e for _, e in expected], atol=1e-12)
    # The per-vertex errors are the RMS's quadrature vertex by vertex: none clamps here, so their RMS is it.
    assert comparison.error == pytest.approx(rms(errors), rel=1e-12)
    np.testing.assert_allclose(comparison.errors, errors, atol=1e-12)
    assert comparison.measured_p99 > comparison.p99 and comparison.max_difference > 1.0
    assert "p99 99.0 %" in comparison.text() and comparison.as_dict()["rel_p99_error"] == comparison.p99


def test_denoised_error_clamps_where_the_noise_exceeds_the_difference():
    np.testing.assert_allclose(denoised_errors(np.array([1.0, 2.0, 3.0]), np.array([4.0, 1.0, 9.0])),
                               [0.0, np.sqrt(3.0), 0.0])


def test_worst_vertices_rank_ties_by_index_and_stop_at_the_vertex_count():
    assert worst_vertices(np.array([0.1, 0.3, 0.3, 0.2])) == [(1, 0.3), (2, 0.3), (3, 0.2), (0, 0.1)]
    assert worst_vertices(np.array([0.5, 0.7, 0.1, 0.9, 0.2, 0.8, 0.6]), k=3) == [(3, 0.9), (5, 0.8), (1, 0.7)]


def test_the_worst_object_has_the_largest_p99_even_with_a_smaller_rms():
    """Even: 5 % everywhere (RMS 5 %, p99 5 %). Seam: 1 % everywhere but 20 of 1000 vertices at 30 % (RMS
    sqrt(0.98 × 0.01² + 0.02 × 0.3²) = 4.36 %; the 99th percentile, at rank 989.01, falls among the 30 %)."""
    even = compare("Even", *known_errors_case(np.full(1000, 0.05), np.zeros(1000)))
    seam_errors = np.full(1000, 0.01)
    seam_errors[[3, 97, 250, 500, 777] + list(range(900, 915))] = 0.3
    seam = compare("Seam", *known_errors_case(seam_errors, np.zeros(1000)))
    assert even.error == pytest.approx(0.05) and seam.error == pytest.approx(np.sqrt(0.98e-4 + 0.02 * 0.09))
    assert seam.error < even.error and seam.p99 == pytest.approx(0.3) and even.p99 == pytest.approx(0.05)
    assert worst_object([even, seam]) is seam and worst_object([seam, even]) is seam
    assert {index for index, _ in seam.worst} <= set(np.flatnonzero(seam_errors == 0.3))
    assert [error for _, error in seam.worst] == pytest.approx([0.3] * 5)


def p99_where_prt_is_exact(nu_difference, nu_noise):
    """The 99th percentile of the de-noised error in units of Cycles' noise RMS where PRT is exact and Cycles'
    noise is Gaussian: e² ÷ noise² = X/ν₁ − Y/ν₂ with X ~ χ²(ν₁) (the noise drawn) and Y ~ χ²(ν₂) (its
    variance estimated from the passes), independent; q solves P(X/ν₁ − Y/ν₂ > q²) = 1 %, by quadrature."""
    def tail(q):
        def given(y):
            return stats.chi2.sf(nu_difference * (q * q + y / nu_noise), nu_difference) * stats.chi2.pdf(y, nu_noise)
        return integrate.quad(given, 0.0, np.inf)[0] - 0.01
    return optimize.brentq(tail, 0.1, 10.0)


@pytest.mark.parametrize("grey", [True, False])
def test_the_p99_keeps_part_of_cycles_noise_as_the_docstring_says(grey):
    """PRT exact, Cycles' noise Gaussian, 4 passes, 200,000 vertices. Grey light: one draw per vertex scaled into
    R, G and B (ν₁ = 1, ν₂ = 3); independent channels: ν₁ = 3, ν₂ = 9. The de-noised p99 comes out at 2.41 and
    1.71 × Cycles' noise RMS, the measured one (no noise taken out) at sqrt(χ²₀.₉₉(ν₁)/ν₁) = 2.58 and 1.94 ×."""
    rng = np.random.default_rng(7)
    passes_count, vertices = 4, 200_000
    draws = rng.standard_normal((passes_count, vertices, 1 if grey else 3)) * np.ones(3)
    cycles = np.array([0.0, 0.0, 40.0])  # far above the noise: the scale is 40 whatever was drawn
    comparison = compare("Noise", np.tile(cycles, (vertices, 1)), cycles + draws)
    nu_difference, nu_noise = (1, passes_count - 1) if grey else (3, 3 * (passes_count - 1))
    expected = p99_where_prt_is_exact(nu_difference, nu_noise)
    measured = np.sqrt(stats.chi2.ppf(0.99, nu_difference) / nu_difference)
    assert expected == pytest.approx(2.41 if grey else 1.71, abs=0.01)
    assert comparison.p99 / comparison.cycles_noise == pytest.approx(expected, abs=0.03)
    assert comparison.measured_p99 / comparison.cycles_noise == pytest.approx(measured, abs=0.03)
    assert comparison.error < 0.15 * comparison.cycles_noise  # the RMS takes the noise out: about 0
