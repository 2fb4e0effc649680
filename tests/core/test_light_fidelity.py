"""Light fidelity from the light alone: projection errors per order, the predicted shading error, the recommended
order, the Auto window and the sun split off an image, against closed forms and painted test images."""

import math

import numpy as np
import pytest

from prt_addon.core import light_fidelity, lights, lobes, sh, shading, sun_extraction


def band_image(coeffs, height=128, width=256):
    """An equirect image that is exactly the grey SH light `coeffs` (n²,)."""
    return np.repeat(lobes.reconstruct_equirect(coeffs, height, width), 3, axis=2)


def environment(pixels, name="painted"):
    return lights.Environment((name, pixels.shape[1], pixels.shape[0]), tuple(np.eye(3).ravel()), (1.0, 1.0, 1.0),
                              pixels=lambda: pixels)


def test_projection_error_of_a_band_limited_light_is_its_missing_bands_share():
    """A light with 1, 0.5 and 0.25 in one coefficient of bands 0, 1, 2: at order n the error is the share of the
    norm in bands ≥ n, and nothing from order 3 on."""
    coeffs = np.zeros(16)
    coeffs[sh.index(0, 0)], coeffs[sh.index(1, -1)], coeffs[sh.index(2, 1)] = 1.0, 0.5, 0.25
    fidelity = light_fidelity.analyse([environment(band_image(coeffs))], range(1, 6))
    norm = 1 + 0.25 + 0.0625
    for order, expected in {1: math.sqrt(0.3125 / norm), 2: math.sqrt(0.0625 / norm), 3: 0.0, 4: 0.0}.items():
        assert fidelity.projection[order] == pytest.approx(expected, abs=5e-3)  # the pixel sums, in a root


def test_a_point_sun_is_carried_by_no_order_and_a_sky_by_every_order():
    point = light_fidelity.analyse([lights.Sun((0.0, 0.0, 1.0), 0.0, (1.0, 1.0, 1.0))], [4, 16])
    assert point.projection == {4: 1.0, 16: 1.0}
    sky = light_fidelity.analyse([lights.Sky((0.5, 0.5, 0.5))], [1, 4])
    assert sky.projection == {1: pytest.approx(0.0, abs=1e-6), 4: pytest.approx(0.0, abs=1e-6)}
    assert sky.predicted == {1: 0.0, 4: 0.0} and sky.recommended == 1


def test_disc_norm_is_the_sum_of_its_band_powers():
    """Parseval for a disc of radius 1 rad: its closed-form ‖L‖² against Σ_l z_l² to band 63."""
    zonal = lobes.sun_disc_zonal(64, 1.0, irradiance=2.0)
    assert light_fidelity.disc_norm_squared((2.0, 0.0, 0.0), 1.0) == pytest.approx(np.sum(zonal ** 2), rel=0.02)


def test_unshadowed_model_transfer_has_the_clamped_cosine_band_powers():
    """With no occluder the model transfer is the clamped cosine / π, whose band power is (Â_l/π)²·(2l+1)/4π."""
    a_hat = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24])
    expected = (a_hat / np.pi) ** 2 * (2 * np.arange(5) + 1) / (4 * np.pi)
    measured = light_fidelity.transfer_band_powers(5, tilts=(0.0,))
    np.testing.assert_allclose(measured, expected, rtol=0.02, atol=1e-5)


def test_predicted_error_of_one_band_is_all_or_nothing():
    powers = np.zeros(8)
    powers[5] = 1.0
    predicted = light_fidelity.predicted_errors(powers, range(1, 9))
    assert [predicted[n] for n in range(1, 9)] == pytest.approx([1.0] * 5 + [0.0] * 3)


def test_recommended_order_is_the_lowest_meeting_the_target():
    predicted = {1: 0.3, 2: 0.1, 3: 0.04, 4: 0.02, 5: 0.01}
    assert light_fidelity.recommended_order(predicted, 0.03) == 4
    assert light_fidelity.recommended_order(predicted, 0.001) == 5
    sun = lights.Sun(shading.direction_from_angles(0.5, 0.2), 0.05, (3.0, 3.0, 3.0))
    fidelity = light_fidelity.analyse([sun, lights.Sky((0.2, 0.2, 0.2))], range(1, 17))
    errors = [fidelity.predicted[n] for n in range(1, 17)]
    assert errors == sorted(errors, reverse=True)  # more bands never predict more error
    assert fidelity.recommended == light_fidelity.recommended_order(fidelity.predicted)


# -- the Auto window ---------------------------------------------------------------------------------------------
def point_sun(order, sky=0.0):
    light = shading.sun_coefficients(order, (0.3, 0.4, 0.866), 0.0, 2.0) + lobes.constant_sky(order, sky)
    return np.tile(light, (3, 1))


@pytest.mark.parametrize("order", [4, 8, 16])
def test_auto_window_keeps_a_delta_like_light_non_negative_and_is_the_gentlest(order):
    """A point sun over a dim sky rings at every order; Auto tapers it until at most AUTO_CLAMPED_SHARE of it is
    negative, and a 1 % gentler taper would not do."""
    light = point_sun(order, sky=0.3)
    assert lights.negative_share(light) > 0.02
    strength = lights.auto_window_strength(light)
    assert 0.0 < strength < 1.0
    tapered = lobes.apply_window(light, lobes.window(order, "tapered", strength))
    assert lights.negative_share(tapered) <= lights.AUTO_CLAMPED_SHARE
    gentler = lobes.apply_window(light, lobes.window(order, "tapered", 0.99 * strength))
    assert lights.negative_share(gentler) > lights.AUTO_CLAMPED_SHARE


@pytest.mark.parametrize("order", [4, 8, 16])
def test_auto_window_stops_at_hanning(order):
    """A bare point rings more than Hanning takes out: Auto is Hanning (a stronger taper would cost more than
    Hanning does against the real light), and rings less than no window."""
    light = point_sun(order)
    assert lights.auto_window_strength(light) == 1.0
    hanning = lobes.apply_window(light, lobes.window(order, "hanning"))
    np.testing.assert_allclose(lights.windowed(light, "auto"), hanning)
    assert lights.negative_share(hanning) < 0.5 * lights.negative_share(light)


def test_auto_window_leaves_a_light_that_does_not_ring_alone():
    soft = np.zeros((3, 16))
    soft[:, 0], soft[:, sh.index(1, 0)] = 1.0, 0.3
    assert lights.auto_window_strength(soft) == 0.0
    np.testing.assert_array_equal(lights.windowed(soft, "auto"), soft)


def test_tapered_window_runs_from_none_to_hanning():
    np.testing.assert_allclose(lobes.window(6, "tapered", 0.0), np.ones(6))
    np.testing.assert_allclose(lobes.window(6, "tapered", 1.0), lobes.window(6, "hanning"))


# -- the sun split off an image ----------------------------------------------------------------------------------
def painted_sun(direction, radius, irradiance, height=512, width=1024):
    """A sky (brighter up, slightly coloured) with a disc of constant radiance E/(π sin²α) painted in."""
    directions = lobes.equirect_directions(height, width)
    sky = np.stack([0.4 + 0.2 * directions[..., 2], 0.5 + 0.2 * directions[..., 2], 0.7 + 0.1 * directions[..., 2]],
                   axis=-1)
    inside = directions @ np.asarray(direction) >= math.cos(radius)
    radiance = np.asarray(irradiance) / (math.pi * math.sin(radius) ** 2)
    image = sky.copy()
    image[inside] += radiance
    return image.astype(np.float32), sky


def test_sun_extraction_finds_a_painted_sun():
    direction = np.array(shading.direction_from_angles(math.radians(60.0), math.radians(30.0)))
    radius, irradiance = math.radians(2.0), np.array([3.0, 2.5, 2.0])
    image, sky = painted_sun(direction, radius, irradiance)
    found, without = sun_extraction.find_sun(image)
    assert found is not None
    assert math.degrees(math.acos(min(1.0, float(np.dot(found.direction, direction))))) < 0.2
    assert found.angular_radius == pytest.approx(radius, rel=0.1)
    np.testing.assert_allclose(found.irradiance, irradiance, rtol=0.05)
    sun_power = irradiance @ sun_extraction.LUMINANCE  # a small disc: its power is nearly its irradiance
    sky_power = np.sum((sky @ sun_extraction.LUMINANCE) * lobes.equirect_solid_angles(*sky.shape[:2]))
    assert found.share == pytest.approx(sun_power / (sun_power + sky_power), rel=0.05)
    # what is left is the sky: the disc is painted over with its surroundings
    assert np.abs(without - sky).max() < 0.05


def test_no_sun_in_a_smooth_sky_nor_in_a_large_bright_window():
    smooth = painted_sun((0.0, 0.0, 1.0), math.radians(2.0), (0.0, 0.0, 0.0))[0]
    assert sun_extraction.find_sun(smooth)[0] is None
    window = painted_sun((1.0, 0.0, 0.0), math.radians(15.0), (30.0, 30.0, 30.0), height=128, width=256)[0]
    assert sun_extraction.find_sun(window)[0] is None


def test_auto_is_never_predicted_worse_than_hanning():
    """Auto's taper lies between none and Hanning band by band, so through the predicted shading error it can
    never cost more than Hanning (benchmarks/lights.py --windows measures it against Cycles)."""
    rng = np.random.default_rng(7)
    for order in (4, 8, 12):
        light = np.tile(shading.sun_coefficients(16, tuple(rng.normal(size=3)), 0.05, 3.0)
                        + lobes.constant_sky(16, 0.1), (3, 1))
        powers = light_fidelity.band_powers(light)
        auto = lobes.window(order, "tapered", lights.auto_window_strength(light[:, :order * order]))
        predicted = {window: light_fidelity.predicted_errors(powers, [order], factors)[order]
                     for window, factors in (("auto", auto), ("none", None),
                                             ("hanning", lobes.window(order, "hanning")))}
        assert predicted["none"] <= predicted["auto"] <= predicted["hanning"]
