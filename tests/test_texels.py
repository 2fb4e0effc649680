"""Texel storage in Blender: texel bakes against closed forms, the lightmap UV map, the stored maps (packed,
reloaded, exported), relighting per texel, Auto's choice, and bad input stopped before any ray."""

import json
import math

import bpy
import numpy as np
import pytest

from conftest import run_cli
from gltf_files import read_glb
from node_setups import principled_material
from prt_addon.blender import storage, texel_maps
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, gltf_pack, lobes, rotation
from prt_addon.core.errors import InputError

ORDER = 4
Y00 = 0.5 / math.sqrt(math.pi)


def floor_quad(size=4.0, cuts=1, name="Floor"):
    """A square floor at z = 0 with Blender's own UV map 'UVMap' (u along x, v along y over [0, 1])."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=cuts, y_subdivisions=cuts, size=size)
    ob = bpy.context.object
    ob.name = name
    return ob


def ball(radius=0.5, height=1.5):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=radius, location=(0, 0, height))
    ob = bpy.context.object
    ob.name = "Ball"
    ob.data.shade_smooth()
    return ob


def run_bake(objects=None, log=None, **options):
    settings = {key: options.pop(key) for key in ("mode", "samples", "target_error") if key in options}
    scene_bake = SceneBake(bpy.context, bake.BakeSettings(order=ORDER, **{"samples": 64, **settings}), objects,
                           storage_options=options)
    scene_bake.run(log=log)
    return scene_bake


def texel_centres(meta, size=4.0):
    """World x, y of every texel centre of a floor whose UV map spans it (Blender's grid UVs)."""
    y, x = np.mgrid[0: meta["height"], 0: meta["width"]]
    return (((x + 0.5) / meta["width"] - 0.5) * size).ravel(), (((y + 0.5) / meta["height"] - 0.5) * size).ravel()


def sphere_blocked_dc(x, y, radius, height):
    """T_00 of an upward point at (x, y, 0) under a sphere: (Y_00/π)·∫ over the unblocked hemisphere of cos θ, where
    the sphere's cap (half-angle α, axis β from the zenith, wholly above the horizon) blocks π·sin²α·cos β."""
    distance = np.sqrt(x * x + y * y + height * height)
    return Y00 * (1.0 - (radius / distance) ** 2 * height / distance)


# -- baking -------------------------------------------------------------------------------------------------------
def test_an_unshadowed_texel_bake_is_the_cosine_lobe_everywhere_gutters_included(empty_scene):
    floor = floor_quad()
    run_bake(["Floor"], mode="unshadowed", storage="texel", resolution=32, uv_map="UVMap")
    planes, meta = texel_maps.read_planes(floor.data)
    assert (meta["storage"], meta["width"], meta["height"], meta["texels"]) == ("TEXEL", 32, 32, 32 * 32)
    expected = lobes.cosine_transfer(ORDER, np.array([[0.0, 0.0, 1.0]]))[0]
    np.testing.assert_allclose(planes.T, np.broadcast_to(expected, (32 * 32, ORDER * ORDER)), atol=1e-6)


def test_a_one_quad_floor_per_texel_shows_the_spheres_shadow_as_the_closed_form_says(empty_scene):
    """Where vertex storage has only the quad's four corners (no shadow at all), its texels hold the shadow:
    T_00 within 0.5 % RMS of the closed form, and each texel within 4 standard errors plus 2 % (a texel whose
    replicates all missed the far, small ball estimates no error at all)."""
    floor, radius, height = floor_quad(), 0.5, 1.5
    ball(radius, height)
    run_bake(["Floor"], samples=256, storage="texel", resolution=48, uv_map="UVMap")
    planes, meta = texel_maps.read_planes(floor.data)
    x, y = texel_centres(meta)
    distance = np.sqrt(x * x + y * y + height * height)
    above_horizon = np.arcsin(radius / distance) + np.arccos(height / distance) < np.pi / 2 - 0.05
    expected = sphere_blocked_dc(x, y, radius, height)
    error = texel_maps.read_error(floor.data).ravel() * lobes.unshadowed_norm(ORDER)
    difference = np.abs(planes[0] - expected)[above_horizon]
    assert above_horizon.sum() > 500
    assert np.sqrt(np.mean(difference ** 2)) < 0.005 * Y00
    assert np.all(difference <= 4 * error[above_horizon] + 0.02 * Y00)
    centre = np.argmin(x * x + y * y)
    assert planes[0, centre] == pytest.approx(Y00 * (1 - (radius / height) ** 2), abs=0.01 * Y00)
    assert planes[0, centre] < 0.9 * Y00  # the shadow is there


def test_prt_adds_its_own_lightmap_uv_map_and_leaves_the_users_maps_alone(empty_scene):
    """The floor's own map tiles a texture twice (beyond 0-1), so it is no lightmap: PRT makes its own."""
    floor = floor_quad(cuts=4)
    ball()
    mesh = floor.data
    before = np.empty(len(mesh.loops) * 2)
    mesh.uv_layers["UVMap"].uv.foreach_get("vector", before)
    before *= 2.0
    mesh.uv_layers["UVMap"].uv.foreach_set("vector", before)
    run_bake(["Floor"], storage="texel", resolution=64)
    assert [layer.name for layer in mesh.uv_layers] == ["UVMap", texel_maps.PRT_UV_MAP]
    assert mesh.uv_layers.active.name == "UVMap" and mesh.uv_layers["UVMap"].active_render
    after = np.empty(len(mesh.loops) * 2)
    mesh.uv_layers["UVMap"].uv.foreach_get("vector", after)
    np.testing.assert_array_equal(before, after)
    meta = mesh[storage.METADATA_KEY]
    assert meta["uv_map"] == texel_maps.PRT_UV_MAP and 0.5 * 64 * 64 < meta["texels"] < 64 * 64


def test_a_render_uv_map_that_serves_as_a_lightmap_is_used_as_it_is(empty_scene):
    floor = floor_quad(cuts=4)
    scene_bake = run_bake(["Floor"], mode="unshadowed", storage="texel", resolution=32)
    assert [layer.name for layer in floor.data.uv_layers] == ["UVMap"]
    assert scene_bake.report().storage[0] == "'Floor': Storage Texel; 32 × 32 texels in UV map 'UVMap', 1024 covered"


def test_a_chosen_uv_map_beyond_the_unit_square_is_refused(empty_scene):
    floor = floor_quad(cuts=2)
    floor.data.uv_layers["UVMap"].uv[0].vector = (1.5, 0.0)
    with pytest.raises(InputError, match=r"'Floor': 1 faces reach outside the unit square in UV map 'UVMap'"):
        run_bake(["Floor"], storage="texel", resolution=16, uv_map="UVMap")


def test_the_maps_are_packed_survive_reloading_and_export_as_exr(empty_scene, tmp_path):
    floor = floor_quad()
    ball()
    run_bake(["Floor"], storage="texel", resolution=32, uv_map="UVMap")
    planes, meta = texel_maps.read_planes(floor.data)
    assert meta["images"] == [f"_prt_{floor.data.name}_t{j:02d}" for j in range(4)]
    assert all(bpy.data.images[name].packed_file is not None for name in meta["images"] + [meta["error_image"]])
    path = tmp_path / "texels.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    reloaded, _ = texel_maps.read_planes(bpy.data.objects["Floor"].data)
    np.testing.assert_array_equal(reloaded, planes)
    out = run_cli("export", path, "--object", "Floor", "--npz", tmp_path / "floor.npz")
    assert out.returncode == 0, out.stderr
    exported = np.load(tmp_path / "floor.npz")
    np.testing.assert_allclose(exported["transfer"].reshape(-1, ORDER * ORDER), planes.T, atol=1e-6)
    assert json.loads(str(exported["metadata"]))["storage"] == "TEXEL"
    image = bpy.data.images.load(str(tmp_path / "floor_t00.exr"))
    pixels = np.empty(32 * 32 * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    np.testing.assert_allclose(pixels.reshape(-1, 4), planes[:4].T, atol=1e-6)


def test_gltf_export_carries_the_maps_in_gltfs_frame_through_the_lightmap_uv_set(empty_scene, tmp_path):
    floor = floor_quad()
    ball()
    run_bake(["Floor"], storage="texel", resolution=32)  # the grid's own UV map serves as its lightmap
    planes, meta = texel_maps.read_planes(floor.data)
    path = tmp_path / "texels.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    out = run_cli("export", path, "--gltf", tmp_path / "texels.glb")
    assert out.returncode == 0, out.stderr
    assert meta["uv_map"] == "UVMap"
    assert "Floor: order 4 in 4 RGBA32F texel maps of 32 × 32 (TEXCOORD_0)" in out.stdout
    document, binary = read_glb(tmp_path / "texels.glb")  # its extras as the manual describes them
    mesh = next(m for m in document["meshes"] if m["name"] == "Floor")
    extras = mesh["extras"]["prt"]
    assert (extras["layout"], extras["texcoord"], extras["vec4s"]) == ("texel_maps", "TEXCOORD_0", 4)
    maps = [np.frombuffer(bytes(binary[document["bufferViews"][view]["byteOffset"]:][: 32 * 32 * 16]),
                          dtype=np.float32).reshape(32, 32, 4) for view in extras["maps"]["bufferViews"]]
    rows = np.concatenate(maps, axis=-1)[::-1].reshape(-1, ORDER * ORDER)  # top row first → Blender's bottom first
    back = rotation.rotate(rows.astype(np.float64), gltf_pack.Z_UP_TO_Y_UP.T)
    np.testing.assert_allclose(back, planes.T, atol=2e-6)
    texcoord = mesh["primitives"][0]["attributes"]["TEXCOORD_0"]
    accessor = document["accessors"][texcoord]
    start = document["bufferViews"][accessor["bufferView"]].get("byteOffset", 0) + accessor.get("byteOffset", 0)
    exported = np.frombuffer(bytes(binary[start: start + 8 * accessor["count"]]), dtype=np.float32).reshape(-1, 2)
    lightmap = np.empty(2 * len(floor.data.loops), dtype=np.float32)
    floor.data.uv_layers[meta["uv_map"]].uv.foreach_get("vector", lightmap)
    flipped = {(round(u, 5), round(1.0 - v, 5)) for u, v in lightmap.reshape(-1, 2)}  # glTF's v runs down
    assert {(round(u, 5), round(v, 5)) for u, v in exported} == flipped


def test_a_vertex_bake_replaces_a_texel_bake_and_its_maps(empty_scene):
    floor = floor_quad()
    run_bake(["Floor"], mode="unshadowed", storage="texel", resolution=16, uv_map="UVMap")
    names = list(floor.data[storage.METADATA_KEY]["images"])
    run_bake(["Floor"], mode="unshadowed")
    assert not [name for name in names if name in bpy.data.images]
    assert storage.read_transfer(floor.data)[1]["domain"] == "POINT"


# -- Auto ---------------------------------------------------------------------------------------------------------
def test_auto_stores_a_shadowed_floor_per_texel_and_the_smooth_ball_per_vertex_and_says_why(empty_scene):
    floor = floor_quad(cuts=16)
    sphere = ball()
    scene_bake = run_bake(["Floor", "Ball"], storage="auto", samples=64)
    assert floor.data[storage.METADATA_KEY]["storage"] == "TEXEL"
    assert sphere.data[storage.METADATA_KEY]["domain"] in ("POINT", "CORNER")
    decisions = " ".join(scene_bake.report().storage)
    assert "'Floor': Auto stores per texel: interpolating between vertices errs" in decisions
    assert "'Ball': Auto keeps vertex storage" in decisions


# -- relighting ---------------------------------------------------------------------------------------------------
def test_moving_a_light_reshades_each_texel_with_one_dot_product(empty_scene):
    floor = floor_quad()
    ball()
    run_bake(["Floor"], samples=256, storage="texel", resolution=32, uv_map="UVMap")
    bpy.ops.prt.light_add(kind="SKY")
    sky = bpy.context.scene.prt_lights[-1]
    bpy.context.scene.prt_display.show_prt = True
    bpy.context.view_layer.update()
    planes, meta = texel_maps.read_planes(floor.data)
    image = bpy.data.images[f"_prt_{floor.data.name}_shaded"]
    shaded = np.empty(32 * 32 * 4, dtype=np.float32)
    image.pixels.foreach_get(shaded)
    shaded = shaded.reshape(-1, 4)
    corner = 0  # far from the ball: under a unit sky, 1 less the little the ball blocks
    seen = sphere_blocked_dc(-2 + 2 / 32, -2 + 2 / 32, 0.5, 1.5) / Y00
    assert shaded[corner, :3] == pytest.approx([seen] * 3, abs=0.02)
    assert shaded[:, 0].min() < 0.9  # under the ball
    sky.strength = 2.0
    bpy.context.view_layer.update()
    image.pixels.foreach_get(shaded.ravel())
    light = 2.0 * np.sqrt(4 * np.pi) * np.eye(1, ORDER * ORDER)[0]  # a constant sky of radiance 2
    np.testing.assert_allclose(shaded[:, 0], np.maximum(light @ planes, 0), rtol=1e-5, atol=1e-6)
    material = floor.material_slots[0].material
    node = next(n for n in material.node_tree.nodes if n.type == "TEX_IMAGE")
    assert node.image == image and material["_prt_display_image"] == image.name


# -- bad input ----------------------------------------------------------------------------------------------------
def baked_bytes(mesh):
    """Every PRT attribute's bytes and the metadata."""
    found = {}
    for attribute in (a for a in mesh.attributes if a.name.startswith("_prt_")):
        key = "vector" if attribute.data_type == "FLOAT_VECTOR" else "value"
        values = np.empty(len(attribute.data) * (3 if key == "vector" else 1), dtype=np.float32)
        attribute.data.foreach_get(key, values)
        found[attribute.name] = values.tobytes()
    return found, json.dumps(mesh[storage.METADATA_KEY].to_dict(), sort_keys=True)


def test_no_uv_map_and_no_permission_to_add_one_stops_before_any_ray_and_keeps_the_earlier_bake(empty_scene):
    floor = floor_quad()
    floor.data.uv_layers.remove(floor.data.uv_layers["UVMap"])
    run_bake(["Floor"], mode="unshadowed")
    before = baked_bytes(floor.data)
    with pytest.raises(InputError, match=r"'Floor': texel storage needs a lightmap UV map; choose one of its UV "
                                         r"maps \(none\) or allow PRT to add its own 'PRT Lightmap'"):
        run_bake(["Floor"], storage="texel", resolution=16, new_uv_map=False)
    assert baked_bytes(floor.data) == before and len(floor.data.uv_layers) == 0


def test_overlapping_uvs_are_reported_with_their_share(empty_scene):
    floor = floor_quad(cuts=2)
    uv = floor.data.uv_layers["UVMap"].uv
    corners = [(0, 0), (1, 0), (1, 1), (0, 1)]
    for face in floor.data.polygons:  # every face over the whole square
        for corner, loop in zip(corners, face.loop_indices):
            uv[loop].vector = corner
    # every texel but the 32 on the faces' shared diagonal, which lie on edges only
    with pytest.raises(InputError, match=r"'Floor': UV map 'UVMap' overlaps itself: 96\.9 % of its texels \(992\)"):
        run_bake(["Floor"], storage="texel", resolution=32, uv_map="UVMap")


def test_zero_area_uv_faces_are_reported(empty_scene):
    floor = floor_quad(cuts=2)
    uv = floor.data.uv_layers["UVMap"].uv
    for loop in floor.data.polygons[0].loop_indices:
        uv[loop].vector = (0.1, 0.1)
    with pytest.raises(InputError, match=r"'Floor': 1 faces have zero area in UV map 'UVMap'"):
        run_bake(["Floor"], storage="texel", resolution=32, uv_map="UVMap")


def test_a_resolution_beyond_memory_is_refused_before_any_ray(empty_scene, monkeypatch):
    floor_quad()
    from prt_addon.core import job
    monkeypatch.setattr(job.TransferJob, "step", lambda *args: pytest.fail("rays were cast"))
    with pytest.raises(InputError, match=r"'Floor': 8192 × 8192 texels need about .* GB, more than the .* available"):
        SceneBake(bpy.context, bake.BakeSettings(order=10), ["Floor"],
                  storage_options={"storage": "texel", "resolution": 8192, "uv_map": "UVMap"})


def test_interreflected_texel_bakes_with_coloured_albedo_say_what_is_missing(empty_scene):
    floor = floor_quad()
    floor.data.materials.append(principled_material("Red", (0.8, 0.1, 0.1)))
    with pytest.raises(InputError, match="'Floor': texel maps hold one channel, and coloured albedo makes "
                                         "interreflected transfer RGB"):
        run_bake(["Floor"], mode="interreflected", storage="texel", resolution=16, uv_map="UVMap")


# -- image validation ---------------------------------------------------------------------------------------------
def camera(location=(0.0, -5.0, 4.0), rotation=(0.9, 0.0, 0.0)):
    data = bpy.data.cameras.new("Camera")
    ob = bpy.data.objects.new("Camera", data)
    bpy.context.scene.collection.objects.link(ob)
    ob.location, ob.rotation_euler = location, rotation
    return ob


def test_validate_image_sees_the_shadow_texels_hold_and_vertices_miss(empty_scene, tmp_path, prt):
    """The sphere over a one-quad floor, from a camera, against Cycles: vertex storage misses the shadow (about
    10 % RMS), Auto's texels hold it (under 2 %); the heatmap is written and the scene is put back."""
    floor_quad()
    ball(radius=0.5, height=0.8)
    view = camera()
    bpy.context.scene.camera = view
    world, engine = bpy.context.scene.world, bpy.context.scene.render.engine
    errors = {}
    for storage_kind in ("vertex", "auto"):
        run_bake(["Floor", "Ball"], samples=128, storage=storage_kind)
        report = prt.image_validation.validate_image(bpy.context, "Camera", samples=16, resolution=(64, 48),
                                                     heatmap_path=str(tmp_path / f"{storage_kind}.png"))
        errors[storage_kind] = report.comparison.error
        assert report.comparison.vertices > 1000 and (tmp_path / f"{storage_kind}.png").exists()
    assert errors["vertex"] > 0.05 and errors["auto"] < 0.02
    assert bpy.context.scene.world == world and bpy.context.scene.render.engine == engine
    assert not bpy.context.scene.prt_display.show_prt
    assert all(slot.material is None or "PRT" not in slot.material.name for ob in bpy.data.objects
               for slot in ob.material_slots)
    heatmap = bpy.data.images.load(str(tmp_path / "vertex.png"))
    assert tuple(heatmap.size) == (64, 48)


def test_an_objects_own_storage_choice_is_baked_and_changing_it_makes_the_bake_stale(empty_scene):
    from prt_addon.blender.fingerprint import stale_receivers
    floor = floor_quad()
    floor.prt_storage, floor.prt_resolution, floor.prt_uv_map = "texel", 16, "UVMap"
    settings = bake.BakeSettings(order=ORDER, mode="unshadowed")
    SceneBake(bpy.context, settings, ["Floor"]).run()
    assert floor.data[storage.METADATA_KEY]["width"] == 16
    assert stale_receivers(bpy.context, settings, ["Floor"]) == {"Floor": []}
    floor.prt_resolution = 32
    assert stale_receivers(bpy.context, settings, ["Floor"]) == {"Floor": ["settings changed"]}


def test_prt_bake_stores_per_texel_from_the_command_line(empty_scene, tmp_path):
    floor_quad()
    path = tmp_path / "floor.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    out = run_cli("bake", path, "--mode", "unshadowed", "--storage", "texel", "--resolution", "16", "--uv-map",
                  "UVMap", "--report", tmp_path / "report.json")
    assert out.returncode == 0, out.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["storage"] == ["'Floor': Storage Texel; 16 × 16 texels in UV map 'UVMap', 256 covered",
                                 "texel lattices: every 1: 256 baked, 0 interpolated"]
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert bpy.data.objects["Floor"].data[storage.METADATA_KEY]["width"] == 16
    floor = bpy.data.objects["Floor"]
    floor.data.uv_layers.remove(floor.data.uv_layers["UVMap"])
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    refused = run_cli("bake", path, "--storage", "texel", "--resolution", "16", "--no-new-uv-map")
    assert refused.returncode == 1 and "choose one of its UV maps (none)" in refused.stderr


def test_per_vertex_validation_names_texel_bakes(empty_scene, prt):
    """(The installed add-on's InputError is its own class, hence Exception.)"""
    floor_quad()
    ball()
    run_bake(["Floor"], mode="unshadowed", storage="texel", resolution=16, uv_map="UVMap")
    with pytest.raises(Exception, match=r"nothing to validate: mesh '.*' is baked per texel, not per vertex: "
                                         r"compare it with `prt validate --image`"):
        prt.validation.Validation(bpy.context, 8, 2, ["Floor"])


def test_interreflected_texels_gather_the_vertices_bounced_light_and_agree_with_cycles(empty_scene, tmp_path, prt):
    """A white floor of one quad beside a white wall of one quad: per vertex the floor has four values; per texel
    it holds the light the wall bounces onto it, which Cycles (with as many bounces) agrees with in the image."""
    floor = floor_quad()
    bpy.ops.mesh.primitive_plane_add(size=4, location=(0, 2, 2), rotation=(math.pi / 2, 0, 0))
    wall = bpy.context.object
    wall.name = "Wall"
    white = principled_material("White", (1.0, 1.0, 1.0))
    for ob in (floor, wall):
        ob.data.materials.append(white)
    view = camera(location=(0.0, -6.0, 3.0), rotation=(1.2, 0.0, 0.0))
    bpy.context.scene.camera = view
    run_bake(["Floor", "Wall"], mode="shadowed", samples=128, storage="texel", resolution=32, uv_map="UVMap")
    shadowed, _ = texel_maps.read_planes(floor.data)
    scene_bake = SceneBake(bpy.context, bake.BakeSettings(order=ORDER, mode="interreflected", samples=128,
                                                          bounces=2), ["Floor", "Wall"],
                           storage_options={"storage": "texel", "resolution": 32, "uv_map": "UVMap"})
    scene_bake.run()
    bounced, meta = texel_maps.read_planes(floor.data)
    assert meta["mode"] == "interreflected" and meta["bounces"] == 2
    x, y = texel_centres(meta)
    near_wall = y > 1.5
    gained = (bounced[0] - shadowed[0])[near_wall] / Y00
    assert gained.mean() > 0.05  # the wall's light, which the shadowed bake has not
    report = prt.image_validation.validate_image(bpy.context, "Camera", samples=32, resolution=(48, 36))
    print(f"gained {gained.mean():.3f}; {report.line()}")
    assert report.comparison.error < 0.03


def test_prt_validate_image_from_the_command_line_writes_its_report_and_heatmap(empty_scene, tmp_path):
    floor_quad()
    ball(height=0.8)
    bpy.context.scene.camera = camera()
    run_bake(["Floor", "Ball"], storage="auto")
    path = tmp_path / "lit.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    out = run_cli("validate", path, "--image", "--camera", "Camera", "--resolution", "24x18", "--samples", "4",
                  "--heatmap", tmp_path / "error.png", "--report", tmp_path / "image.json")
    assert out.returncode == 0, out.stderr
    assert "PRT validate --image: camera 'Camera', 24 × 18, " in out.stdout
    report = json.loads((tmp_path / "image.json").read_text())
    assert report["resolution"] == [24, 18] and report["pixels"] > 50
    assert 0.0 <= report["rel_rms_error"] < 0.2  # the display shows the PRT colours: its relighting handlers ran
    assert (tmp_path / "error.png").exists()
    wrong = run_cli("validate", path, "--image", "--resolution", "24by18")
    assert wrong.returncode != 0 and "resolution must be WIDTHxHEIGHT, not '24by18'" in wrong.stderr


def test_the_storage_panel_and_the_stored_bake_panel_draw_a_texel_object(empty_scene):
    from conftest import FakeLayout

    class Layout(FakeLayout):
        def prop_search(self, data, name, search_data, search_name, **kwargs):
            assert search_name in search_data.bl_rna.properties
            self.prop(data, name)

        def label(self, text="", **kwargs):
            self.drawn.append(text)

    floor = floor_quad()
    run_bake(["Floor"], mode="unshadowed", storage="texel", resolution=16, uv_map="UVMap")
    bpy.context.view_layer.objects.active = floor
    drawn = []
    for panel in (bpy.types.PRT_PT_storage, bpy.types.PRT_PT_bake_info):
        panel.draw(type("Panel", (), {"layout": Layout(drawn)})(), bpy.context)
    assert {"prt_storage", "prt_resolution", "prt_texel_size", "prt_uv_map", "prt_new_uv_map"} <= set(drawn)
    assert "Per texel: 16 × 16 in 'UVMap'" in drawn
