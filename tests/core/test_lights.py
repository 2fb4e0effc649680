"""SH lights: cached and turned lights against lights projected from scratch, the sum, windowing, closed forms."""

import numpy as np
import pytest
from numpy.polynomial.legendre import leggauss
from scipy.special import eval_legendre

from equirect import equirect_directions
from rotations import matrix_from_euler_zyz, quaternion_from_axis_angle

from prt_addon.core import lights, lobes, rotation, shading

ORDER = 4
A_HAT = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0])  # clamped cosine, bands 0-3


def sun(theta, phi, radius=0.05, rgb=(1.0, 1.0, 1.0)):
    return lights.Sun(shading.direction_from_angles(theta, phi), radius, rgb)


def smooth_equirect(height=32, width=64):
    """A smooth, direction-dependent RGB image with no symmetry a rotation could hide behind."""
    d = equirect_directions(height, width)
    return np.stack([1 + d[..., 0] + 0.5 * d[..., 1] * d[..., 2],
                     1 + 0.8 * d[..., 1] - 0.3 * d[..., 0] ** 2,
                     1 + 0.6 * d[..., 2] + 0.4 * d[..., 0] * d[..., 1]], axis=-1)


def environment(pixels, matrix=np.eye(3), rgb=(1.0, 1.0, 1.0), name="env"):
    return lights.Environment((name, pixels.shape[1], pixels.shape[0]), tuple(np.ravel(matrix)), rgb,
                              pixels=lambda: pixels)


def total(light_list, window="none", cache=None):
    return (cache or lights.LightCache()).totals(light_list, {ORDER}, window)[ORDER]


def test_moved_sun_equals_the_sun_projected_from_scratch_and_its_full_rotation():
    cache = lights.LightCache()
    before = total([sun(0.4, 0.3)], cache=cache)
    after = total([sun(1.2, -2.0)], cache=cache)
    from_scratch = shading.sun_coefficients(ORDER, shading.direction_from_angles(1.2, -2.0), 0.05)
    np.testing.assert_allclose(after, np.tile(from_scratch, (3, 1)), atol=1e-13)
    # The zonal placement agrees with turning the old sun by the full rotation matrix that moves its axis.
    old, new = np.array(shading.direction_from_angles(0.4, 0.3)), np.array(shading.direction_from_angles(1.2, -2.0))
    axis = np.cross(old, new)
    angle = np.arctan2(np.linalg.norm(axis), old @ new)
    turn = quaternion_from_axis_angle(axis, angle)
    np.testing.assert_allclose(rotation.rotate(before, turn), after, atol=1e-12)


def test_environment_turned_about_z_by_whole_pixels_equals_projecting_the_shifted_image():
    pixels = smooth_equirect()
    shift = 5  # columns: a turn by 5 pixel widths maps the pixel grid onto itself, so both sides are exact
    angle = 2 * np.pi * shift / pixels.shape[1]
    turned = total([environment(pixels, matrix_from_euler_zyz(angle, 0.0, 0.0))])
    shifted = total([environment(np.roll(pixels, -shift, axis=1), name="shifted")])
    np.testing.assert_allclose(turned, shifted, atol=1e-12 * np.abs(shifted).max())
    assert np.abs(turned - total([environment(pixels)])).max() > 0.1  # the turn did change the light


def test_environment_is_projected_once_and_turning_it_does_not_drift():
    pixels = smooth_equirect()
    reads = []
    light = lambda matrix: lights.Environment(("env", 64, 32), tuple(np.ravel(matrix)), (1.0, 1.0, 1.0),
                                              pixels=lambda: reads.append(1) or pixels)
    cache = lights.LightCache()
    rng = np.random.default_rng(3)
    for _ in range(50):
        total([light(rotation.quaternion_to_matrix(rng.normal(size=4)))], cache=cache)
    final = rotation.quaternion_to_matrix(rng.normal(size=4))
    from_scratch = rotation.rotate(lobes.project_equirect(pixels, ORDER), final)
    np.testing.assert_allclose(total([light(final)], cache=cache), from_scratch, atol=1e-13)
    assert len(reads) == 1


def test_sum_is_the_sum_of_the_lights_and_only_moved_suns_are_placed_in_one_evaluation(monkeypatch):
    eight = [sun(0.1 * k, 0.7 * k, rgb=(1.0, 0.5 * k, 0.1)) for k in range(6)] + [
        lights.Sky((0.2, 0.3, 0.4)), environment(smooth_equirect())]
    cache = lights.LightCache()
    summed = total(eight, cache=cache)
    one_by_one = sum(total([light]) for light in eight)
    np.testing.assert_allclose(summed, one_by_one, atol=1e-13)

    evaluated = []
    zonal_to_sh = rotation.zonal_to_sh
    monkeypatch.setattr(rotation, "zonal_to_sh", lambda z, d: evaluated.append(len(d)) or zonal_to_sh(z, d))
    eight[2] = sun(1.0, 2.0)
    total(eight, cache=cache)
    assert evaluated == [1]  # the one sun that moved
    eight[:6] = [sun(0.2 * k, 0.3 * k, radius=0.01 * k) for k in range(6)]
    all_moved = total(eight, cache=cache)
    assert evaluated == [1, 6]  # six moved suns, one evaluation
    np.testing.assert_allclose(all_moved, sum(total([light]) for light in eight), atol=1e-13)


def test_colour_scales_each_channel():
    white, tinted = total([sun(0.5, 1.0)]), total([sun(0.5, 1.0, rgb=(2.0, 0.5, 0.0))])
    np.testing.assert_allclose(tinted, white * np.array([[2.0], [0.5], [0.0]]), atol=1e-15)


@pytest.mark.parametrize("kind", ["hanning", "lanczos"])
def test_window_applies_to_the_sum(kind):
    light_list = [sun(0.3, 0.2, radius=0.0), lights.Sky((0.1, 0.1, 0.1))]
    windowed = total(light_list, window=kind)
    np.testing.assert_allclose(windowed, lobes.apply_window(total(light_list), lobes.window(ORDER, kind)), atol=1e-15)
    assert not np.allclose(windowed, total(light_list))


@pytest.mark.parametrize("irradiance", [1.0, 2.5])
def test_point_sun_above_an_upward_vertex_gives_the_band_limited_e_over_pi(irradiance):
    transfer = lobes.cosine_transfer(ORDER, np.array([[0.0, 0.0, 1.0]]))
    light = total([lights.Sun((0.0, 0.0, 1.0), 0.0, (irradiance,) * 3)])
    radiance = shading.shade(transfer.astype(np.float32), light)
    # Σ_l Â_l·(2l+1)/(4π): 1 in the limit of high order, 17/16 at order 4.
    expected = irradiance / np.pi * np.sum(A_HAT * (2 * np.arange(ORDER) + 1) / (4 * np.pi))
    np.testing.assert_allclose(expected, irradiance / np.pi * 17 / 16, rtol=1e-15)
    np.testing.assert_allclose(radiance, expected, rtol=1e-6)


def test_wide_sun_above_an_upward_vertex_matches_direct_integration():
    radius, irradiance = 0.6, 1.7
    transfer = lobes.cosine_transfer(ORDER, np.array([[0.0, 0.0, 1.0]]))
    light = total([lights.Sun((0.0, 0.0, 1.0), radius, (irradiance,) * 3)])
    # Band-limited product ∫ L̃ T̃: per band, 2π·radiance·∫_{cos α}^1 P_l · (2l+1)/(4π) · Â_l/π.
    nodes, weights = leggauss(16)  # exact for these polynomials
    lower = np.cos(radius)
    t, w = lower + (nodes + 1) * (1 - lower) / 2, weights * (1 - lower) / 2
    integrals = [eval_legendre(l, t) @ w for l in range(ORDER)]
    radiance = irradiance / (np.pi * np.sin(radius) ** 2)
    expected = sum(2 * np.pi * radiance * integrals[l] * (2 * l + 1) / (4 * np.pi) * A_HAT[l] / np.pi
                   for l in range(ORDER))
    np.testing.assert_allclose(transfer @ light.T, expected, rtol=1e-12)


def test_unit_sky_on_an_unoccluded_vertex_is_exactly_one():
    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, -1.0, 0.0]])
    light = total([lights.Sky((1.0, 1.0, 1.0))])
    np.testing.assert_allclose(lobes.cosine_transfer(ORDER, normals) @ light.T, 1.0, rtol=1e-14)


def test_a_sun_without_direction_is_refused():
    with pytest.raises(ValueError, match="direction"):
        total([lights.Sun((0.0, 0.0, 0.0), 0.1, (1.0, 1.0, 1.0))])
