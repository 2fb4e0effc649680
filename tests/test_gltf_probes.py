"""Probe volumes and dynamic objects in glTF, and the browser viewer moving a dynamic object through the probes.

The scene: a floor, a wall, a probe volume over both and a dynamic Suzanne in the wall's shadow under a sun, baked
shadowed. Truth for the file: the add-on's own display (blender.relighting) at the same placement, rebuilt from the
file alone by the README's layout; for the viewer: Blender's Workbench render of the PRT display at the placement the
viewer reports, in Debian's headless chromium. The viewer's probe light is also checked against core.probe_grid and
core.rotation with fixed numbers through node.
"""

import copy
import json
import math
import subprocess

import bpy
import numpy as np
import pytest
from mathutils import Matrix

from browser import chromium, open_viewer, viewer_state
from conftest import ROOT, add_light
from gltf_files import (accessor, baked_and_saved, exported, extras_problems, light_from_extras, read_glb,
                        validator_issues)
from pictures import inner_pixels, read_png, rms_over_objects, shot
from prt_addon.blender import probe_volumes
from prt_addon.blender.relighting import Relighter, bounds_centre
from prt_addon.blender.render import render
from prt_addon.commands.view import VIEWER, address, start_server, stop_server
from prt_addon.core import bake, gltf_pack, gltf_probes, probe_grid, probe_transfer, rotation, shading

SIZE = (320, 240)
MAX_RMS = 0.02  # as tests/test_gltf.py: the viewer's picture against Blender's render, RMS over pixels (sRGB, 0-1)
# Over Suzanne's pixels alone: her eyes, brows and ears are edges in depth inside her outline, where two rasterisers'
# anti-aliasing differ pixel by pixel (1.8-2.1 % seen); a wrong light would move her mean, which must stay within 0.5 %.
MAX_RMS_SUZANNE, MAX_MEAN_SUZANNE = 0.03, 0.005
ORDER = 4
RECEIVED = probe_transfer.received_order(ORDER)  # the probes' arriving light, and the dynamic transfer's order
START = (-1.3, 0.0, 0.6)  # Suzanne in the wall's shadow (the sun shines from +X)
TO_GLTF = np.diag([1.0, 1.0, 1.0, 1.0])
TO_GLTF[:3, :3] = gltf_pack.Z_UP_TO_Y_UP


@pytest.fixture(scope="module")
def probe_file(addon, tmp_path_factory):
    """The floor (8 × 8, a grid, so its shadow shows), the wall (x −0.2..0.2, y −2..2, z 0..3), a probe volume of 7 × 2 × 3 probes over x −3.5..3.5 (those at x = 0 in the wall),
    a dynamic Suzanne (scale 0.4, lit at its centre) turned a little, a camera, a sun from +X and a sky; baked shadowed at order 4."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=32, y_subdivisions=32, size=8.0)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.5), scale=(0.4, 4.0, 3.0))
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    volume.location, volume.scale, volume.empty_display_size = (0.0, 0.0, 1.0), (3.5, 1.0, 0.9), 1.0
    volume.prt_probe_resolution = (7, 2, 3)
    bpy.ops.mesh.primitive_monkey_add(size=1.0, location=START, rotation=(0.0, 0.0, -0.6), scale=(0.4,) * 3)
    bpy.ops.object.shade_smooth()
    bpy.context.object.prt_dynamic = True
    bpy.context.object.prt_probe_light = "centre"  # as the viewer and COLOR_0 light it
    bpy.ops.object.camera_add(location=(0.0, -7.5, 3.0), rotation=(math.radians(72), 0.0, 0.0))
    bpy.context.scene.camera = bpy.context.object
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = SIZE
    bpy.ops.object.select_all(action="DESELECT")
    add_light("SUN", theta=1.0, phi=0.0, angular_radius=0.1, strength=2.0)
    add_light("SKY", strength=0.2)
    bpy.context.scene.prt_active_light = 0
    return baked_and_saved(bake.BakeSettings(order=ORDER, mode="shadowed", samples=256),
                           tmp_path_factory.mktemp("gltf_probes") / "probes.blend")


@pytest.fixture(scope="module")
def probe_glb(probe_file):
    return exported(probe_file, "; dynamic: Suzanne; probe volumes: PRT Probe Volume;")


@pytest.fixture(scope="module")
def browser():
    with chromium() as started:
        yield started


def view_floats(document, binary, index) -> np.ndarray:
    view = document["bufferViews"][index]
    start = view.get("byteOffset", 0)
    return np.frombuffer(bytes(binary[start: start + view["byteLength"]]), dtype=np.float32)


def node_matrix(node) -> np.ndarray:
    """(4, 4) a glTF node's local matrix from its translation, rotation (x, y, z, w) and scale."""
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    turn = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    matrix = np.eye(4)
    matrix[:3, :3] = turn * np.asarray(node.get("scale", (1.0, 1.0, 1.0)))
    matrix[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return matrix


# -- the layout ----------------------------------------------------------------------------------------------
def test_probe_matrices_and_placement_turn_into_gltfs_frame():
    """T maps light to light: in glTF's frame T_g L_g is (T L) turned, for any light; the placement puts the probes
    at the Blender positions turned."""
    rng = np.random.default_rng(3)
    matrices, light = rng.normal(size=(5, 3, 16, 16)), rng.normal(size=(3, 16))
    turned = gltf_probes.matrices_to_gltf(matrices)
    arriving = np.einsum("pcij,cj->pci", matrices, light)
    np.testing.assert_allclose(np.einsum("pcij,cj->pci", turned, gltf_pack.to_gltf_frame(light)),
                               gltf_pack.to_gltf_frame(arriving), atol=1e-12)
    placement = np.eye(4)
    placement[:3, :3], placement[:3, 3] = rng.normal(size=(3, 3)), rng.normal(size=3)
    resolution = (3, 2, 4)
    np.testing.assert_allclose(probe_grid.probe_positions(gltf_probes.placement_to_gltf(placement), resolution),
                               probe_grid.probe_positions(placement, resolution) @ gltf_pack.Z_UP_TO_Y_UP.T,
                               atol=1e-12)


def test_the_file_carries_the_probes_and_flags_the_dynamic_object(probe_file, probe_glb):
    document, binary = read_glb(probe_glb)
    extras = document["scenes"][0]["extras"]["prt"]
    (volume,) = extras["probe_volumes"]
    assert set(extras["probe_convention"]) == {"matrices", "placement", "interpolation"}
    bpy.ops.wm.open_mainfile(filepath=str(probe_file))
    empty = bpy.data.objects["PRT Probe Volume"]
    stored, meta = probe_volumes.read(empty), empty[probe_volumes.METADATA_KEY]
    assert (volume["name"], volume["resolution"], volume["order"], volume["received_order"], volume["channels"],
            volume["probes"]) == ("PRT Probe Volume", [7, 2, 3], ORDER, RECEIVED, 1, 42)
    assert volume["bake"]["bake_id"] == meta["bake_id"] and volume["bake"]["layout"] == probe_volumes.PROBE_LAYOUT
    assert volume["valid"] == stored.valid.astype(int).tolist() and sum(volume["valid"]) == 36  # the wall holds 6
    matrices = view_floats(document, binary, volume["bufferView"]).reshape(42, 1, RECEIVED ** 2, ORDER ** 2)
    np.testing.assert_allclose(matrices, gltf_probes.matrices_to_gltf(stored.matrices), atol=1e-6)
    np.testing.assert_allclose(np.reshape(volume["placement"], (4, 4)),
                               TO_GLTF @ np.reshape(meta["placement"], (4, 4)), atol=1e-12)
    flags = {mesh["name"]: mesh["extras"]["prt"].get("dynamic", False) for mesh in document["meshes"]}
    assert flags == {"Grid": False, "Cube": False, "Suzanne": True}
    orders = {mesh["name"]: (mesh["extras"]["prt"]["order"], mesh["extras"]["prt"].get("light_order"))
              for mesh in document["meshes"]}
    assert orders == {"Grid": (ORDER, None), "Cube": (ORDER, None), "Suzanne": (RECEIVED, ORDER)}
    # read_glb found the extras as the manual describes them; a volume of another layout it would refuse
    changed = copy.deepcopy(document)
    changed["scenes"][0]["extras"]["prt"]["probe_volumes"][0]["layout"] = gltf_probes.LAYOUT + 1
    assert extras_problems(changed)


def test_the_file_alone_gives_the_dynamic_objects_colours_as_blenders_display(probe_file, probe_glb):
    """By the README's layout alone: the light at Suzanne's bounding box centre through the exported probes, turned
    into its node's frame, shades its exported transfer to the colours Blender's display shows (COLOR_0 carries
    those, 16-bit)."""
    document, binary = read_glb(probe_glb)
    extras = document["scenes"][0]["extras"]["prt"]
    volume = extras["probe_volumes"][0]
    node = next(node for node in document["nodes"] if node.get("name") == "Suzanne")
    mesh = document["meshes"][node["mesh"]]
    attributes = mesh["primitives"][0]["attributes"]
    accessors = {name: accessor(document, binary, index) for name, index in attributes.items()}
    transfer = np.hstack([accessors[name] for name in mesh["extras"]["prt"]["attributes"]])[:, : RECEIVED ** 2]
    light = light_from_extras(extras, ORDER)
    world = node_matrix(node)
    low, high = (np.array(document["accessors"][attributes["POSITION"]][key]) for key in ("min", "max"))
    centre = world[:3, :3] @ ((low + high) / 2) + world[:3, 3]
    placement = np.reshape(volume["placement"], (4, 4))
    local = np.linalg.solve(placement[:3, :3], centre - placement[:3, 3])
    assert np.all(np.abs(local) <= 1.0)
    indices, weights = probe_grid.trilinear_weights(local, volume["resolution"], np.array(volume["valid"]) != 0)
    matrices = view_floats(document, binary, volume["bufferView"]).reshape(42, 1, RECEIVED ** 2, ORDER ** 2)
    arriving = probe_grid.blend(probe_grid.probe_lights(matrices.astype(np.float64), light), indices, weights)
    turn = world[:3, :3] / np.linalg.norm(world[:3, :3], axis=0)
    shown = shading.shade(transfer, rotation.rotate(arriving, turn.T))
    # COLOR_0 is linear, clipped to 0-1 and 16-bit
    assert np.abs(np.clip(shown, 0.0, 1.0) - accessors["COLOR_0"][:, :3]).max() < 2e-5
    unlit = shading.shade(transfer[:, : ORDER ** 2], rotation.rotate(light, turn.T))
    assert shown.mean() < 0.7 * unlit.mean()  # in the wall's shadow: the probes matter


def suzannes_colours(path) -> np.ndarray:
    document, binary = read_glb(path)
    mesh = next(mesh for mesh in document["meshes"] if mesh["name"] == "Suzanne")
    return accessor(document, binary, mesh["primitives"][0]["attributes"]["COLOR_0"])[:, :3]


def test_a_probe_volume_of_another_layout_is_left_out_with_a_note(probe_file, probe_glb, prt, tmp_path):
    """As the display leaves it out (blender.probe_volumes.read): the dynamic object is then lit by the distant
    light, in the file as in Blender."""
    bpy.ops.wm.open_mainfile(filepath=str(probe_file))
    bpy.data.objects["PRT Probe Volume"][probe_volumes.METADATA_KEY]["layout"] = 99
    done = prt.gltf.export(bpy.context.scene, str(tmp_path / "stale.glb"), "web")
    assert (done["probe_volumes"], done["dynamic"]) == ([], ["Suzanne"])
    assert "probe volume 'PRT Probe Volume' was baked with layout version 99; rebake it: not exported" in done["notes"]
    document, binary = read_glb(tmp_path / "stale.glb")
    assert "probe_volumes" not in document["scenes"][0]["extras"]["prt"]
    assert suzannes_colours(tmp_path / "stale.glb").mean() > 1.3 * suzannes_colours(probe_glb).mean()  # no shadow


def test_gltf_validator_finds_no_error_or_warning(probe_glb):
    issues = validator_issues(probe_glb)
    assert (issues["numErrors"], issues["numWarnings"]) == (0, 0), issues["messages"]


def test_the_viewers_probe_light_is_the_add_ons():
    """viewer/probes.js against core.probe_grid and core.rotation: weights over valid probes only, the blended
    light, points outside the cube, and the light turned into an object's frame."""
    rng = np.random.default_rng(11)
    resolution, channels = (3, 2, 4), 3
    count = int(np.prod(resolution))
    valid = rng.random(count) > 0.3
    placement = np.eye(4)
    placement[:3, :3] = rotation.quaternion_to_matrix(rng.normal(size=4)) @ np.diag([2.0, 1.0, 1.5])
    placement[:3, 3] = rng.normal(size=3)
    matrices = rng.normal(size=(count, channels, 25, 9)).astype(np.float32)  # order 3 to order 5
    light, turn = rng.normal(size=(3, 9)), rotation.quaternion_to_matrix(rng.normal(size=4))
    locals_ = np.vstack([rng.uniform(-1, 1, size=(6, 3)), [[0.99, -0.99, 0.0], [1.2, 0.0, 0.0]]])
    points = locals_ @ placement[:3, :3].T + placement[:3, 3]
    volume = {"name": "V", "order": 3, "received_order": 5, "channels": channels, "resolution": list(resolution),
              "valid": valid.astype(int).tolist(), "placement": placement.ravel().tolist()}
    request = {"volume": volume, "matrices": matrices.ravel().tolist(), "points": points.tolist(),
               "light": light.tolist(), "turn": turn.tolist()}
    done = subprocess.run(["node", str(ROOT / "tests" / "js" / "probe_values.mjs")], input=json.dumps(request),
                          capture_output=True, text=True, timeout=60, check=True, cwd=VIEWER)
    got = json.loads(done.stdout)
    for local, weights, arriving in zip(locals_, got["weights"], got["lights"]):
        if np.any(np.abs(local) > 1.0):
            assert weights is None and arriving is None
            continue
        indices, expected = probe_grid.trilinear_weights(local, resolution, valid)
        assert weights["indices"] == indices.tolist()
        np.testing.assert_allclose(weights["weights"], expected, atol=1e-12)
        lights = probe_grid.probe_lights(matrices.astype(np.float64), light)
        np.testing.assert_allclose(arriving, probe_grid.blend(lights, indices, expected), atol=1e-9)
    np.testing.assert_allclose(got["in_frame"], rotation.rotate(light, turn.T), atol=1e-12)


# -- the viewer against Blender --------------------------------------------------------------------------------
def blender_render(blend, path, matrix_gltf=None, alone=False):
    """Workbench showing the PRT display (no albedo), Suzanne placed by its glTF world matrix (None: as saved);
    `alone`: Suzanne only (its pixels' mask). Transparent film, no dither."""
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    suzanne = bpy.data.objects["Suzanne"]
    if matrix_gltf is not None:
        suzanne.matrix_world = Matrix((np.linalg.inv(TO_GLTF) @ matrix_gltf @ TO_GLTF).tolist())
    for ob in scene.objects:
        ob.hide_render = alone and ob is not suzanne and ob.type == "MESH"
    scene.prt_display.show_prt = True
    bpy.context.view_layer.update()
    Relighter().refresh(scene, bpy.context.evaluated_depsgraph_get())
    scene.render.film_transparent = True
    scene.render.dither_intensity = 0.0
    render(scene, str(path), "WORKBENCH", resolution=SIZE)
    return read_png(path), bounds_centre(suzanne)


def viewer_matrix(page) -> np.ndarray:
    """(4, 4) the moved object's world matrix in glTF's frame, as the viewer holds it (three.js: column-major)."""
    return np.array(viewer_state(page)["moving"]["matrixWorld"]).reshape(4, 4).T


def compare(probe_file, page, tmp_path, name, matrix):
    """Asserts the viewer's picture agrees with Blender's render with Suzanne at `matrix` (glTF's frame); returns
    the mean of Suzanne's pixels in the viewer."""
    reference, centre = blender_render(probe_file, tmp_path / f"blender_{name}.png", matrix)
    alone, _ = blender_render(probe_file, tmp_path / f"alone_{name}.png", matrix, alone=True)
    picture = shot(page, tmp_path / f"viewer_{name}.png")
    whole = rms_over_objects(reference, picture)
    covered = alone[..., 3] > 0.99
    suzanne = rms_over_objects(reference, picture, covered)
    inside = inner_pixels(covered)
    means = picture[..., :3][inside].mean(), reference[..., :3][inside].mean()
    print(f"{name} (Suzanne's centre at {np.round(centre, 3).tolist()}): viewer vs Blender's Workbench render "
          f"{100 * whole:.2f} % RMS over the objects' pixels, {100 * suzanne:.2f} % over Suzanne's "
          f"({int(inside.sum())} pixels), her mean {means[0]:.4f} against {means[1]:.4f}")
    assert whole <= MAX_RMS and suzanne <= MAX_RMS_SUZANNE and abs(means[0] - means[1]) <= MAX_MEAN_SUZANNE
    return means[0]


def test_the_viewer_shades_the_dynamic_object_from_the_probes_as_blender_and_keys_move_it(
        probe_file, probe_glb, browser, tmp_path):
    server = start_server(VIEWER, str(probe_glb))
    try:
        page = open_viewer(browser, f"{address(server)}?textures=0&readout=0&outline=0", SIZE)
        state = viewer_state(page)
        assert state["moving"]["name"] == "Suzanne" and state["moving"]["volume"] == "PRT Probe Volume"
        start = viewer_matrix(page)
        before = compare(probe_file, page, tmp_path, "start", start)
        for key in ["ArrowRight"] * 12 + ["BracketRight"] * 2:
            page.keyboard.press(key)
        moved = viewer_matrix(page)
        step = np.linalg.norm(moved[:3, 3] - start[:3, 3])
        assert moved[0, 3] - start[0, 3] > 2.0 and abs(moved[2, 3] - start[2, 3]) < 0.1 * step  # along +X, out
        turned = math.degrees(math.atan2(moved[0, 2], moved[0, 0]) - math.atan2(start[0, 2], start[0, 0]))
        assert turned % 360 == pytest.approx(330.0, abs=1e-3)  # ] turns −15° about the vertical, twice
        after = compare(probe_file, page, tmp_path, "moved", moved)
        assert "Moving Suzanne" in viewer_state(page)["readout"]
        assert after > 1.2 * before  # out of the wall's shadow, in the viewer as in Blender
    finally:
        stop_server(server)
