"""Lights at their extremes (issue: stability): delta and hemisphere suns, huge and tiny strengths, an HDRI
with a sun spike with and without windowing, and how negative reconstructed light is handled."""

import bpy  # noqa: F401  (to read the bundled HDRIs)
import numpy as np
import pytest

from prt_addon.core import lights, lobes, shading

ORDER = 4


def sun(strength, radius=0.05, direction=(0.3, -0.4, 0.86)):
    return lights.Sun(tuple(np.array(direction) / np.linalg.norm(direction)), radius, (strength,) * 3)


def total(light_list, window="none"):
    return lights.LightCache().totals(light_list, {ORDER}, window)[ORDER]


@pytest.mark.parametrize("strength", [1e-6, 1e6])
def test_strength_is_exactly_linear_from_1e_minus_6_to_1e6(strength):
    unit = total([sun(1.0)])
    np.testing.assert_allclose(total([sun(strength)]), strength * unit, rtol=1e-13, atol=0)


@pytest.mark.parametrize("radius", [0.0, 1e-9, np.pi / 2])
def test_delta_and_hemisphere_suns_are_finite_and_keep_their_irradiance(radius):
    """Whatever its radius, a sun of irradiance E straight above an upward vertex gives E/π times the
    band-limited cosine's response; at π/2 it is the upper hemisphere of radiance E/π: irradiance E."""
    coefficients = total([sun(1.0, radius, direction=(0.0, 0.0, 1.0))])
    assert np.isfinite(coefficients).all()
    upward = lobes.cosine_transfer(ORDER, np.array([[0.0, 0.0, 1.0]]))[0]
    value = coefficients[0] @ upward
    if radius == np.pi / 2:
        # A hemisphere of constant radiance 1/π: (1/π)∫ L cos over the band-limited hemisphere.
        zonal = lobes.sun_disc_zonal(ORDER, np.pi / 2, 1.0)
        expected = np.sum(zonal * lobes.clamped_cosine_zonal(ORDER)) / np.pi
    else:
        expected = np.sum(lobes.clamped_cosine_zonal(ORDER) * np.sqrt((2 * np.arange(ORDER) + 1) / (4 * np.pi))) / np.pi
    assert value == pytest.approx(expected, rel=1e-9)


@pytest.fixture(scope="module")
def sunrise():
    from pathlib import Path
    root = Path(bpy.utils.system_resource("DATAFILES")) / "studiolights" / "world"
    image = bpy.data.images.load(str(root / "sunrise.exr"))
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, 4)[..., :3].astype(np.float64)


def test_hdri_with_a_sun_spike_rings_and_windowing_tames_it(sunrise):
    """sunrise.exr's sun makes the order-8 reconstruction go negative; Hanning windowing keeps the total flux
    (band 0 is untouched) and at least halves the most negative value."""
    order = 8
    coefficients = lobes.project_equirect(sunrise, order)
    plain = lobes.reconstruct_equirect(coefficients, 64, 128)
    windowed = lobes.reconstruct_equirect(lobes.apply_window(coefficients, lobes.window(order, "hanning")), 64, 128)
    assert plain.min() < 0 and np.isfinite(plain).all()
    windowed_coefficients = lobes.apply_window(coefficients, lobes.window(order, "hanning"))
    np.testing.assert_array_equal(windowed_coefficients[:, 0], coefficients[:, 0])  # same flux
    assert windowed.min() > 0.5 * plain.min()  # negative lobes at least halved


def test_negative_light_is_clamped_to_black_in_the_display_colours():
    """Documented behaviour: shading goes negative under a ringing light; the colours written are clamped to 0."""
    from prt_addon.blender import display
    mesh = bpy.data.meshes.new("probe")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    transfer = lobes.cosine_transfer(ORDER, normals).astype(np.float32)
    ringing = total([sun(1.0, 0.0, direction=(0.0, 0.0, 1.0))])
    ringing[:, 0] -= 0.3  # a light dimmer than its own ringing: negative below
    raw = shading.shade(transfer, ringing)
    assert raw[1].max() < 0 < raw[0].min()
    display.write_display_colours(mesh, transfer, ringing)
    written = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes[display.DISPLAY_ATTRIBUTE].data.foreach_get("color", written)
    np.testing.assert_allclose(written.reshape(-1, 4)[:, :3], np.maximum(raw, 0.0), rtol=1e-6)
    bpy.data.meshes.remove(mesh)


def test_an_environment_whose_image_file_is_missing_does_not_shine_and_says_so(empty_scene, tmp_path, capfd):
    from prt_addon.blender import storage
    from prt_addon.blender.scene_bake import SceneBake
    from prt_addon.core.bake import BakeSettings
    from test_bake_blender import grid
    floor = grid("Floor", cuts=2)
    SceneBake(bpy.context, BakeSettings(order=ORDER, samples=16), ["Floor"]).run(log=lambda line: None)
    missing = bpy.data.images.new("gone", 8, 4, float_buffer=True)
    missing.source, missing.filepath = "FILE", str(tmp_path / "gone.exr")  # a file that is not there
    missing.reload()
    bpy.ops.prt.light_add(kind="SKY")
    bpy.ops.prt.light_add(kind="ENVIRONMENT")
    empty_scene.prt_lights[-1].image = missing
    bpy.context.evaluated_depsgraph_get().update()
    transfer, _ = storage.read_transfer(floor.data)
    written = np.empty(len(floor.data.vertices) * 4, dtype=np.float32)
    floor.data.color_attributes["prt_color"].data.foreach_get("color", written)
    sky_only = shading.shade(transfer, np.tile(lobes.constant_sky(ORDER, 1.0), (3, 1)))
    np.testing.assert_allclose(written.reshape(-1, 4)[:, :3], sky_only, rtol=1e-5)
    assert "SH light 'Environment' has no readable image" in capfd.readouterr().out
