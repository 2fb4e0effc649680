"""Ground truth from Cycles (`prt validate` and the panel's button).

Cycles lit by the SH-reconstructed light is what PRT must match up to Monte Carlo noise. Both sides are noisy, so
validation runs Cycles in passes with different seeds and takes Cycles' own noise, measured from their spread, out
of the measured difference: modest Cycles samples then still judge PRT's own error (blender/validation.py).
SH lights are the installed add-on's properties, so validation runs through its modules (`prt`).
"""

import json
import math

import bpy
import numpy as np
import pytest

from conftest import FakeLayout, run_cli
from node_setups import principled_material
from prt_addon.blender import sample_scenes, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import lights, lobes
from prt_addon.core.bake import BakeSettings
from test_bake_blender import add_mesh, box, grid

DEMO_VERTICES = 13_575


def bake(**settings):
    SceneBake(bpy.context, BakeSettings(**settings)).run(log=lambda line: None)


def add_windowed_sun_over_sky(scene):
    """A Hanning-windowed sun over a sky: its reconstruction is nowhere negative, so Cycles sees exactly it."""
    bpy.ops.prt.light_add(kind="SUN")
    sun = scene.prt_lights[-1]
    sun.theta, sun.phi, sun.angular_radius, sun.strength = math.radians(35.0), math.radians(-60.0), 0.2, 2.0
    bpy.ops.prt.light_add(kind="SKY")
    scene.prt_lights[-1].strength = 0.3
    scene.prt_display.window = "hanning"


def validated(prt, samples, passes=4, names=None):
    validation = prt.validation.Validation(bpy.context, samples, passes, names)
    return validation, validation.run(log=lambda line: None)


# -- agreement with Cycles -------------------------------------------------------------------------------------

def test_demo_scene_shadowed_at_default_settings_agrees_with_cycles(empty_scene, prt):
    """The demo scene (torus, floor, two walls: 13,575 vertices) baked at the default settings agrees with Cycles
    under the same light to 2 % relative RMS (RMS over vertices of ‖PRT − Cycles‖ ÷ RMS of ‖Cycles‖).

    The measured difference holds PRT's error and Cycles' noise, which are independent: measured² = PRT² + noise².
    Four Cycles passes of 32 samples with different seeds give the noise of their mean from their spread (per
    vertex the passes' variance ÷ 4); summed over 13,575 vertices that estimate is good to about 1 % of itself, so
    PRT's error is sqrt(measured² − noise²) without a high-sample render, which would take minutes. Measured: PRT
    0.78 % (torus 0.64 %, floor and walls 0.85-1.16 %), Cycles' noise 0.97 %, measured 1.24 %, p99 3.8 % (the
    floor's 5.2 %); with 4 × 128 samples, Cycles' noise 0.32 %, PRT's error is 0.74 %, p99 3.0 %."""
    sample_scenes.build_demo_scene()
    bake()
    add_windowed_sun_over_sky(empty_scene)
    validation, comparisons = validated(prt, samples=32)
    assert validation.scene_light and validation.clamped == {4: 0.0}
    overall = comparisons[-1]
    assert overall.vertices == DEMO_VERTICES
    assert overall.error <= 0.02, validation.lines(comparisons)
    assert all(c.error <= 0.03 for c in comparisons), validation.lines(comparisons)
    assert 0.0 < overall.cycles_noise < overall.measured
    assert overall.error < overall.p99 <= 0.06, validation.lines(comparisons)


def test_unshadowed_sphere_under_a_sun_agrees_with_cycles_to_one_percent(empty_scene, prt):
    """A lone smooth sphere sees its whole upper hemisphere from every vertex, so its unshadowed transfer is exact;
    only the light's band limit and Cycles' noise remain (measured: 0.06 % with 4 × 64 samples)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
    bpy.ops.object.shade_smooth()
    bake(mode="unshadowed")
    add_windowed_sun_over_sky(empty_scene)
    validation, comparisons = validated(prt, samples=64)
    assert comparisons[-1].error <= 0.01, validation.lines(comparisons)
    assert any("unshadowed" in note for note in validation.notes)


def coloured(ob, rgb):
    ob.data.materials.append(principled_material(ob.name, rgb))
    return ob


def test_interreflected_bake_agrees_with_cycles_direct_and_indirect_light(empty_scene, prt):
    """A red wall standing on a grey floor: the light bounced between them is 17 % of what they show (Cycles'
    direct light alone is 17 % off). With Cycles' indirect light and the bake's bounces, they agree: measured
    0.2-0.6 % (Cycles 4 × 16 to 4 × 64 samples)."""
    coloured(grid("Floor", size=2.0, cuts=16), (0.8, 0.8, 0.8))
    ticks = np.linspace(-1.0, 1.0, 17)
    faces = [(r * 17 + c, r * 17 + c + 1, (r + 1) * 17 + c + 1, (r + 1) * 17 + c) for r in range(16) for c in range(16)]
    coloured(add_mesh("Wall", [(-1.0, y, z + 1.0) for z in ticks for y in ticks], faces), (0.9, 0.2, 0.1))
    bake(mode="interreflected", samples=1024)
    validation, comparisons = validated(prt, samples=32)
    (group,) = validation.cycles.groups
    assert group.bounces >= 2
    assert comparisons[-1].error <= 0.02, validation.lines(comparisons)


# -- what validation says and leaves behind ---------------------------------------------------------------------

def scene_state():
    """Everything validation changes while it runs, as plain data."""
    scene, layer = bpy.context.scene, bpy.context.view_layer
    objects = {}
    for ob in scene.objects:
        entry = {"hide_render": ob.hide_render, "selected": ob.select_get(),
                 "slots": [slot.material.name if slot.material else None for slot in ob.material_slots]}
        if ob.type == "MESH":
            attributes = ob.data.color_attributes
            entry["colours"] = ([a.name for a in attributes], attributes.active_color_name,
                                attributes.default_color_name)
            entry["mesh_materials"] = [m.name if m else None for m in ob.data.materials]
        objects[ob.name] = entry
    floor_colours = np.empty(81 * 4, dtype=np.float32)
    bpy.data.meshes["Floor"].color_attributes["prt_color"].data.foreach_get("color", floor_colours)
    return {
        "world": scene.world.name if scene.world else None, "engine": scene.render.engine,
        "cycles": [getattr(scene.cycles, key) for key in
                   ("device", "samples", "seed", "max_bounces", "diffuse_bounces", "sample_clamp_indirect")],
        "bake": [getattr(scene.render.bake, key) for key in
                 ("target", "use_pass_direct", "use_pass_indirect", "use_pass_color", "use_selected_to_active")],
        "active": layer.objects.active.name if layer.objects.active else None,
        "objects": objects, "floor_colours": floor_colours.tolist(),
        "blocks": {kind: sorted(block.name for block in getattr(bpy.data, kind))
                   for kind in ("materials", "images", "worlds", "meshes", "objects", "lights", "curves")},
    }


def assert_same_state(before):
    after = scene_state()
    for key in before:
        if key == "objects":
            for name in before[key]:
                assert after[key][name] == before[key][name], name
        assert after[key] == before[key], key


def test_the_panel_button_validates_stores_the_result_and_restores_the_scene_exactly(empty_scene, prt):
    """A scene with what validation must set aside and put back: the PRT display's materials over an albedo
    material, a mesh without material, a colour attribute of the user's, a lamp, text, a world, Cycles settings."""
    scene = empty_scene
    floor, cube = coloured(grid("Floor"), (0.2, 0.5, 0.7)), box("Box")
    floor.data.color_attributes.new("paint", "BYTE_COLOR", "CORNER")
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    text = bpy.data.objects.new("Label", bpy.data.curves.new("Label", "FONT"))
    for ob in (lamp, text):
        scene.collection.objects.link(ob)
    scene.world = bpy.data.worlds.new("World")
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.cycles.samples, scene.cycles.seed, scene.cycles.sample_clamp_indirect = 7, 5, 4.0
    for ob in bpy.data.objects:
        ob.select_set(ob in (floor, cube))
    bpy.context.view_layer.objects.active = cube
    bake_floor = SceneBake(bpy.context, BakeSettings(samples=16), ["Floor"])
    bake_floor.run(log=lambda line: None)
    bpy.ops.prt.light_add(kind="SKY")
    scene.prt_display.show_prt = True
    bpy.context.view_layer.update()
    before = scene_state()
    assert before["objects"]["Floor"]["slots"] != ["Floor"]  # the display's material stands in
    scene.prt_validate.samples, scene.prt_validate.passes = 2, 2
    assert bpy.ops.prt.validate() == {"FINISHED"}
    assert_same_state(before)
    result = bpy.context.window_manager.prt_validation
    assert [entry.name for entry in result.compared] == ["Floor", "all"]
    assert result.worst_object == "Floor" and len(result.worst_vertices.split(", ")) == 5
    assert all(entry.p99 > 0 for entry in result.compared)
    assert result.cycles_s > 0 and result.light.startswith("Scene light")
    assert "'Box' has no PRT bake" in result.notes  # selected, but nothing to compare
    drawn = []
    bpy.types.PRT_PT_validate.draw(type("Panel", (), {"layout": FakeLayout(drawn)})(), bpy.context)
    assert drawn == ["samples", "passes", "reference"]
    # The bake read its albedo through the display's stand-in; so does validation, from the original material.
    validation = prt.validation.Validation(bpy.context, 1, 2, ["Floor"])
    np.testing.assert_allclose(validation.albedos[floor], np.tile((0.2, 0.5, 0.7), (81, 1)), rtol=1e-6)
    assert_same_state(before)


def test_a_ringing_light_is_measured_and_reported_and_the_default_light_does_not_ring(empty_scene, prt):
    grid("Floor")
    bake(samples=16)
    bpy.ops.prt.light_add(kind="SUN")
    empty_scene.prt_lights[0].angular_radius = 0.0  # a point sun, unwindowed: its reconstruction goes negative
    ringing = prt.validation.Validation(bpy.context, 1, 2)
    assert ringing.clamped[4] > 0.01
    assert any("rings" in note and "Window" in note for note in ringing.notes)
    bpy.ops.prt.light_remove()
    default = prt.validation.Validation(bpy.context, 1, 2)
    assert not default.scene_light and default.clamped == {4: 0.0}
    assert any("default light" in note for note in default.notes)
    for order in range(1, 11):  # every order a bake can have (measured minimum 0.21, at order 10)
        assert lobes.reconstruct_equirect(lights.default_light(order), 64, 128).min() > 0.2


def raise_dc_transfer(mesh, amounts: dict):
    """Adds amounts[v] × the mean DC transfer coefficient to vertex v's: PRT's colour there gains amounts[v] ×
    albedo · L₀ · mean T₀ (about the mean colour) whatever Cycles sees, so these vertices' errors rank as the
    amounts do, far above everything else's."""
    (name, *_) = storage.coefficient_attribute_names(4)
    values = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes[name].data.foreach_get("vector", values)
    values = values.reshape(-1, 3)
    mean_dc = values[:, 0].mean()
    for vertex, amount in amounts.items():
        values[vertex, 0] += amount * mean_dc
    mesh.attributes[name].data.foreach_set("vector", values.ravel())


def test_validate_command_writes_a_line_and_json_and_fails_in_one_line(empty_scene, tmp_path):
    """Five of the floor's vertices have their transfer spoiled by known amounts: the report must name the floor
    as the worst object and list those five, worst first, where they are in the world."""
    floor = grid("Floor")
    floor.location = (0.25, -0.5, 0.0)  # world positions differ from the mesh's
    box("Cube")
    path, report = tmp_path / "baked.blend", tmp_path / "validation.json"
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "unbaked.blend"))
    bake(samples=32)
    spoiled = {40: 5.0, 12: 4.0, 66: 3.0, 8: 2.0, 77: 1.0}  # 40, under the cube, the worst
    raise_dc_transfer(floor.data, spoiled)
    ground = grid("Ground")  # saved selected and unbaked: validating the file's bakes passes over it
    ground.hide_render = True
    for ob in bpy.data.objects:
        ob.select_set(ob is ground)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    result = run_cli("validate", path, "--samples", 4, "--passes", 2, "--report", report)
    assert result.returncode == 0, result.stderr
    assert "left" in result.stdout and "PRT validate: 2 objects, 89 vertices vs Cycles (2 × 4 samples)" in result.stdout
    assert "default light" in result.stderr  # the file has no SH lights
    data = json.loads(report.read_text())
    assert data["objects"] == ["Floor", "Cube"] and data["vertices"] == 89
    assert data["light"]["source"] == "default" and data["light"]["clamped_fraction"] == {"4": 0.0}
    assert data["cycles"]["passes"] == 2 and data["cycles"]["time_s"] > 0 and data["prt"]["bake_time_s"] > 0
    for name in ("Floor", "Cube"):
        assert set(data["per_object"][name]) >= {"rel_rms_error", "measured_rel_rms", "cycles_noise_rel_rms",
                                                 "rel_p99_error", "measured_rel_p99", "rel_max_difference",
                                                 "est_rms_rel_error", "bake_time_s"}
    assert 0.0 < data["rel_p99_error"] <= data["measured_rel_p99"] <= data["rel_max_difference"]
    worst, floor_errors = data["worst"], data["per_object"]["Floor"]
    assert worst["object"] == "Floor" and [v["index"] for v in worst["vertices"]] == list(spoiled)
    errors = [v["rel_error"] for v in worst["vertices"]]
    # The worst vertex's error, Cycles' noise taken out, is the floor's largest difference less a little noise.
    assert 0.9 * floor_errors["rel_max_difference"] <= errors[0] <= floor_errors["rel_max_difference"]
    # 81 vertices: numpy's linear 99th percentile lies at rank 0.99 × 80 = 79.2, between the two worst.
    assert floor_errors["rel_p99_error"] == pytest.approx(0.8 * errors[1] + 0.2 * errors[0], rel=1e-9)
    corners = np.array([v.co for v in floor.data.vertices])[list(spoiled)] + np.array(floor.location)
    np.testing.assert_allclose([v["position"] for v in worst["vertices"]], corners, atol=1e-6)
    assert f"  worst: Floor, p99 {100 * floor_errors['rel_p99_error']:.1f} %; vertices 40 (" in result.stdout
    assert "; vertex 40 at (0.25, -0.50, 0.00)" in result.stdout
    for args, words in (((tmp_path / "unbaked.blend",), "nothing to validate"),
                        ((path, "--passes", 1), "passes must be at least 2")):
        failed = run_cli("validate", *args)
        assert failed.returncode == 1
        lines = [line for line in failed.stderr.splitlines() if line.startswith("prt:")]
        assert len(lines) == 1 and words in lines[0], failed.stderr


# -- error against run time --------------------------------------------------------------------------------------
