"""Interreflected bakes through the add-on: albedo from materials, RGB storage, export and relighting."""

import json

import bpy
import numpy as np

from conftest import run_cli
from prt_addon.blender import geometry, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import lobes, shading
from prt_addon.core.bake import BakeSettings
from node_setups import principled_material
from test_bake_blender import add_mesh, grid


def coloured(ob, rgb, texture=None):
    ob.data.materials.append(principled_material(f"{ob.name} colour", rgb, texture))
    return ob


def wall(name, x):
    """A 2 × 2 wall in the plane x = `x`, standing on the floor, facing the origin."""
    ticks = np.linspace(-1.0, 1.0, 9)
    heights = np.linspace(0.0, 2.0, 9)
    vertices = [(x, y, z) for z in heights for y in ticks]
    faces = [(r * 9 + c, r * 9 + c + 1, (r + 1) * 9 + c + 1, (r + 1) * 9 + c) for r in range(8) for c in range(8)]
    if x > 0:  # as listed the faces face +X
        faces = [tuple(reversed(f)) for f in faces]
    ob = add_mesh(name, vertices, faces)
    assert np.sign(ob.data.polygons[0].normal.x) == -np.sign(x)  # facing into the box
    return ob


def cornell():
    floor = coloured(grid("Floor", size=2.0, cuts=8), (0.8, 0.8, 0.8))
    red = coloured(wall("Red", 1.0), (0.8, 0.05, 0.05))
    green = coloured(wall("Green", -1.0), (0.05, 0.8, 0.05))
    return floor, red, green


def test_cornell_floor_turns_red_near_the_red_wall_and_green_near_the_green(empty_scene):
    floor, red, green = cornell()
    scene_bake = SceneBake(bpy.context, BakeSettings(mode="interreflected", order=3, samples=128), ["Floor"])
    summary = scene_bake.run(log=lambda line: None)
    transfer, meta = storage.read_transfer(floor.data)
    assert transfer.shape == (81, 3, 9) and meta["channels"] == 3 and meta["bounces"] >= 1
    assert "prt" not in red.data and "prt" not in green.data  # they only reflected light
    positions = np.array([v.co[:] for v in floor.data.vertices])
    near_red = np.argmin(np.linalg.norm(positions - [0.75, 0.0, 0.0], axis=1))
    near_green = np.argmin(np.linalg.norm(positions - [-0.75, 0.0, 0.0], axis=1))
    sky = transfer[:, :, 0]  # under a constant sky only T_00 matters
    assert sky[near_red, 0] > 1.05 * sky[near_red, 1]
    assert sky[near_green, 1] > 1.05 * sky[near_green, 0]
    assert summary.bounce_relative_changes and summary.bounce_relative_changes[0] < 1
    report = scene_bake.report().as_dict()
    assert report["bounces"] == summary.bounces and set(report["phases_s"]) >= {"rays_s", "bounces_s"}


def test_grey_scene_keeps_one_channel_and_texture_albedo_is_sampled(empty_scene):
    floor = coloured(grid("Floor", size=2.0, cuts=4), (0.5, 0.5, 0.5))
    image = bpy.data.images.new("half red", 4, 4)
    pixels = np.ones((4, 4, 4), dtype=np.float32)
    pixels[:, 2:, 1:3] = 0.0  # right half (u ≥ 0.5) red
    image.pixels.foreach_set(pixels.ravel())
    textured = coloured(wall("Textured", 1.0), (0.8, 0.8, 0.8), texture=image)
    notes = []
    surface = geometry.surface_from_object(textured, bpy.context.evaluated_depsgraph_get(), notes, albedo=True)
    assert any("no UV map" in note for note in notes)  # add_mesh makes no UVs: the colour value is used
    np.testing.assert_allclose(surface.albedo, 0.8)
    textured.data.uv_layers.new(name="UVMap")
    uv = np.array([[v.co.y * 0.5 + 0.5, v.co.z * 0.5] for v in textured.data.vertices])
    corner_vertex = [loop.vertex_index for loop in textured.data.loops]
    textured.data.uv_layers["UVMap"].data.foreach_set("uv", uv[corner_vertex].ravel())
    surface = geometry.surface_from_object(textured, bpy.context.evaluated_depsgraph_get(), [], albedo=True)
    left, right = surface.albedo[uv[:, 0] < 0.4], surface.albedo[uv[:, 0] > 0.6]
    assert np.all(left > 0.9) and np.all(right[:, 0] > 0.9) and np.all(right[:, 1:] < 0.1)
    textured.data.materials.clear()  # now everything is grey (Blender's default)
    scene_bake = SceneBake(bpy.context, BakeSettings(mode="interreflected", order=2, samples=32), ["Floor"])
    scene_bake.run(log=lambda line: None)
    transfer, meta = storage.read_transfer(floor.data)
    assert transfer.shape == (25, 4) and meta["channels"] == 1


def test_rgb_bake_relights_and_exports(empty_scene, tmp_path):
    floor, red, green = cornell()
    SceneBake(bpy.context, BakeSettings(mode="interreflected", order=3, samples=64, bounces=2),
              ["Floor"]).run(log=lambda line: None)
    transfer, _ = storage.read_transfer(floor.data)
    light = np.tile(lobes.constant_sky(3, 1.0), (3, 1))
    radiance = shading.shade(transfer, light)
    np.testing.assert_allclose(radiance, np.einsum("vck,ck->vc", transfer, light), rtol=1e-6)
    path = tmp_path / "cornell.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    npz = tmp_path / "floor.npz"
    result = run_cli("export", path, "--object", "Floor", "--npz", npz)
    assert result.returncode == 0, result.stderr
    exported = np.load(npz)
    assert exported["transfer"].shape == (81, 3, 9)
    assert json.loads(str(exported["metadata"]))["channels"] == 3


def test_cli_bounces_argument():
    result = run_cli("bake", "x.blend", "--mode", "interreflected", "--bounces", "many")
    assert result.returncode == 1 and "bounces must be a whole number or 'auto'" in result.stderr


def test_albedo_is_read_from_the_own_materials_while_the_prt_display_stands_in(empty_scene):
    floor = coloured(grid("Floor", size=2.0, cuts=2), (0.7, 0.1, 0.2))
    SceneBake(bpy.context, BakeSettings(samples=16), ["Floor"]).run(log=lambda line: None)
    bpy.context.scene.prt_display.show_prt = True  # the add-on's handler swaps in its display materials
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert floor.active_material.name != "Floor colour"
    surface = geometry.surface_from_object(floor, depsgraph, [], albedo=True)
    np.testing.assert_allclose(surface.albedo, np.tile([0.7, 0.1, 0.2], (9, 1)), rtol=1e-6)


def test_cornell_colour_bleeding_on_the_floor_is_within_10_percent_of_cycles_indirect_light(empty_scene):
    """White floor, red and green walls, the same band-limited light: the bounced light PRT adds to floor vertices
    (interreflected − shadowed, same seed so the direct parts are identical) against Cycles' diffuse indirect
    light alone at those vertices, RMS over the floor relative to the RMS of Cycles' indirect light."""
    from prt_addon.blender import cycles, materials, validation
    from prt_addon.core import lights
    floor, red, green = cornell()
    order, seed, bounces = 3, 5, 3
    direct = SceneBake(bpy.context, BakeSettings(order=order, samples=512, seed=seed), ["Floor"])
    direct.run(log=lambda line: None)
    shadowed, _ = storage.read_transfer(floor.data)
    SceneBake(bpy.context, BakeSettings(mode="interreflected", order=order, samples=512, seed=seed,
                                        bounces=bounces), ["Floor"]).run(log=lambda line: None)
    interreflected, _ = storage.read_transfer(floor.data)
    light = lights.default_light(order)
    albedo = np.tile([0.8, 0.8, 0.8], (len(floor.data.vertices), 1))
    prt_bounced = albedo * (shading.shade(interreflected, light) - shading.shade(shadowed, light))
    albedos = {ob: materials.vertex_albedo(ob, ob.data, []) for ob in (floor, red, green)}
    group = cycles.LightGroup([floor], lobes.reconstruct_equirect(light, *validation.ENVIRONMENT_SIZE), bounces,
                              indirect_only=True)
    reference = cycles.CyclesReference(bpy.context, [group], albedos, samples=256, passes=2)
    while not reference.step():
        pass
    cycles_bounced = np.mean(reference.radiance["Floor"], axis=0)
    positions = np.array([v.co[:] for v in floor.data.vertices])
    near_red = positions[:, 0] > 0.5
    assert cycles_bounced[near_red, 0].mean() > 1.5 * cycles_bounced[near_red, 1].mean()  # Cycles sees red too
    difference = np.linalg.norm(prt_bounced - cycles_bounced, axis=1)
    scale = np.sqrt(np.mean(np.sum(cycles_bounced ** 2, axis=1)))
    relative = np.sqrt(np.mean(difference ** 2)) / scale
    print(f"colour bleeding: PRT vs Cycles indirect, RMS relative difference {relative:.4f}")
    assert relative < 0.10
