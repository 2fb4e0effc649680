"""A probe volume carries the static scene's shadows to a dynamic object: a floor, a box wall, a probe volume added by
its operator and a dynamic sphere, baked; the sphere is shaded from its self-transfer and the light arriving at its
centre through the probes. Interreflected, the probes also hold the light a coloured floor reflects.

Truth, independent of the bake: the direct-light model in closed form. A probe's transfer is T_ij = ∫ y_i V y_j dω (i to
the arriving light's order, j to the distant light's) with V from exact ray tests against the floor square and the
wall's box, integrated by Gauss-Legendre quadrature in z × uniform φ (scipy's SH); a convex sphere's self-transfer is
the clamped cosine, so under a point sun L it shows at world normal n: Σ_lm (Â_l/π) Y_lm(n) (T L)_lm, whatever its turn.
A floor that nothing shadows has the clamped cosine lobe for transfer, so with albedo ρ it sends back E = ρ (Â_l/π)
Y_lm(+Z) everywhere: a probe's matrix gains ∫ y_i [ray meets the floor] dω · E_j.
"""

import math

import bpy
import numpy as np
import pytest

from conftest import add_light, labels_drawn
from node_setups import principled_material
from test_relight import read_png, srgb_to_linear
from quadrature import reference_sh
from prt_addon.blender import probe_volumes
from prt_addon.blender.checks import scene_checks
from prt_addon.blender.plan import plan_bake
from prt_addon.blender.request import read_request
from prt_addon.blender.compat import new_node_material
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, probe_grid, probe_transfer, sh
from prt_addon.core.checks import ERROR
from prt_addon.core.executors import InProcess
from prt_addon.core.shading import direction_from_angles, sun_coefficients

ORDER = 4
RECEIVED = probe_transfer.received_order(ORDER)  # the arriving light's order, and the dynamic transfer's
SAMPLES = 4096
SUN = (0.7, 0.0, 3.0)  # θ, φ, strength: a point sun over the wall from +X, so the wall shadows its −X side
A_HAT = (math.pi, 2 * math.pi / 3, math.pi / 4, 0.0, -math.pi / 24, 0.0)  # Â_l of the clamped cosine, l < 6
FLOOR = 10.0  # half the floor's side
WALL = ((-0.2, -3.0, 0.0), (0.2, 3.0, 3.0))  # the wall's box
SHADOW, BESIDE_WALL, OPEN = (-1.6, 0.0, 0.7), (-0.8, 0.0, 0.7), (3.2, 0.0, 0.7)


def update():
    bpy.context.view_layer.update()


@pytest.fixture
def wall_scene(empty_scene):
    """The floor, the wall, a probe volume over them (a cube of display size 2 scaled to 8 × 2 × 2) with probes at
    x = −3.2, −1.6, 0 (in the wall), 1.6, 3.2 and z = 0.7, 1.7, a dynamic sphere lit at its centre (one blend of
    probes for all of it, which the closed form at one point checks; per vertex where a test says so) and the sun."""
    bpy.ops.mesh.primitive_plane_add(size=2 * FLOOR)
    low, high = np.array(WALL[0]), np.array(WALL[1])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=tuple((low + high) / 2), scale=tuple(high - low))
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    volume.location, volume.scale, volume.empty_display_size = (0.0, 0.0, 1.2), (2.0, 0.5, 0.5), 2.0
    volume.prt_probe_resolution = (5, 1, 2)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.3, location=SHADOW)
    sphere = bpy.context.object
    bpy.ops.object.shade_smooth()
    sphere.prt_dynamic = True
    sphere.prt_probe_light = "centre"
    bpy.ops.object.select_all(action="DESELECT")
    empty_scene.prt_display.window = "none"
    theta, phi, strength = SUN
    add_light(theta=theta, phi=phi, strength=strength, angular_radius=0.0)
    return sphere, volume


def blocked(origin, directions) -> np.ndarray:
    """Exact ray tests: does the ray from `origin` along each direction meet the floor square or the wall's box."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -origin[2] / directions[:, 2]
        hit = origin[:2] + t[:, None] * directions[:, :2]
        floor = (directions[:, 2] < 0) & np.all(np.abs(hit) <= FLOOR, axis=1)
        near = (np.array(WALL[0]) - origin) / directions
        far = (np.array(WALL[1]) - origin) / directions
    enter = np.nanmax(np.minimum(near, far), axis=1)
    leave = np.nanmin(np.maximum(near, far), axis=1)
    return floor | ((enter <= leave) & (leave > 0))


def sphere_quadrature(nodes=400):
    """Gauss-Legendre in z × uniform φ; V jumps at the edges, so integrals of it are fine rather than exact."""
    z, w = np.polynomial.legendre.leggauss(nodes)
    phi = 2 * np.pi * (np.arange(2 * nodes) + 0.5) / (2 * nodes)
    r = np.sqrt(1 - z * z)[:, None]
    directions = np.stack(np.broadcast_arrays(r * np.cos(phi), r * np.sin(phi), z[:, None]), -1).reshape(-1, 3)
    return directions, np.repeat(w, 2 * nodes) * (np.pi / nodes)


def closed_form_transfer(origin, hits=blocked) -> np.ndarray:
    """T_ij = ∫ y_i V y_j dω (N² × n²), V from the ray tests `hits`."""
    directions, weights = sphere_quadrature()
    y = reference_sh(RECEIVED, directions)
    return np.einsum("k,ki,kj->ij", weights * ~hits(np.asarray(origin, dtype=float), directions), y, y[:, :ORDER ** 2])


def sun_light() -> np.ndarray:
    theta, phi, strength = SUN
    return strength * sun_coefficients(ORDER, direction_from_angles(theta, phi), 0.0)


def lobe(order, normals=((0.0, 0.0, 1.0),)) -> np.ndarray:
    """(..., order²) the clamped cosine lobe's SH about each normal, (Â_l/π) Y_lm(n): a convex object's transfer."""
    return np.repeat(np.array(A_HAT[:order]) / math.pi, 2 * np.arange(order) + 1) * reference_sh(order, normals)


def convex_shading(normals, arriving) -> np.ndarray:
    """What a convex object shows at world normals under the arriving SH light (N²,), or the distant one (n²,)."""
    return np.maximum(lobe(RECEIVED, normals)[:, :len(arriving)] @ arriving, 0.0)


def colours(mesh) -> np.ndarray:
    values = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["prt_color"].data.foreach_get("color", values)
    return values.reshape(-1, 4)[:, 0]


def world_normals(ob) -> np.ndarray:
    normals = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertices.foreach_get("normal", normals)
    turned = normals.reshape(-1, 3) @ np.array(ob.matrix_world.to_3x3()).T
    return turned / np.linalg.norm(turned, axis=1, keepdims=True)


def shown_at(sphere, location, turn=(0.0, 0.0, 0.0)) -> np.ndarray:
    sphere.location, sphere.rotation_euler = location, turn
    update()
    return colours(sphere.data)


def test_a_dynamic_sphere_in_the_walls_shadow_gets_the_closed_form_light_through_the_probes(wall_scene):
    sphere, volume = wall_scene
    job = SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="shadowed", samples=SAMPLES))
    job.run(log=lambda line: None)
    assert any("probe volume 'PRT Probe Volume': 10 probes, 2 inside geometry" in note for note in job.notes)
    stored = probe_volumes.read(volume)
    np.testing.assert_array_equal(stored.valid.reshape(5, 2), [[1, 1], [1, 1], [0, 0], [1, 1], [1, 1]])
    bpy.context.view_layer.objects.active = volume
    drawn = []
    assert "2 probes inside geometry, left out" in labels_drawn(bpy.types.PRT_PT_probe_volume, drawn)
    assert drawn == ["prt_probe_resolution"]
    light = sun_light()
    sigma = volume[probe_volumes.METADATA_KEY]["est_max_error"]
    # The shading at any normal moves by at most ‖ΔT‖_F ‖L‖ ‖(Â/π)·y(n)‖ for an error ΔT of the probe's matrix.
    reach = np.linalg.norm(light) * np.linalg.norm(lobe(RECEIVED))
    means = {}
    for name, location, turn in (("shadow", SHADOW, (0.4, 1.1, -2.0)), ("open", OPEN, (0.0, 0.0, 0.0))):
        shown = shown_at(sphere, location, turn)
        expected = convex_shading(world_normals(sphere), closed_form_transfer(location) @ light)
        error = np.abs(shown - expected).max()
        print(f"{name}: mean shown {shown.mean():.4f}, closed form {expected.mean():.4f}, largest difference "
              f"{error:.4f}, bound {3 * sigma * reach + 2e-3:.4f} (3σ of the probe, σ = {sigma:.4f})")
        assert error <= 3 * sigma * reach + 2e-3  # the closed form's own quadrature is good to about 1e-3
        assert shown.mean() == pytest.approx(expected.mean(), rel=0.03)
        means[name] = shown.mean(), expected.mean()
    assert means["shadow"][0] < 0.6 * means["open"][0]
    assert means["shadow"][1] < 0.6 * means["open"][1]


def test_per_vertex_each_vertex_gets_its_own_blend_of_the_closed_form_probes(wall_scene):
    """Per vertex, a vertex at p shows the convex lobe under Σ_k w_k(p) T_k L, T_k the closed form at the probes
    around p and w their trilinear weights over the valid ones (checked against hand values in
    tests/core/test_probe_volume.py): across the sphere in the shadow, vertices towards the open side blend in the
    open probes' light, while those towards the wall take the probe beside it alone. Outside every volume, every
    vertex gets the distant light."""
    sphere, volume = wall_scene
    sphere.prt_probe_light = "vertex"
    SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="shadowed", samples=SAMPLES)).run(log=lambda line: None)
    stored = probe_volumes.read(volume)
    sigma = volume[probe_volumes.METADATA_KEY]["est_max_error"]
    placement = np.linalg.inv(stored.to_volume)
    truth = np.array([closed_form_transfer(origin) for origin in probe_grid.probe_positions(placement, (5, 1, 2))])
    light = sun_light()
    reach = np.linalg.norm(light) * np.linalg.norm(lobe(RECEIVED))
    apart = worst = 0.0
    # The last stands half above the volume's top (z = 2.2): its upper vertices get the distant light.
    for location, turn in ((SHADOW, (0.4, 1.1, -2.0)), (OPEN, (0.0, 0.0, 0.0)), ((-2.4, 0.0, 1.2), (1.0, 0.0, 0.5)),
                           ((3.2, 0.0, 2.2), (0.3, 0.2, 0.0))):
        shown = shown_at(sphere, location, turn)
        positions = np.empty(3 * len(sphere.data.vertices))
        sphere.data.vertices.foreach_get("co", positions)
        world = positions.reshape(-1, 3) @ np.array(sphere.matrix_world.to_3x3()).T + np.array(location)
        local = world @ stored.to_volume[:3, :3].T + stored.to_volume[:3, 3]
        indices, weights = probe_grid.trilinear_weights(local, (5, 1, 2), stored.valid)
        arriving = np.einsum("vk,vkij,j->vi", weights, truth[indices], light)
        inside = np.all(np.abs(local) <= 1.0, axis=1)
        assert inside.all() or 0.2 < inside.mean() < 0.8  # the half-out placement is half out
        arriving[~inside] = sh.fitted(light, RECEIVED ** 2)
        normals = world_normals(sphere)
        expected = np.array([convex_shading(normal[None], row)[0] for normal, row in zip(normals, arriving)])
        centre = convex_shading(normals, closed_form_transfer(location) @ light)
        error = np.abs(shown - expected).max()
        print(f"{location}: per vertex largest difference {error:.4f} (bound {3 * sigma * reach + 2e-3:.4f}); "
              f"from the centre's light instead {np.abs(centre - expected).max():.4f}")
        assert error <= 3 * sigma * reach + 2e-3
        apart, worst = max(apart, np.abs(centre - expected).max()), max(worst, error)
    assert apart > 3 * worst  # per vertex is not the centre's light
    sphere.prt_probe_light = "centre"  # shown again at once, the centre's light
    update()
    indices, weights = probe_grid.trilinear_weights(stored.to_volume[:3, :3] @ location + stored.to_volume[:3, 3],
                                                    (5, 1, 2), stored.valid)
    at_centre = np.einsum("k,kij,j->i", weights, stored.matrices[indices, 0], light)  # the stored probes, blended
    np.testing.assert_allclose(colours(sphere.data), convex_shading(world_normals(sphere), at_centre), atol=1e-5)
    sphere.location = (-10.0, 0.0, 0.7)
    update()
    np.testing.assert_allclose(colours(sphere.data), convex_shading(world_normals(sphere), sun_light()),
                               rtol=0, atol=2e-6)


def test_keyframed_motion_renders_each_frames_probe_light_with_eevee(wall_scene, prt, tmp_path):
    """Two frames of an animation rendered with EEVEE (the frame handler relights the moving sphere for each, per
    vertex): in the wall's shadow at frame 1, in the open and turned at frame 2. A camera following it straight down
    sees the top of the sphere, whose colour (× a white albedo) is the closed form's: the light arriving at the top
    vertex, Σ_k w_k T_k L with T_k the closed-form probes, on the convex lobe around +Z."""
    sphere, volume = wall_scene
    sphere.prt_probe_light = "vertex"
    sphere.data.materials.append(principled_material("White", base_colour=(1.0, 1.0, 1.0)))
    SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="shadowed", samples=SAMPLES)).run(log=lambda line: None)
    stored = probe_volumes.read(volume)
    sigma = volume[probe_volumes.METADATA_KEY]["est_max_error"]
    scene = bpy.context.scene
    scene.prt_display.show_prt = True
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = "ORTHO", 0.05
    scene.collection.objects.link(camera)
    scene.camera = camera
    frames = {1: (SHADOW, 0.0), 2: (OPEN, 1.0)}
    for frame, (location, turn) in frames.items():
        sphere.location, sphere.rotation_euler = location, (0.0, 0.0, turn)  # about Z: its pole stays on top
        sphere.keyframe_insert("location", frame=frame)
        sphere.keyframe_insert("rotation_euler", frame=frame)
        camera.location = (location[0], location[1], 3.0)
        camera.keyframe_insert("location", frame=frame)
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.engine = prt.render.engine_id("EEVEE")
    scene.eevee.taa_render_samples = 1
    scene.view_settings.view_transform = "Standard"
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = str(tmp_path / "frame_")
    bpy.ops.render.render(animation=True)
    upward = lobe(RECEIVED)[0]
    placement = np.linalg.inv(stored.to_volume)
    light = sun_light()
    bound = 3 * sigma * np.linalg.norm(light) * np.linalg.norm(upward) + 2e-3 + 0.01  # + 8-bit sRGB and EEVEE's filter
    shown, expected = {}, {}
    for frame, (location, _) in frames.items():
        top = np.array(location) + (0.0, 0.0, 0.3)
        indices, weights = probe_grid.trilinear_weights(top @ stored.to_volume[:3, :3].T + stored.to_volume[:3, 3],
                                                        (5, 1, 2), stored.valid)
        probes = probe_grid.probe_positions(placement, (5, 1, 2))[indices]
        arriving = sum(weight * closed_form_transfer(origin) @ light for weight, origin in zip(weights, probes))
        expected[frame] = max(upward @ arriving, 0.0)
        pixels = srgb_to_linear(read_png(str(tmp_path / f"frame_{frame:04d}.png"))[7:9, 7:9, :3])
        shown[frame] = pixels.mean()
        print(f"frame {frame}: top of the sphere rendered {shown[frame]:.4f}, closed form {expected[frame]:.4f} "
              f"(bound {bound:.4f})")
        assert np.abs(pixels - expected[frame]).max() <= bound
    assert expected[2] - expected[1] > 2 * bound  # each frame shows its own light, not the other's


def test_beside_the_wall_the_sphere_is_lit_by_its_own_side_only(wall_scene, tmp_path):
    """Its cell's probes in the wall are left out: it takes the probe at x = −1.6 alone, not the open side's. The
    probes stay where they were baked when the volume moves, and are saved with the file."""
    sphere, volume = wall_scene
    SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="shadowed", samples=256)).run(log=lambda line: None)
    in_shadow = shown_at(sphere, SHADOW)
    np.testing.assert_allclose(shown_at(sphere, BESIDE_WALL), in_shadow, rtol=0, atol=1e-6)
    volume.location.x += 0.8  # the probes stay where they were baked
    assert not np.allclose(shown_at(sphere, OPEN), in_shadow, rtol=0, atol=1e-3)  # shaded again on the way back
    np.testing.assert_allclose(shown_at(sphere, SHADOW), in_shadow, rtol=0, atol=1e-6)
    sphere.location = (-10.0, 0.0, 0.7)  # outside every volume: the distant light, unshadowed
    update()
    open_sky = convex_shading(world_normals(sphere), sun_light())
    np.testing.assert_allclose(colours(sphere.data), open_sky, rtol=0, atol=2e-6)
    baked = probe_volumes.read(volume)
    path = str(tmp_path / "probes.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    reread = probe_volumes.read(bpy.data.objects["PRT Probe Volume"])
    assert np.array_equal(reread.matrices, baked.matrices) and np.array_equal(reread.valid, baked.valid)
    assert reread.resolution == (5, 1, 2) and (reread.order, reread.received_order) == (ORDER, RECEIVED)


def floor_only(origin, directions):
    """Exact ray tests against the floor square alone."""
    with np.errstate(divide="ignore", invalid="ignore"):
        hit = origin[:2] - (origin[2] / directions[:, 2])[:, None] * directions[:, :2]
    return (directions[:, 2] < 0) & np.all(np.abs(hit) <= FLOOR, axis=1)


def test_interreflected_probes_hold_the_light_a_coloured_floor_reflects(empty_scene):
    bpy.ops.mesh.primitive_plane_add(size=2 * FLOOR)
    floor = bpy.context.object
    material = new_node_material("Floor")
    principled = material.node_tree.nodes.new("ShaderNodeBsdfPrincipled")
    output = material.node_tree.nodes.new("ShaderNodeOutputMaterial")
    material.node_tree.links.new(principled.outputs["BSDF"], output.inputs["Surface"])
    albedo = np.array([0.8, 0.4, 0.2])
    principled.inputs["Base Color"].default_value = (*albedo, 1.0)
    floor.data.materials.append(material)
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    volume.location, volume.scale, volume.prt_probe_resolution = (1.0, -2.0, 1.0), (1.0, 1.0, 0.5), (1, 1, 2)
    bpy.ops.object.select_all(action="DESELECT")
    SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="interreflected", samples=SAMPLES)).run(
        log=lambda line: None)
    stored = probe_volumes.read(volume)
    assert stored.matrices.shape == (2, 3, RECEIVED ** 2, ORDER ** 2) and stored.valid.all()
    sigma = volume[probe_volumes.METADATA_KEY]["est_max_error"]
    floor = lobe(ORDER)[0]  # the floor's own transfer, to the distant light's order
    directions, weights = sphere_quadrature()
    for probe, height in enumerate((0.75, 1.25)):
        origin = np.array([1.0, -2.0, height])
        seen = (weights * floor_only(origin, directions)) @ reference_sh(RECEIVED, directions)  # ∫ y_i [floor]
        expected = closed_form_transfer(origin, floor_only)[None] + np.einsum("i,c,j->cij", seen, albedo, floor)
        difference = np.linalg.norm(stored.matrices[probe] - expected)
        reflected = np.linalg.norm(np.einsum("i,c,j->cij", seen, albedo, floor))
        print(f"probe at z = {height}: ‖T − closed form‖ {difference:.4f}, 3σ {3 * sigma:.4f}, "
              f"reflected part ‖·‖ {reflected:.4f}")
        assert difference <= 3 * sigma + 2e-3
        assert reflected > 5 * (3 * sigma + 2e-3)  # the reflection is far beyond the noise: it is there


def test_the_checks_count_the_probes_rays_and_refuse_probes_memory_cannot_hold(empty_scene):
    bpy.ops.mesh.primitive_plane_add(size=2 * FLOOR)
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    volume.prt_probe_resolution = (2, 2, 2)
    bpy.ops.object.select_all(action="DESELECT")

    def checks(order):
        plan = plan_bake(read_request(bpy.context, bake.BakeSettings(order=order, samples=64)))
        return {check.subject: check for check in scene_checks(bpy.context, plan, InProcess())}
    assert "(768 rays at a typical" in checks(ORDER)["time"].text  # (4 vertices + 8 probes) × 64
    volume.prt_probe_resolution = (64, 64, 64)
    memory = checks(16)["memory"]  # 262,144 probes × 16⁴ values × 12 bytes: about 190 GB
    assert memory.level == ERROR and "fewer objects or probes" in memory.text, memory.text


def test_an_unshadowed_or_farm_bake_leaves_the_probes_as_they_were(empty_scene):
    bpy.ops.mesh.primitive_plane_add(size=2 * FLOOR)
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    bpy.ops.object.select_all(action="DESELECT")
    unshadowed = SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="unshadowed"))
    unshadowed.run(log=lambda line: None)
    assert any("an unshadowed bake leaves them as they were" in note for note in unshadowed.notes)
    assert probe_volumes.METADATA_KEY not in volume
    farm = read_request(bpy.context, bake.BakeSettings(order=ORDER, samples=16), farm=True)
    assert farm.probe_volumes == [] and any("a farm bake leaves them as they were" in note for note in farm.notes)
    volume.scale = (1.0, 0.0, 1.0)
    flat = read_request(bpy.context, bake.BakeSettings(order=ORDER, samples=16))
    assert flat.probe_volumes == [] and any("flat on an axis" in problem for problem in flat.problems)


def test_a_volume_rebaked_at_another_resolution_holds_the_new_probes(empty_scene):
    """Its arrays are replaced by arrays of the new size (assigned over the old ones, Blender corrupted its heap)."""
    bpy.ops.mesh.primitive_plane_add(size=2 * FLOOR)
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    bpy.ops.object.select_all(action="DESELECT")
    for resolution in ((1, 1, 2), (3, 2, 2), (2, 1, 1)):
        volume.prt_probe_resolution = resolution
        SceneBake(bpy.context, bake.BakeSettings(order=ORDER, samples=16)).run(log=lambda line: None)
        stored = probe_volumes.read(volume)
        assert stored.resolution == resolution and stored.matrices.shape[0] == stored.valid.size == np.prod(resolution)
