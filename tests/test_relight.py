"""Relighting in Blender: SH lights, the depsgraph handler, display materials, renders and `prt relight`.

Property groups and handlers belong to the installed add-on, so its modules are used where identity matters;
the checkout's `prt_addon` builds scenes, bakes and gives the reference maths.
"""

import math

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from conftest import FakeLayout, add_light, run_cli
from equirect import equirect_directions
from node_setups import environment_world, principled_material
from prt_addon.blender import sample_scenes, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, lobes, shading

ORDER = 4
POINT_SUN_PEAK = 17 / 16  # Σ_l Â_l(2l+1)/(4π) at order 4: a point sun overhead gives 17/16 · E/π
SMALL = (96, 72)


def update():
    bpy.context.view_layer.update()


def bake_scene(samples=16):
    SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="shadowed", samples=samples)).run(
        log=lambda line: None)


@pytest.fixture
def plane(empty_scene):
    """A 5 × 5 vertex grid facing +Z with nothing above it: every vertex is baked exactly, without rays. No window
    (the default is Auto), so the colours are the band-limited sums themselves."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2)
    bake_scene()
    empty_scene.prt_display.window = "none"
    return bpy.context.object


@pytest.fixture(scope="module")
def demo_blend(addon, tmp_path_factory):
    """The demo scene (torus over a floor and two walls), baked once for the module."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sample_scenes.build_demo_scene()
    bake_scene(samples=32)
    path = str(tmp_path_factory.mktemp("demo") / "demo_baked.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    return path


@pytest.fixture
def demo(empty_scene, demo_blend):
    bpy.ops.wm.open_mainfile(filepath=demo_blend)
    bpy.context.scene.prt_display.window = "none"  # the band-limited sums themselves (the default is Auto)
    return bpy.context.scene


def colours(mesh) -> np.ndarray:
    values = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["prt_color"].data.foreach_get("color", values)
    return values.reshape(-1, 4)


def sun_light(theta, phi, radius, strength):
    return strength * shading.sun_coefficients(ORDER, shading.direction_from_angles(theta, phi), radius)


def expected_colours(mesh, light):
    transfer, _ = storage.read_transfer(mesh)
    return np.maximum(transfer.astype(np.float64) @ light, 0.0)


# -- values ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("strength", [1.0, 2.5])
def test_sun_straight_above_an_unoccluded_upward_vertex_gives_e_over_pi(plane, strength):
    add_light(theta=0.0, angular_radius=0.0, strength=strength)
    update()
    rgba = colours(plane.data)
    np.testing.assert_allclose(rgba[:, :3], strength / math.pi * POINT_SUN_PEAK, rtol=1e-6)
    np.testing.assert_array_equal(rgba[:, 3], 1.0)


def test_relighting_a_moved_sun_equals_lighting_with_it_from_scratch(demo):
    sun = add_light(theta=0.3, phi=0.2, angular_radius=0.05, strength=2.0)
    add_light("SKY", strength=0.15)
    update()
    sun.theta, sun.phi = 1.1, -2.4
    update()
    light = sun_light(1.1, -2.4, 0.05, 2.0) + lobes.constant_sky(ORDER, 0.15)
    for name in ("Torus", "Floor", "BackWall", "LeftWall"):
        mesh = bpy.data.meshes[name]
        np.testing.assert_allclose(colours(mesh)[:, :3], np.tile(expected_colours(mesh, light)[:, None], (1, 3)),
                                   atol=1e-6, err_msg=name)


def equirect_image(name, pixels):
    height, width = pixels.shape[:2]
    image = bpy.data.images.new(name, width, height, float_buffer=True)
    rgba = np.concatenate([pixels, np.ones((height, width, 1))], axis=2).astype(np.float32)
    image.pixels.foreach_set(rgba.ravel())
    return image


def test_turned_environment_equals_projecting_the_turned_image(plane):
    plane.rotation_euler.x = 1.0  # tilted: an upward plane would see the same under any turn about Z
    update()
    bake_scene()
    directions = equirect_directions(32, 64)
    pixels = np.stack([1 + directions[..., 0], 1 + 0.5 * directions[..., 1], 1 + 0.7 * directions[..., 2]], -1)
    shift = 5  # pixel columns: the turned image is exactly the shifted one
    environment = add_light("ENVIRONMENT", image=equirect_image("Env", pixels),
                            rotation=(0.0, 0.0, 2 * math.pi * shift / 64))
    update()
    turned = colours(plane.data).copy()
    environment.image = equirect_image("Shifted", np.roll(pixels, -shift, axis=1))
    environment.rotation = (0.0, 0.0, 0.0)
    update()
    np.testing.assert_allclose(colours(plane.data), turned, atol=1e-6)
    environment.image = bpy.data.images["Env"]
    update()
    assert np.abs(colours(plane.data) - turned).max() > 0.01  # unturned, the same image lights differently


def test_environment_defaults_to_the_worlds_environment_texture(plane):
    world, texture = environment_world("World")
    bpy.context.scene.world = world
    directions = equirect_directions(16, 32)
    texture.image = equirect_image("Sky", np.repeat(0.5 + 0.5 * directions[..., 2:], 3, axis=2))
    add_light("ENVIRONMENT")
    update()
    from_world = colours(plane.data).copy()
    assert from_world[:, :3].min() > 0.5  # brighter above: the upward plane sees more than the average
    bpy.context.scene.prt_lights[0].image = texture.image
    update()
    np.testing.assert_allclose(colours(plane.data), from_world, atol=1e-7)


def test_light_follows_a_sun_object_and_its_angle(plane):
    sun_object = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    bpy.context.scene.collection.objects.link(sun_object)
    sun_object.data.angle = 0.4
    add_light(sun_object=sun_object, strength=3.0)
    sun_object.rotation_euler = (0.7, 0.0, 1.9)
    update()
    towards = sun_object.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    light = 3.0 * shading.sun_coefficients(ORDER, towards, 0.2)
    np.testing.assert_allclose(colours(plane.data)[:, 0], expected_colours(plane.data, light), atol=1e-6)


def test_a_driver_makes_a_light_follow_another_object(plane):
    target = bpy.data.objects.new("Target", None)
    bpy.context.scene.collection.objects.link(target)
    add_light(angular_radius=0.1)
    driver = bpy.context.scene.driver_add("prt_lights[0].theta").driver
    variable = driver.variables.new()
    variable.type = "TRANSFORMS"
    variable.targets[0].id = target
    variable.targets[0].transform_type = "LOC_X"
    driver.expression = variable.name
    target.location.x = 0.9
    update()
    np.testing.assert_allclose(colours(plane.data)[:, 0],
                               expected_colours(plane.data, sun_light(0.9, bpy.context.scene.prt_lights[0].phi,
                                                                      0.1, 1.0)), atol=1e-6)


def test_window_is_applied_to_the_sum(plane):
    add_light(theta=0.0, angular_radius=0.0)
    bpy.context.scene.prt_display.window = "hanning"
    update()
    light = lobes.apply_window(sun_light(0.0, 0.0, 0.0, 1.0), lobes.window(ORDER, "hanning"))
    np.testing.assert_allclose(colours(plane.data)[:, 0], expected_colours(plane.data, light), atol=1e-6)


# -- the handler ----------------------------------------------------------------------------------------------

@pytest.fixture
def counted(prt, monkeypatch):
    """Counts of the handler's refreshes and of colour writes, from now on."""
    counts = {"refresh": 0, "write": 0}
    engine = prt.handlers.engine
    refresh, write = engine.refresh, prt.display.write_display_colours

    def counting_refresh(*args):
        counts["refresh"] += 1
        return refresh(*args)

    def counting_write(*args):
        counts["write"] += 1
        return write(*args)

    monkeypatch.setattr(engine, "refresh", counting_refresh)
    monkeypatch.setattr(prt.display, "write_display_colours", counting_write)

    def taken():
        now = dict(counts)
        counts.update(refresh=0, write=0)
        return now
    return taken


def test_handler_runs_once_per_light_change_and_not_for_its_own_writes(plane, prt, counted):
    update()  # the bake's own update
    counted()
    light = add_light()  # operators end with an evaluation, which runs the handler
    update()
    assert counted() == {"refresh": 1, "write": 1}
    light.theta = 0.7
    update()
    assert counted() == {"refresh": 1, "write": 1}
    update()
    assert counted() == {"refresh": 0, "write": 0}
    # A write outside the handler is reported by the next evaluation: it is ours, so it is ignored.
    prt.display.write_display_colours(plane.data, *[np.zeros((25, 16), np.float32), np.zeros((3, 16))])
    counted()
    update()
    assert counted() == {"refresh": 0, "write": 0}


def test_handler_ignores_what_does_not_light(plane, counted):
    add_light()
    update()
    counted()
    bpy.context.scene.render.resolution_x = 123  # the scene changed, the light did not: looked at, not redone
    update()
    assert counted()["write"] == 0
    other = bpy.data.objects.new("Other", None)
    bpy.context.scene.collection.objects.link(other)
    update()
    counted()
    other.location.x = 3.0  # an object no light follows
    update()
    assert counted() == {"refresh": 0, "write": 0}
    bpy.context.scene.frame_set(7)  # nothing is animated
    assert counted()["write"] == 0


def test_handler_relights_a_rebaked_mesh(plane, counted):
    add_light()
    update()
    counted()
    bpy.context.object.data.update()  # a geometry update that leaves the bake as it was: nothing to do
    update()
    assert counted()["write"] == 0
    bake_scene()
    update()
    assert counted() == {"refresh": 1, "write": 1}


def test_keyframed_light_relights_every_frame_and_renders_differ(plane, prt, tmp_path, counted):
    scene = bpy.context.scene
    light = add_light(theta=0.0)
    light.keyframe_insert("theta", frame=1)
    light.theta = math.radians(70)
    light.keyframe_insert("theta", frame=3)
    scene.frame_set(2)
    assert counted()["write"] == 1
    np.testing.assert_allclose(colours(plane.data)[:, 0],
                               expected_colours(plane.data, sun_light(light.theta, light.phi, light.angular_radius,
                                                                      1.0)), atol=1e-6)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, 3.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.frame_start, scene.frame_end = 1, 3
    prt.render.render(scene, str(tmp_path / "still.png"), "WORKBENCH", resolution=(32, 24))
    scene.render.filepath = str(tmp_path / "frame_")
    bpy.ops.render.render(animation=True)
    centre = [read_png(str(tmp_path / f"frame_{frame:04d}.png"))[12, 16, 0] for frame in (1, 2, 3)]
    assert centre[0] > centre[1] + 0.05 > centre[2] + 0.1, centre


def test_handlers_survive_saving_and_reloading(plane, prt, tmp_path):
    add_light(theta=0.2)
    update()
    path = str(tmp_path / "relit.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert prt.handlers.on_depsgraph_update in bpy.app.handlers.depsgraph_update_post
    assert prt.handlers.on_frame_change in bpy.app.handlers.frame_change_post
    scene = bpy.context.scene
    scene.prt_lights[0].theta = 1.0
    update()
    mesh = scene.objects["Grid"].data
    light = sun_light(1.0, scene.prt_lights[0].phi, scene.prt_lights[0].angular_radius, 1.0)
    np.testing.assert_allclose(colours(mesh)[:, 0], expected_colours(mesh, light), atol=1e-6)


def test_stale_bake_is_reported_once_and_never_applied(plane, capsys):
    mesh = plane.data
    mesh.vertices.add(1)
    mesh.update()
    light = add_light()
    update()
    light.theta = 1.2
    update()
    assert "prt_color" not in mesh.color_attributes
    printed = capsys.readouterr().out
    assert printed.count("PRT: not relighting") == 1 and "'Grid'" in printed, printed


def test_no_lights_no_colours(plane):
    bpy.context.scene.prt_display.window = "lanczos"
    update()
    assert "prt_color" not in plane.data.color_attributes


# -- display --------------------------------------------------------------------------------------------------

def material_names(ob):
    return [slot.material.name if slot.material else None for slot in ob.material_slots]


def test_display_materials_replace_and_restore_the_originals(plane, prt):
    own = bpy.data.materials.new("Own")
    plane.data.materials.append(own)
    bare = bpy.data.objects.new("Bare", plane.data.copy())
    bpy.context.scene.collection.objects.link(bare)
    bare.data.materials.clear()
    add_light()
    display = bpy.context.scene.prt_display
    display.show_prt = True
    update()
    for ob in (plane, bare):
        assert [prt.display.DISPLAY_OF_KEY in slot.material for slot in ob.material_slots] == [True], ob.name
    display.show_prt = False
    update()
    assert material_names(plane) == ["Own"]
    assert material_names(bare) == []
    assert not [m.name for m in bpy.data.materials if prt.display.DISPLAY_OF_KEY in m]


def show_and_reopen(plane, tmp_path, own):
    """The plane showing the PRT display in place of `own`, saved and opened again; the reopened plane."""
    plane.data.materials.append(own)
    add_light()
    bpy.context.scene.prt_display.show_prt = True
    update()
    assert material_names(plane) != [own.name]
    path = str(tmp_path / "shown.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    return bpy.data.objects["Grid"]


def test_the_originals_survive_saving_while_the_display_shows_and_come_back(plane, prt, tmp_path):
    own = bpy.data.materials.new("Own")
    own.diffuse_color = (0.25, 0.5, 0.75, 1.0)
    plane = show_and_reopen(plane, tmp_path, own)
    assert "Own" in bpy.data.materials and tuple(bpy.data.materials["Own"].diffuse_color) == (0.25, 0.5, 0.75, 1.0)
    assert prt.materials.original_materials(plane) == [bpy.data.materials["Own"]]
    bpy.context.scene.prt_display.show_prt = False
    update()
    assert material_names(plane) == ["Own"]
    assert not [m.name for m in bpy.data.materials if prt.display.DISPLAY_OF_KEY in m]


def test_clearing_the_bake_of_a_saved_shown_file_brings_the_originals_back(plane, tmp_path):
    plane = show_and_reopen(plane, tmp_path, bpy.data.materials.new("Own"))
    for ob in bpy.context.scene.objects:
        ob.select_set(ob == plane)
    bpy.context.view_layer.objects.active = plane
    assert bpy.ops.prt.clear() == {"FINISHED"}
    update()
    assert material_names(plane) == ["Own"]


def test_a_file_that_lost_the_originals_gets_a_note_not_a_crash(plane, prt, tmp_path, capsys):
    """A file whose record names a material it does not hold (a record of names keeps no material in the file):
    the export warns, naming object and material; the display goes off with the same note, that slot left empty; a
    record naming a material the file holds brings it back."""
    plane.data.materials.append(bpy.data.materials.new("Own"))
    bare = bpy.data.objects.new("Kept", plane.data.copy())
    bpy.context.scene.collection.objects.link(bare)
    bare.data.materials[0] = bpy.data.materials.new("Kept material")
    bare.data.materials[0].use_fake_user = True
    add_light()
    bpy.context.scene.prt_display.show_prt = True
    update()
    plane[prt.materials.ORIGINALS_KEY] = ["Own"]  # names, not references: nothing keeps "Own" in the file
    bare[prt.materials.ORIGINALS_KEY] = ["Kept material"]
    path = tmp_path / "lost.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert "Own" not in bpy.data.materials
    exported = run_cli("export", path, "--gltf", tmp_path / "lost.glb")
    assert exported.returncode == 0, exported.stderr
    assert exported.stderr.count("prt: warning: 'Grid': the PRT display stands in for material 'Own', which is not "
                                 "in this file") == 1, exported.stderr
    assert "'Kept'" not in exported.stderr
    capsys.readouterr()
    bpy.context.scene.prt_display.show_prt = False
    update()
    assert material_names(bpy.data.objects["Grid"]) == [None]
    assert material_names(bpy.data.objects["Kept"]) == ["Kept material"]
    printed = capsys.readouterr().out
    assert printed.count("'Grid': the PRT display stands in for material 'Own', which is not in this file") == 1


def test_disabling_the_addon_restores_the_originals(plane, addon):
    plane.data.materials.append(bpy.data.materials.new("Own"))
    add_light()
    bpy.context.scene.prt_display.show_prt = True
    update()
    assert material_names(plane) != ["Own"]
    bpy.ops.preferences.addon_disable(module=addon)
    try:
        assert material_names(plane) == ["Own"]
    finally:
        bpy.ops.preferences.addon_enable(module=addon)


def test_display_material_takes_the_base_color_texture_and_the_albedo_switch(demo, prt):
    add_light()
    demo.prt_display.show_prt = True
    update()
    material = bpy.data.objects["Torus"].material_slots[0].material
    textures = [node.image for node in material.node_tree.nodes if node.type == "TEX_IMAGE"]
    assert textures == [bpy.data.images["Albedo"]]
    uv_maps = [node.uv_map for node in material.node_tree.nodes if node.type == "UVMAP"]
    assert uv_maps == ["UVMap"]
    switch = material.node_tree.nodes[prt.display.ALBEDO_MIX].inputs[0]
    assert switch.default_value == 1.0
    demo.prt_display.use_albedo = False
    update()
    assert switch.default_value == 0.0


# -- renders --------------------------------------------------------------------------------------------------

def read_png(path) -> np.ndarray:
    """(H, W, 4) values as stored (sRGB-encoded), row 0 at the bottom."""
    image = bpy.data.images.load(path)
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    shape = (image.size[1], image.size[0], 4)
    bpy.data.images.remove(image)
    return pixels.reshape(shape)


def floor_samples(scene, towards_sun):
    """Pixel positions of floor vertices the camera sees, split into those the torus shadows and the others."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    floor = scene.objects["Floor"]
    camera = scene.camera.matrix_world.translation
    shadowed, lit = [], []
    for vertex in floor.data.vertices:
        point = floor.matrix_world @ vertex.co
        to_point = point - camera
        hit, location, *_ = scene.ray_cast(depsgraph, camera, to_point.normalized())
        if not hit or (location - point).length > 1e-3:
            continue  # hidden behind the torus or a wall
        x, y, _ = world_to_camera_view(scene, scene.camera, point)
        blocked, _, _, _, blocker, _ = scene.ray_cast(depsgraph, point + Vector((0, 0, 1e-4)), Vector(towards_sun))
        if not blocked:
            lit.append((y, x))
        elif blocker.name == "Torus":
            shadowed.append((y, x))
    return np.array(shadowed), np.array(lit)


def mean_at(image, samples):
    """Mean linear value of the pixels at samples (row, column fractions)."""
    rows = np.clip((samples[:, 0] * image.shape[0]).astype(int), 0, image.shape[0] - 1)
    columns = np.clip((samples[:, 1] * image.shape[1]).astype(int), 0, image.shape[1] - 1)
    return srgb_to_linear(image[rows, columns, :3]).mean()


def test_render_is_darker_in_the_torus_shadow_and_the_shadow_moves_with_the_sun(demo, prt, tmp_path):
    sun = add_light(angular_radius=0.02, strength=2.0)
    images, samples = [], []
    for theta, phi in ((50.0, 120.0), (50.0, 20.0)):  # shadows thrown to the front right, then front left
        sun.theta, sun.phi = math.radians(theta), math.radians(phi)
        update()
        path = str(tmp_path / f"sun_{phi:.0f}.png")
        prt.render.render(demo, path, "WORKBENCH", resolution=(160, 120))
        images.append(read_png(path))
        samples.append(floor_samples(demo, shading.direction_from_angles(sun.theta, sun.phi)))
    for image, (shadowed, lit) in zip(images, samples):
        assert len(shadowed) > 20 and len(lit) > 100
        assert mean_at(image, shadowed) < 0.75 * mean_at(image, lit)  # measured here: 0.57 and 0.51
    # Where the first sun's shadow fell, the second sun's render is brighter: the shadow moved (measured: 2.8×).
    first_shadow = samples[0][0]
    assert mean_at(images[1], first_shadow) > 1.5 * mean_at(images[0], first_shadow)


def srgb_to_linear(value):
    return np.where(value <= 0.04045, value / 12.92, ((value + 0.055) / 1.055) ** 2.4)


def test_eevee_render_shows_prt_colour_times_albedo_texture(plane, prt, tmp_path):
    """One EEVEE render (slow headless): a plane with a uniform albedo texture under a sun overhead."""
    albedo = (0.25, 0.5, 0.75)
    image = bpy.data.images.new("Albedo", 8, 8, float_buffer=True)  # linear: the albedo as written
    image.pixels.foreach_set(np.tile([*albedo, 1.0], 64).astype(np.float32))
    plane.data.materials.append(principled_material("Textured", texture=image))
    add_light(theta=0.0, angular_radius=0.0, strength=1.5)
    scene = bpy.context.scene
    scene.prt_display.show_prt = True
    update()
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    path = str(tmp_path / "eevee.png")
    prt.render.render(scene, path, "EEVEE", samples=1, resolution=SMALL)
    centre = srgb_to_linear(read_png(path)[SMALL[1] // 2, SMALL[0] // 2, :3])
    expected = np.array(albedo) * 1.5 / math.pi * POINT_SUN_PEAK
    np.testing.assert_allclose(centre, expected, atol=0.01)


# -- command line ---------------------------------------------------------------------------------------------

def test_relight_command_renders_a_baked_file_under_a_moved_sun(demo, tmp_path):
    add_light(theta=0.5)
    path = str(tmp_path / "lit.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    out = tmp_path / "relit.png"
    result = run_cli("relight", path, "--light-theta", 40, "--light-phi", 120, "--engine", "WORKBENCH",
                     "--resolution", "96x72", "--render", out)
    assert result.returncode == 0, result.stderr
    assert "θ 40.0°, φ 120.0°" in result.stdout
    assert read_png(str(out)).shape == (72, 96, 4)
    bad = run_cli("relight", path, "--light", 3, "--light-theta", 10, "--render", out)
    assert bad.returncode == 1
    assert bad.stderr.strip().count("\n") == 0 and "no SH light 3" in bad.stderr


def test_relight_command_refuses_a_file_without_lights(demo_blend, tmp_path):
    result = run_cli("relight", demo_blend, "--render", tmp_path / "out.png")
    assert result.returncode == 1 and "no SH lights" in result.stderr


# -- interface ------------------------------------------------------------------------------------------------

def test_overlays_are_absent_in_background_and_their_lines_are_right(plane, prt):
    assert bpy.app.background and prt.overlays._handle is None
    segments = prt.overlays.normal_segments(plane).reshape(-1, 2, 3)
    positions = np.array([plane.matrix_world @ v.co for v in plane.data.vertices])
    np.testing.assert_allclose(segments[:, 0], positions, atol=1e-6)
    offsets = segments[:, 1] - segments[:, 0]
    np.testing.assert_allclose(offsets[:, :2], 0.0, atol=1e-6)
    assert (offsets[:, 2] > 0).all()
    add_light(theta=0.6, phi=1.0, colour=(1.0, 0.5, 0.0))
    lines, line_colours = prt.overlays.light_segments(bpy.context.scene, (1.0, 2.0, 3.0))
    np.testing.assert_allclose(lines[0], (1.0, 2.0, 3.0))
    direction = (lines[1] - lines[0]) / np.linalg.norm(lines[1] - lines[0])
    np.testing.assert_allclose(direction, shading.direction_from_angles(0.6, 1.0), atol=1e-6)
    np.testing.assert_allclose(line_colours[:, :3], [[1.0, 0.5, 0.0]] * 2)


@pytest.mark.parametrize("kind", ["SUN", "ENVIRONMENT", "SKY"])
def test_panels_draw_the_active_light_and_the_switches(empty_scene, kind):
    add_light(kind)
    drawn = []
    for panel in (bpy.types.PRT_PT_lights, bpy.types.PRT_PT_display):
        stand_in = type("Panel", (), {"layout": FakeLayout(drawn), "_draw_light": panel.__dict__.get("_draw_light")})
        panel.draw(stand_in(), bpy.context)
    expected = {"SUN": {"sun_object", "theta", "phi", "angular_radius"}, "ENVIRONMENT": {"image", "rotation"},
                "SKY": set()}[kind]
    assert expected | {"kind", "colour", "strength", "show_prt", "use_albedo", "window"} <= set(drawn)


def test_light_add_and_remove_keep_the_active_light_valid(empty_scene):
    scene = empty_scene
    for kind in ("SUN", "SKY", "ENVIRONMENT"):
        bpy.ops.prt.light_add(kind=kind)
    assert [light.kind for light in scene.prt_lights] == ["SUN", "SKY", "ENVIRONMENT"]
    assert scene.prt_active_light == 2
    bpy.ops.prt.light_remove()
    assert scene.prt_active_light == 1 and len(scene.prt_lights) == 2
    scene.prt_active_light = 0
    bpy.ops.prt.light_remove()
    assert [light.name for light in scene.prt_lights] == ["Sky"]
    bpy.ops.prt.light_remove()
    assert not bpy.ops.prt.light_remove.poll()
