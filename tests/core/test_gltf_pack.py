"""glTF's frame, the profiles' packing and the GLB container, without Blender."""

import math

import numpy as np
import pytest

from prt_addon.core import glb, gltf_pack, lights, lobes, rotation, shading
from prt_addon.core.errors import InputError

RNG = np.random.default_rng(17)


def random_transfer(points, order, channels=None):
    shape = (points, order * order) if channels is None else (points, channels, order * order)
    return RNG.normal(size=shape)


def test_the_frame_is_the_exporters_axis_conversion():
    """glTF (x, y, z) = Blender (x, z, −y), and it is a proper rotation (so an SH rotation exists)."""
    assert gltf_pack.direction_to_gltf([1.0, 2.0, 3.0]) == [1.0, 3.0, -2.0]
    matrix = gltf_pack.Z_UP_TO_Y_UP
    assert np.allclose(matrix.T @ matrix, np.eye(3)) and np.isclose(np.linalg.det(matrix), 1.0)


@pytest.mark.parametrize("order", [2, 4, 7])
def test_a_sun_in_blender_and_the_same_sun_in_gltfs_frame_shade_identically(order):
    """The sun placed along its glTF direction on the rotated transfer gives Blender's shading, to rounding."""
    transfer = random_transfer(50, order)
    direction = shading.direction_from_angles(math.radians(40), math.radians(120))
    zonal = lobes.sun_disc_zonal(order, 0.2, 2.0)
    in_blender = shading.shade(transfer, np.tile(rotation.zonal_to_sh(zonal, direction), (3, 1)))
    in_gltf = shading.shade(gltf_pack.to_gltf_frame(transfer),
                            np.tile(rotation.zonal_to_sh(zonal, gltf_pack.direction_to_gltf(direction)), (3, 1)))
    assert np.allclose(in_gltf, in_blender, atol=1e-5 * np.abs(in_blender).max())


def test_an_environment_turned_into_gltfs_frame_shades_coloured_transfer_identically():
    order = 4
    transfer, light = random_transfer(20, order, channels=3), RNG.normal(size=(3, order * order))
    in_gltf = shading.shade(gltf_pack.to_gltf_frame(transfer), gltf_pack.to_gltf_frame(light))
    assert np.allclose(in_gltf, shading.shade(transfer, light), atol=1e-4)


def test_web_packs_within_twelve_vec4s_channel_after_channel():
    transfer = random_transfer(5, 4, channels=3).astype(np.float32)  # 48 floats: exactly 12 VEC4s
    packed = gltf_pack.pack(transfer, gltf_pack.PROFILES["web"], "Cube")
    assert list(packed.attributes) == [f"_PRT_SH{j}" for j in range(12)] and packed.texture is None
    rows = np.hstack(list(packed.attributes.values()))
    assert np.array_equal(rows, transfer.reshape(5, 48))
    assert packed.extras() == {"order": 4, "channels": 3, "vec4s": 12, "layout": "attributes",
                               "attributes": list(packed.attributes)}


def test_grey_transfer_is_zero_padded_to_whole_vec4s():
    transfer = random_transfer(3, 3).astype(np.float32)  # 9 coefficients: 3 VEC4s, the last holding 1
    packed = gltf_pack.pack(transfer, gltf_pack.PROFILES["generic"], "Cube")
    rows = np.hstack(list(packed.attributes.values()))
    assert rows.shape == (3, 12) and np.array_equal(rows[:, :9], transfer) and not rows[:, 9:].any()


def test_web_beyond_its_budget_is_a_data_texture_indexed_by_point():
    transfer = random_transfer(1000, 7).astype(np.float32)  # 49 coefficients: 13 VEC4s
    packed = gltf_pack.pack(transfer, gltf_pack.PROFILES["web"], "Cube")
    assert packed.attributes == {} and packed.vec4s == 13
    height, width = packed.texture.shape[:2]
    assert width == gltf_pack.TEXTURE_WIDTH and height * width >= 13_000
    texels = packed.texture.reshape(-1, 4)
    point, j = 617, 5  # texel point·vec4s + j holds floats 4j .. 4j + 3 of the point
    assert np.array_equal(texels[point * 13 + j], transfer[point, 4 * j: 4 * j + 4])
    assert packed.extras()["texture"] == {"width": width, "height": height, "format": "RGBA32F"}


@pytest.mark.parametrize("order, channels", [(5, None), (3, 3)])
def test_godot_refuses_what_its_four_custom_arrays_cannot_hold(order, channels):
    with pytest.raises(InputError, match="godot profile allows 4 .*CUSTOM0-CUSTOM3"):
        gltf_pack.pack(random_transfer(4, order, channels).astype(np.float32), gltf_pack.PROFILES["godot"], "Cube")


def test_godot_holds_order_four_grey_in_custom0_to_3():
    packed = gltf_pack.pack(random_transfer(4, 4).astype(np.float32), gltf_pack.PROFILES["godot"], "Cube")
    assert list(packed.attributes) == ["_CUSTOM0", "_CUSTOM1", "_CUSTOM2", "_CUSTOM3"]


def test_light_extras_rebuild_the_scenes_light_in_gltfs_frame():
    """A viewer that places each sun's zonal lobe along its glTF direction and adds the others' coefficients gets
    the scene's light, turned into glTF's frame."""
    order = 5
    scene = [lights.Sun(shading.direction_from_angles(0.7, -1.2), 0.15, (2.0, 1.5, 1.0)), lights.Sky((0.3, 0.2, 0.1))]
    rebuilt = np.zeros((3, order * order))
    for light in gltf_pack.light_extras(scene, order):
        if light["kind"] == "sun":
            assert math.isclose(light["theta"], 0.7) and math.isclose(light["phi"], -1.2)
            rebuilt += np.outer(light["rgb"], rotation.zonal_to_sh(np.array(light["zonal"]), light["direction"]))
        else:
            rebuilt += np.array(light["coefficients"])
    expected = gltf_pack.to_gltf_frame(lights.LightCache().totals(scene, [order])[order])
    assert np.allclose(rebuilt, expected, atol=1e-12)


def test_glb_round_trip_with_an_appended_view():
    document = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": 3}]}
    binary = bytearray(b"abc")
    index = glb.append_buffer_view(document, binary, b"0123456789")
    data = glb.write(document, binary)
    assert len(data) % 4 == 0
    read_document, read_binary = glb.read(data)
    view = read_document["bufferViews"][index]
    assert view["byteOffset"] % 16 == 0 and read_document["buffers"][0]["byteLength"] == len(binary)
    assert bytes(read_binary[view["byteOffset"]: view["byteOffset"] + view["byteLength"]]) == b"0123456789"
