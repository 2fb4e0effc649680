"""Dynamic objects: baked in their own frame against themselves only, relit by turning the SH lights into that frame
as they move, never stale for moving, and checked for what the display cannot follow.

Truth: a convex object shadows nothing of itself, so its transfer is the clamped-cosine lobe and under a point sun
its shaded value at a vertex of world normal n is the band-limited lobe in closed form,
(E/π) Σ_l Â_l (2l+1)/(4π) P_l(d·n), whatever the object's rotation. A non-convex one (a torus) turned after its bake
is compared with the same torus baked statically at that turn, alone: the two agree within their bakes' noise.
"""

import json
import math

import bpy
import numpy as np
import pytest
from mathutils import Euler, Matrix

from conftest import add_light, run_cli
from prt_addon.blender import checks as scene_checks
from prt_addon.blender import fingerprint, storage
from prt_addon.blender.plan import plan_bake
from prt_addon.blender.relighting import light_in_frame
from prt_addon.blender.request import read_request
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, checks
from prt_addon.core.checks import ERROR, WARNING
from prt_addon.core.executors import InProcess
from prt_addon.core.progress import format_duration
from prt_addon.core.statistics import compare
from prt_addon.core.shading import direction_from_angles, sun_coefficients
from test_heatmaps import labels_drawn

ORDER = 4
SUN = (0.6, 2.2, 3.0)  # θ, φ, strength of a point sun
TURNS = [(0.0, 0.0, 0.0), (0.9, 0.0, 0.0), (0.0, 1.3, 0.4), (2.5, -0.7, 1.9), (math.pi, 0.3, -2.2)]
A_HAT = (math.pi, 2 * math.pi / 3, math.pi / 4, 0.0)  # Â_l of the clamped cosine, l < 4


def update():
    bpy.context.view_layer.update()


def bake_now(names=None, samples=64, mode="shadowed", seed=0):
    job = SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode=mode, samples=samples, seed=seed), names)
    job.run(log=lambda line: None)
    return job


def colours(mesh) -> np.ndarray:
    values = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["prt_color"].data.foreach_get("color", values)
    return values.reshape(-1, 4)[:, :3]


def world_normals(ob) -> np.ndarray:
    normals = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertices.foreach_get("normal", normals)
    turned = normals.reshape(-1, 3) @ np.array(ob.matrix_world.to_3x3()).T
    return turned / np.linalg.norm(turned, axis=1, keepdims=True)


def point_sun_shading(normals, direction, strength) -> np.ndarray:
    """The order-4 band-limited clamped cosine of a point sun, by Legendre polynomials (the SH addition theorem)."""
    c = normals @ np.asarray(direction)
    legendre = (np.ones_like(c), c, 0.5 * (3 * c * c - 1), 0.5 * (5 * c ** 3 - 3 * c))
    return np.maximum(strength / math.pi * sum(a * (2 * l + 1) / (4 * math.pi) * p
                                               for l, (a, p) in enumerate(zip(A_HAT, legendre))), 0.0)


@pytest.fixture
def sphere_over_floor(empty_scene):
    """A dynamic sphere resting just above a static floor that would shadow its lower half, and a sun."""
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 0))
    floor = bpy.context.object
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=1.0, location=(0, 0, 1.05))
    sphere = bpy.context.object
    bpy.ops.object.shade_smooth()
    sphere.prt_dynamic = True
    bpy.ops.object.select_all(action="DESELECT")
    empty_scene.prt_display.window = "none"
    return sphere, floor


def test_a_convex_dynamic_object_shows_the_closed_form_cosine_lobe_at_every_turn(sphere_over_floor):
    sphere, floor = sphere_over_floor
    bake_now()
    assert storage.read_transfer(sphere.data)[1][storage.DYNAMIC_KEY] is True
    assert storage.DYNAMIC_KEY not in floor.data["prt"]
    theta, phi, strength = SUN
    add_light(theta=theta, phi=phi, strength=strength, angular_radius=0.0)
    sun = direction_from_angles(theta, phi)
    for turn in TURNS:
        sphere.rotation_euler = turn
        sphere.location = (turn[0], -turn[1], 1.05 + turn[2])  # moving changes nothing
        sphere.scale = (1.7,) * 3                               # nor does a uniform scale
        update()
        expected = point_sun_shading(world_normals(sphere), sun, strength)
        np.testing.assert_allclose(colours(sphere.data), np.repeat(expected[:, None], 3, 1), rtol=0, atol=2e-6)


def test_the_static_floor_is_not_shadowed_by_the_dynamic_object(sphere_over_floor):
    """Dynamic objects cast no shadow on the static scene: under the sphere the floor sees the whole sky."""
    sphere, floor = sphere_over_floor
    bake_now()
    transfer, _ = storage.read_transfer(floor.data)
    upward = np.array([A_HAT[0] / math.pi * 0.5 / math.sqrt(math.pi), 0.0, A_HAT[1] / math.pi *
                       math.sqrt(3 / (4 * math.pi)), 0.0])  # Â_l/π · Y_lm(+Z), bands 0 and 1
    np.testing.assert_allclose(transfer[:, :4], np.broadcast_to(upward, (len(transfer), 4)), atol=1e-6)


def test_a_turned_torus_matches_a_static_bake_of_it_at_that_turn(empty_scene):
    """Baked once at rest then turned, against baked statically, alone, at each turn: within their noise; not
    turning the light would be far off."""
    bpy.ops.mesh.primitive_torus_add(major_segments=32, minor_segments=12, major_radius=1.0, minor_radius=0.45)
    torus = bpy.context.object
    torus.prt_dynamic = True
    dynamic = bake_now(["Torus"], samples=512)
    # Baked to the order its probes carry light to; under the distant light alone its higher coefficients are unlit.
    transfer = storage.read_transfer(torus.data)[0].astype(np.float64)[:, :ORDER ** 2]
    sigma = dynamic.results.results[0].std_error
    theta, phi, strength = SUN
    light = strength * sun_coefficients(ORDER, direction_from_angles(theta, phi), 0.05)
    for turn in TURNS[1:]:
        matrix = Euler(turn).to_matrix().to_4x4()
        shown = transfer @ light_in_frame(light, matrix)
        unturned = transfer @ light
        torus.prt_dynamic = False
        torus.matrix_world = matrix
        static = bake_now(["Torus"], samples=512, seed=1)
        reference = storage.read_transfer(torus.data)[0].astype(np.float64) @ light
        noise = np.linalg.norm(light) * np.hypot(sigma, static.results.results[0].std_error)
        difference = np.abs(shown - reference)
        assert np.sqrt(np.mean(difference ** 2)) <= np.sqrt(np.mean(noise ** 2))
        assert np.sqrt(np.mean((unturned - reference) ** 2)) > 10 * np.sqrt(np.mean(noise ** 2))
        torus.matrix_world = Matrix.Identity(4)
        torus.prt_dynamic = True
        bake_now(["Torus"], samples=512)


def test_a_dynamic_bake_is_the_same_bits_at_any_placement(empty_scene):
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.object
    monkey.prt_dynamic = True
    bake_now(["Suzanne"], samples=32)
    first = storage.read_transfer(monkey.data)[0].copy()
    monkey.rotation_euler = (0.4, 1.1, -2.0)
    monkey.location = (3.0, -1.0, 2.0)
    bake_now(["Suzanne"], samples=32)
    assert np.array_equal(storage.read_transfer(monkey.data)[0], first)


def test_moving_a_dynamic_object_leaves_it_and_the_static_scene_up_to_date(sphere_over_floor):
    sphere, floor = sphere_over_floor
    bake_now()
    settings = bake.BakeSettings(order=ORDER, mode="shadowed", samples=64)
    sphere.rotation_euler = (0.3, 0.2, 1.0)
    sphere.location.x += 0.5
    assert fingerprint.stale_receivers(bpy.context, settings) == {"Plane": [], "Sphere": []}
    sphere.data.vertices[0].co.z += 0.1
    sphere.data.update()
    assert fingerprint.stale_receivers(bpy.context, settings, ["Sphere"]) == {"Sphere": ["geometry changed"]}
    sphere.prt_dynamic = False
    assert "settings changed" in fingerprint.stale_receivers(bpy.context, settings, ["Sphere"])["Sphere"]


def checks_of(names):
    plan = plan_bake(read_request(bpy.context, bake.BakeSettings(order=ORDER, samples=16), names))
    return scene_checks.scene_checks(bpy.context, plan, InProcess())


def test_non_uniform_scale_is_an_error_and_a_deforming_modifier_a_warning(sphere_over_floor):
    sphere, _ = sphere_over_floor
    sphere.scale = (1.0, 2.0, 1.0)
    update()
    found = [check for check in checks_of(["Sphere"]) if check.subject == "'Sphere'"]
    assert [check.level for check in found if "non-uniform scale" in check.text] == [ERROR]
    sphere.scale = (2.0, 2.0, 2.0)
    sphere.modifiers.new("Bend", "SIMPLE_DEFORM")
    update()
    found = [check for check in checks_of(["Sphere"]) if check.subject == "'Sphere'"]
    assert not any(check.level == ERROR for check in found)
    assert [check.level for check in found if "deformed (Bend)" in check.text] == [WARNING]


def test_the_command_line_marks_receivers_dynamic_and_saves_it(empty_scene, tmp_path):
    bpy.ops.mesh.primitive_plane_add(size=6)
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1.2))
    path = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    report = tmp_path / "report.json"
    result = run_cli("bake", path, "--object", "Suzanne", "--dynamic", "--samples", "16", "--workers", "1",
                     "--report", report)
    assert result.returncode == 0, result.stderr
    assert "; 1 dynamic object, each baked in its own frame against itself only" in result.stdout
    written = json.loads(report.read_text())
    assert written["dynamic"] == 1 and written["per_object"]["Suzanne"]["dynamic"] is True
    bpy.ops.wm.open_mainfile(filepath=path)
    monkey = bpy.data.objects["Suzanne"]
    assert monkey.prt_dynamic and monkey.data["prt"][storage.DYNAMIC_KEY] is True
    assert not bpy.data.objects["Plane"].prt_dynamic and "prt" not in bpy.data.objects["Plane"].data


def test_the_stored_bake_panel_and_the_summary_say_which_bakes_are_dynamic(sphere_over_floor):
    sphere, floor = sphere_over_floor
    job = bake_now()
    assert job.summary.dynamic == 1
    assert {name: entry["dynamic"] for name, entry in job.summary.per_object.items()} == {"Plane": False,
                                                                                           "Sphere": True}
    assert job.summary.line().endswith("; 1 dynamic object, each baked in its own frame against itself only")
    said = "Dynamic: in its own frame, against itself only"
    for ob, dynamic in ((sphere, True), (floor, False)):
        bpy.context.view_layer.objects.active = ob
        assert (said in labels_drawn(bpy.types.PRT_PT_bake_info, [])) is dynamic
    bpy.context.view_layer.objects.active = sphere  # its transfer goes to the order its probes carry light to
    assert f"Lit by the order-{ORDER} light, to order {ORDER + 2} through probes" in \
        labels_drawn(bpy.types.PRT_PT_bake_info, [])


def test_the_checks_count_each_dynamic_objects_rays_against_itself_only(empty_scene):
    """A static floor, and a dynamic Suzanne and cube: three bakes one after another, each part casting its
    points' rays (as many as the bake then bakes) against its own triangles, and the time and memory checks adding
    them up."""
    bpy.ops.mesh.primitive_plane_add(size=6)
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1.2))
    bpy.ops.object.shade_smooth()  # one point per vertex
    bpy.context.object.prt_dynamic = True
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(2, 0, 0.25))
    bpy.ops.object.shade_smooth()
    bpy.context.object.prt_dynamic = True
    bpy.ops.object.select_all(action="DESELECT")
    update()
    samples = 16
    plan = plan_bake(read_request(bpy.context, bake.BakeSettings(order=ORDER, samples=samples)))
    sizes = scene_checks.bake_sizes(plan, InProcess())
    assert [size.occluder_triangles for size in sizes] == [2, 968, 12]  # the plane; Suzanne's own; the cube's own
    found = {check.subject: check.text for check in scene_checks.scene_checks(bpy.context, plan, InProcess())}
    points = {name: entry["points"] for name, entry in bake_now(samples=samples).summary.per_object.items()}
    assert [size.rays for size in sizes] == [points[name] * samples for name in ("Plane", "Suzanne", "Cube")]
    engine = sizes[0].ray_engine
    seconds = sum(checks.estimated_seconds(size.rays, size.occluder_triangles, engine, 1) for size in sizes)
    assert f"about {format_duration(seconds)} with 1 process ({sum(points.values()) * samples} rays" in found["time"]
    needed = max(checks.bake_bytes(size) for size in sizes)
    assert f"needs about {checks.format_bytes(needed)}" in found["memory"]
    dynamic_only = plan_bake(read_request(bpy.context, bake.BakeSettings(order=ORDER, samples=samples),
                                          ["Suzanne", "Cube"]))
    assert [size.occluder_triangles for size in scene_checks.bake_sizes(dynamic_only, InProcess())] == [968, 12]


def test_validation_shades_a_dynamic_object_turned_and_has_cycles_render_it_alone(sphere_over_floor, prt):
    """A sun from below the floor and a sky: in the whole scene Cycles would find the sphere in the floor's shadow,
    but a dynamic object's bake is against itself only, so Cycles renders it alone (the floor hidden for it, then
    shown again); turned, it is shaded with the light turned into its frame, as the display shades it. A convex
    sphere's bake is the exact lobe (the first test), so all that is left is Cycles' noise (the sky keeps the
    light positive: Cycles cannot emit a ringing sun's negative lobes); the light not turned is far off."""
    sphere, floor = sphere_over_floor
    bpy.context.scene.prt_display.window = "hanning"
    bake_now()
    add_light(theta=2.2, phi=0.4, strength=3.0, angular_radius=0.2)
    add_light("SKY", strength=0.3)
    sphere.rotation_euler = (0.9, 0.3, -1.2)
    update()
    check = prt.validation.Validation(bpy.context, 32, 2, ["Sphere"])
    turned = check.run()[0]
    cycles = np.stack(check.cycles.radiance["Sphere"])
    unturned = compare("unturned", check.colours(sphere, check.lights[ORDER]), cycles)
    assert check.clamped[ORDER] == 0.0
    assert turned.error <= 0.5 * turned.cycles_noise and turned.p99 <= 0.05 and unturned.error > 0.3
    assert not floor.hide_render
