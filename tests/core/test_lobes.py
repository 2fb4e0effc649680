"""Lobes and equirect projection against closed forms, exact quadrature, scipy SH and Blender's HDRIs."""
import glob
import os

import numpy as np
import pytest
from numpy.polynomial.legendre import leggauss
from scipy.special import eval_legendre

from equirect import equirect_directions
from quadrature import reference_sh

from prt_addon.core import lobes



def zonal_normalisation(order):
    return np.sqrt((2 * np.arange(order) + 1) / (4 * np.pi))


def legendre_integrals(order, lower, upper, nodes=64):
    """∫_lower^upper P_l(t) dt and ∫ t·P_l(t) dt by Gauss-Legendre: exact for degree < 2·nodes - 1."""
    x, w = leggauss(nodes)
    t = lower + (x + 1) * (upper - lower) / 2
    w = w * (upper - lower) / 2
    p = np.array([eval_legendre(l, t) for l in range(order)])
    return p @ w, p @ (w * t)


def random_unit_vectors(count, seed):
    v = np.random.default_rng(seed).standard_normal((count, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# --- clamped cosine -----------------------------------------------------------------------------------------

def test_clamped_cosine_matches_closed_form_for_low_bands():
    a_hat = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24, 0.0, np.pi / 64])
    np.testing.assert_allclose(lobes.clamped_cosine_zonal(7), a_hat * zonal_normalisation(7), rtol=1e-14, atol=1e-16)


@pytest.mark.parametrize("order", [30, 64])
def test_clamped_cosine_matches_quadrature(order):
    _, first_moments = legendre_integrals(order, 0.0, 1.0)
    truth = 2 * np.pi * first_moments * zonal_normalisation(order)
    result = lobes.clamped_cosine_zonal(order)
    assert np.all(np.isfinite(result))
    np.testing.assert_allclose(result, truth, rtol=0, atol=5e-14)  # the quadrature's own rounding
    assert abs(result[order - 2]) > 1e-4  # the high even bands are small but genuinely nonzero


def test_cosine_transfer_is_eigenvalue_times_sh_at_normal():
    normals = np.vstack([random_unit_vectors(20, 0), [[0, 0, 1.0], [0, 0, -1.0]]])
    a_hat = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24])
    per_coefficient = np.repeat(a_hat / np.pi, 2 * np.arange(5) + 1)
    np.testing.assert_allclose(lobes.cosine_transfer(5, normals), reference_sh(5, normals) * per_coefficient,
                               rtol=0, atol=1e-14)


def test_unit_constant_sky_through_cosine_transfer_gives_exactly_one():
    normals = random_unit_vectors(50, 1)
    radiance = lobes.cosine_transfer(6, normals) @ lobes.constant_sky(6)
    np.testing.assert_allclose(radiance, 1.0, rtol=1e-14)


# --- sun disc and sky -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("angular_radius", [0.01, 0.1, 0.5, 1.0, 1.4])
def test_sun_disc_matches_quadrature(angular_radius):
    order, irradiance = 30, 2.5
    integrals, _ = legendre_integrals(order, np.cos(angular_radius), 1.0)
    radiance = irradiance / (np.pi * np.sin(angular_radius) ** 2)
    truth = radiance * 2 * np.pi * zonal_normalisation(order) * integrals
    result = lobes.sun_disc_zonal(order, angular_radius, irradiance)
    np.testing.assert_allclose(result, truth, rtol=0, atol=1e-11 * np.abs(truth).max())


@pytest.mark.parametrize("angular_radius", [0.0, 1e-8])
def test_sun_disc_is_exactly_the_delta_at_tiny_radius(angular_radius):
    order = 64
    delta = 1.7 * zonal_normalisation(order)
    np.testing.assert_allclose(lobes.sun_disc_zonal(order, angular_radius, 1.7), delta, rtol=1e-12)


def test_sun_disc_follows_the_delta_plus_its_taylor_terms_at_small_radius():
    """At α = 1e-4 the disc really differs from the delta by ~ε·l²/4 (ε = 1 - cos α = 5e-9), too much for a
    1e-12 comparison with the bare delta. z_l/delta_l = 2·P_l'(1-ε)/(l(l+1)); Taylor's terms follow from
    P_l^(k)(1) = (l+k)! / ((l-k)!·k!·2^k)."""
    order, alpha = 64, 1e-4
    l = np.arange(order)
    eps = 2 * np.sin(alpha / 2) ** 2
    ratio = 1 - eps * (l - 1) * (l + 2) / 4 + eps ** 2 * (l - 2) * (l - 1) * (l + 2) * (l + 3) / 48
    np.testing.assert_allclose(lobes.sun_disc_zonal(order, alpha), ratio * zonal_normalisation(order), rtol=1e-12)


def test_sun_disc_at_right_angle_is_the_upper_hemisphere():
    order, irradiance = 30, 3.0
    result = lobes.sun_disc_zonal(order, np.pi / 2, irradiance)
    # radiance E/π over the hemisphere: flux 2E, dipole E·sqrt(3/4π), no even bands beyond 0
    np.testing.assert_allclose(result[:3], [2 * irradiance / np.sqrt(4 * np.pi), irradiance * np.sqrt(3 / (4 * np.pi)), 0],
                               rtol=0, atol=1e-14)
    integrals, _ = legendre_integrals(order, 0.0, 1.0)
    truth = irradiance / np.pi * 2 * np.pi * zonal_normalisation(order) * integrals
    np.testing.assert_allclose(result, truth, rtol=0, atol=1e-13)


@pytest.mark.parametrize("angular_radius", [-1e-3, np.pi / 2 + 1e-3])
def test_sun_disc_rejects_radius_outside_quarter_turn(angular_radius):
    with pytest.raises(ValueError):
        lobes.sun_disc_zonal(4, angular_radius)


def test_constant_sky_reconstructs_to_its_radiance_everywhere():
    coeffs = lobes.constant_sky(5, 0.75)
    assert np.count_nonzero(coeffs) == 1
    np.testing.assert_allclose(lobes.reconstruct_equirect(coeffs, 8, 16), 0.75, rtol=1e-14)


# --- equirect mapping -------------------------------------------------------------------------------------------

def cycles_direction_to_uv(directions):
    """direction_to_equirectangular from Cycles (range -2π, π, -π, π), written out independently."""
    u = (np.arctan2(directions[..., 1], directions[..., 0]) - np.pi) / (-2 * np.pi)
    v = (np.arccos(np.clip(directions[..., 2], -1, 1)) - np.pi) / (-np.pi)
    return u, v


def pixel_directions(height, width):
    """The direction the code gives each pixel centre, read back by reconstructing x, y and z, which are
    Y_1,1, Y_1,-1 and Y_1,0 scaled: Y_1,(-1, 0, 1) = √(3/4π)·(-y, z, -x)."""
    coeffs = np.zeros((3, 4))
    coeffs[0, 3], coeffs[1, 1], coeffs[2, 2] = -1.0, -1.0, 1.0
    return lobes.reconstruct_equirect(coeffs / np.sqrt(3 / (4 * np.pi)), height, width)


def test_pixel_centres_are_unit_and_map_back_to_their_pixel_through_cycles_formula():
    height, width = 16, 32
    directions = pixel_directions(height, width)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, rtol=1e-15)
    u, v = cycles_direction_to_uv(directions)
    rows, columns = np.mgrid[0:height, 0:width]
    np.testing.assert_allclose(u, (columns + 0.5) / width, rtol=0, atol=1e-14)
    np.testing.assert_allclose(v, (rows + 0.5) / height, rtol=0, atol=1e-14)
    # ... and so agree with the directions Cycles' inverse formula gives the pixel centres (the test images).
    np.testing.assert_allclose(directions, equirect_directions(height, width), rtol=0, atol=1e-15)


def test_known_directions_land_on_the_documented_pixels():
    odd = pixel_directions(5, 9)       # centre pixel (2, 4) sits at u = v = 0.5
    np.testing.assert_allclose(odd[2, 4], [1, 0, 0], atol=1e-15)
    quarter = pixel_directions(5, 6)   # columns 1 and 4 sit at u = 0.25 and 0.75
    np.testing.assert_allclose(quarter[2, 1], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(quarter[2, 4], [0, -1, 0], atol=1e-15)
    z = odd[..., 2]
    assert np.all(z[-1] == z.max()) and np.all(z[0] == z.min())  # top row looks up, bottom row down
    np.testing.assert_allclose(z[-1], np.cos(np.pi / 10), rtol=1e-15)
    columns_at_seam = odd[2, [0, -1]]                               # u = 0 and u = 1 both border -X
    assert np.all(columns_at_seam[:, 0] < -0.9)
    assert columns_at_seam[0, 1] > 0 > columns_at_seam[1, 1]          # u grows as φ decreases


def test_solid_angles_are_exact_and_sum_to_the_sphere():
    height, width = 37, 64
    edges = np.pi * np.arange(height + 1) / height  # v edges → z = -cos(π·v)
    truth = (2 * np.pi / width) * np.diff(-np.cos(edges))
    result = lobes.equirect_solid_angles(height, width)
    assert result.shape == (height, 1)
    np.testing.assert_allclose(result[:, 0], truth, rtol=1e-13)
    np.testing.assert_allclose(result.sum() * width, 4 * np.pi, rtol=1e-14)
    np.testing.assert_allclose(result[::-1], result, rtol=1e-14)  # north and south mirror each other


# --- projection -------------------------------------------------------------------------------------------------

def load_blender_image(path):
    import bpy
    image = bpy.data.images.load(path)
    width, height = image.size
    buffer = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(buffer)
    bpy.data.images.remove(image)
    return buffer.reshape(height, width, 4)


@pytest.fixture(scope="module")
def hdris():
    import bpy
    paths = sorted(glob.glob(os.path.join(bpy.utils.system_resource("DATAFILES"), "studiolights", "world", "*.exr")))
    assert len(paths) >= 2, "Blender's bundled world HDRIs are missing"
    return {os.path.basename(path): load_blender_image(path) for path in paths}


def test_projected_flux_matches_direct_integration_of_real_hdris(hdris):
    for name in ["forest.exr", "city.exr", "sunset.exr"]:
        pixels = hdris[name]
        height, width = pixels.shape[:2]
        edges = np.pi * np.arange(height + 1) / height
        solid_angles = (2 * np.pi / width) * np.diff(-np.cos(edges))
        direct = np.einsum("hwc,h->c", pixels[..., :3].astype(np.float64), solid_angles)
        flux = lobes.project_equirect(pixels, 2)[:, 0] * np.sqrt(4 * np.pi)
        np.testing.assert_allclose(flux, direct, rtol=1e-6, err_msg=name)


def test_every_bundled_hdri_is_brighter_above_the_horizon(hdris):
    """Real-data check of the orientation: sky and ceiling lights are above, so row 0 must be the bottom."""
    for name, pixels in hdris.items():
        coeffs = lobes.project_equirect(pixels, 2)
        upward_dipole = coeffs[:, 2]  # Y_1,0 ∝ z
        assert np.all(upward_dipole > 0.1 * coeffs[:, 0]), name


@pytest.mark.parametrize("order", [4, 8])
def test_projection_of_band_limited_image_has_the_predicted_grid_error(order):
    """With W > 2·(order-1) the column sums are exact, and the row rule (value at the row's centre angle times
    its exact Δz) errs by (h²/24)·(2π·(F(+Z) + F(-Z)) - c_k) + O(h⁴), h = π/H, F = f·Y_k: the bound the grid
    allows. The prediction is checked to 1% (the O(h⁴) rest), and the error shrinks 4× per doubling of H."""
    coeffs = np.random.default_rng(order).standard_normal((3, order * order))
    poles = reference_sh(order, np.array([[0, 0, 1.0], [0, 0, -1.0]]))
    pole_integrands = 2 * np.pi * (poles @ coeffs.T).T @ poles
    errors = []
    for height in [128, 256]:
        image = reference_sh(order, equirect_directions(height, 2 * height)) @ coeffs.T
        error = lobes.project_equirect(image, order) - coeffs
        predicted = (np.pi / height) ** 2 / 24 * (pole_integrands - coeffs)
        np.testing.assert_allclose(error, predicted, rtol=0, atol=0.01 * np.abs(predicted).max())
        errors.append(np.abs(error).max())
    assert 3.9 < errors[0] / errors[1] < 4.2


def test_reconstruct_then_project_tends_to_identity():
    order = 8
    coeffs = np.random.default_rng(5).standard_normal((3, order * order))
    errors = [np.abs(lobes.project_equirect(lobes.reconstruct_equirect(coeffs, h, 2 * h), order) - coeffs).max()
              for h in [64, 128, 256]]
    assert errors[0] / errors[1] > 3.9 and errors[1] / errors[2] > 3.9
    assert errors[2] < 1e-3 * np.abs(coeffs).max()


def test_reconstruction_matches_reference_sh_and_handles_one_channel():
    coeffs = np.random.default_rng(6).standard_normal((2, 25))
    truth = reference_sh(5, equirect_directions(6, 10)) @ coeffs.T
    np.testing.assert_allclose(lobes.reconstruct_equirect(coeffs, 6, 10), truth, rtol=0, atol=1e-13)
    single = lobes.reconstruct_equirect(coeffs[0], 6, 10)
    np.testing.assert_allclose(single[..., 0], truth[..., 0], rtol=0, atol=1e-13)


def test_projection_reads_only_rgb_and_chunks_consistently(monkeypatch):
    rng = np.random.default_rng(7)
    pixels = rng.random((24, 48, 4)).astype(np.float32)
    whole = lobes.project_equirect(pixels, 3)
    assert whole.shape == (3, 9)
    pixels[..., 3] = 1e6  # alpha must not leak into colour
    monkeypatch.setattr(lobes, "_CHUNK_VALUES", 48 * 9 * 5)  # 5 rows per chunk: a ragged last chunk
    # Chunks change the order of the sums: equal to rounding, relative to the largest coefficient.
    np.testing.assert_allclose(lobes.project_equirect(pixels, 3), whole, rtol=0,
                               atol=1e-14 * np.abs(whole).max())


# --- windows ----------------------------------------------------------------------------------------------------

def test_window_values():
    np.testing.assert_array_equal(lobes.window(6, "none"), np.ones(6))
    np.testing.assert_allclose(lobes.window(4, "hanning"), [1, (1 + np.sqrt(0.5)) / 2, 0.5, (1 - np.sqrt(0.5)) / 2],
                               rtol=1e-15)
    np.testing.assert_allclose(lobes.window(4, "lanczos"),
                               [1, np.sin(np.pi / 4) / (np.pi / 4), np.sin(np.pi / 2) / (np.pi / 2),
                                np.sin(3 * np.pi / 4) / (3 * np.pi / 4)], rtol=1e-15)
    with pytest.raises(ValueError):
        lobes.window(4, "hamming")


def test_apply_window_scales_every_m_of_a_band():
    factors = np.array([1.0, 0.5, 0.25])
    result = lobes.apply_window(np.ones((2, 9)), factors)
    np.testing.assert_array_equal(result, [[1, 0.5, 0.5, 0.5, 0.25, 0.25, 0.25, 0.25, 0.25]] * 2)
    with pytest.raises(ValueError):
        lobes.apply_window(np.ones(16), factors)


@pytest.mark.parametrize("kind", ["hanning", "lanczos"])
def test_window_reduces_ringing_of_a_sharp_sun(kind):
    order = 8
    zonal = lobes.sun_disc_zonal(order, 0.05)
    cos_theta = np.cos(np.linspace(0, np.pi, 4001))
    legendre = np.array([eval_legendre(l, cos_theta) for l in range(order)])

    def most_negative(factors):
        return ((factors * zonal * zonal_normalisation(order)) @ legendre).min()

    plain = most_negative(lobes.window(order, "none"))
    assert plain < -0.5
    assert plain / 4 < most_negative(lobes.window(order, kind)) < 0  # still a ring, but far weaker
