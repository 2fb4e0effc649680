"""A dynamic object lit per vertex through the probes (Probe Light: Per Vertex) in glTF and in the browser viewer.

The scene is tests/test_gltf_probes.py's (a floor, a wall, a probe volume over both, a dynamic Suzanne in the wall's
shadow under a sun), with Suzanne lit per vertex. Truth for the file: each vertex's light rebuilt from the file
alone by the README's layout (core.probe_grid, core.rotation); for the viewer's numbers: the same through
core.probe_grid with fixed inputs, run by node; for the viewer's picture: Blender's Workbench render of the PRT
display, per vertex, at the placement the viewer reports, in Debian's headless chromium.
"""

import json
import subprocess

import bpy
import numpy as np
import pytest

from conftest import ROOT
from gltf_files import accessor, exported, light_from_extras, read_glb
from test_gltf_probes import (ORDER, START, TO_GLTF, browser, compare, node_matrix, probe_file, probe_glb,
                              suzannes_colours, view_floats, viewer_matrix)
from browser import open_viewer, viewer_state
from prt_addon.blender import probe_volumes
from prt_addon.commands.view import VIEWER, address, start_server, stop_server
from prt_addon.core import probe_grid, rotation, sh, shading

__all__ = ["browser", "probe_file", "probe_glb"]  # fixtures this module uses from test_gltf_probes


@pytest.fixture(scope="module")
def vertex_file(probe_file, tmp_path_factory):
    """The baked scene with Suzanne lit per vertex: a display setting, so the same bake."""
    bpy.ops.wm.open_mainfile(filepath=str(probe_file))
    bpy.data.objects["Suzanne"].prt_probe_light = "vertex"
    path = tmp_path_factory.mktemp("gltf_probe_vertices") / "vertices.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    return path


@pytest.fixture(scope="module")
def vertex_glb(vertex_file):
    return exported(vertex_file, "; dynamic: Suzanne; lit per vertex: Suzanne; probe volumes: PRT Probe Volume;")


def shaded_per_vertex(volumes, positions, transfer, channels, light, turn, order) -> np.ndarray:
    """(V, 3) by the README's rules: each point's light through the smallest cube holding it (trilinear over the
    valid probes), else the distant light, to the transfer's `order` (zeros above, or cut), turned into the object's
    frame, shading its transfer row."""
    n2 = order * order
    rows = transfer[:, :n2] if channels == 1 else transfer[:, :3 * n2].reshape(-1, 3, n2)
    found = []
    for point, row in zip(positions, rows):
        arriving, smallest = light, None
        for placement, resolution, valid, matrices in volumes:
            local = np.linalg.solve(placement[:3, :3], point - placement[:3, 3])
            size = abs(np.linalg.det(placement[:3, :3]))
            if np.all(np.abs(local) <= 1.0) and (smallest is None or size < smallest):
                indices, weights = probe_grid.trilinear_weights(local, resolution, valid)
                arriving = probe_grid.blend(probe_grid.probe_lights(matrices, light), indices, weights)
                smallest = size
        found.append(shading.shade(row[None], rotation.rotate(sh.fitted(arriving, n2), turn.T))[0])
    return np.array(found)


def test_the_viewers_per_vertex_light_is_the_add_ons():
    """viewer/probes.js vertexRadiance against core.probe_grid and core.rotation: two nested volumes (the smaller
    takes its points), invalid probes, points outside both, grey and coloured transfer, to the probes' received
    order and below it."""
    rng = np.random.default_rng(5)
    volumes, request = [], []
    for scale, resolution in ((np.diag([3.0, 2.0, 2.5]), (3, 2, 4)), (np.diag([0.8, 0.9, 0.7]), (2, 3, 2))):
        count = int(np.prod(resolution))
        placement = np.eye(4)
        placement[:3, :3] = rotation.quaternion_to_matrix(rng.normal(size=4)) @ scale
        placement[:3, 3] = rng.normal(size=3) * 0.2
        valid = rng.random(count) > 0.25
        matrices = rng.normal(size=(count, 3, 25, 9)).astype(np.float32)  # order 3 to order 5
        volumes.append((placement, resolution, valid, matrices.astype(np.float64)))
        request.append({"volume": {"name": f"V{len(request)}", "order": 3, "received_order": 5, "channels": 3,
                                   "resolution": list(resolution), "valid": valid.astype(int).tolist(),
                                   "placement": placement.ravel().tolist()},
                        "matrices": matrices.ravel().tolist()})
    positions = np.vstack([rng.uniform(-3.5, 3.5, size=(300, 3)), rng.uniform(-0.8, 0.8, size=(100, 3))])
    light, turn = rng.normal(size=(3, 9)), rotation.quaternion_to_matrix(rng.normal(size=4))
    for channels, order in ((1, 5), (3, 5), (1, 3)):
        stride = 4 * -(-channels * order * order // 4)
        transfer = rng.normal(size=(len(positions), stride)).astype(np.float32)
        done = subprocess.run(["node", str(ROOT / "tests" / "js" / "probe_radiance.mjs")], input=json.dumps({
            "volumes": request, "positions": positions.ravel().tolist(), "transfer": transfer.ravel().tolist(),
            "stride": stride, "channels": channels, "light": light.tolist(), "turn": turn.tolist(), "order": order}),
            capture_output=True, text=True, timeout=60, check=True, cwd=VIEWER)
        got = np.array(json.loads(done.stdout)).reshape(-1, 3)
        expected = shaded_per_vertex(volumes, positions, transfer.astype(np.float64), channels, light, turn, order)
        np.testing.assert_allclose(got, expected, atol=1e-4 * np.abs(expected).max())  # float32 results
    inside = [np.all(np.abs(np.linalg.solve(placement[:3, :3], (positions - placement[:3, 3]).T)) <= 1.0, axis=0)
              for placement, *_ in volumes]
    assert (inside[1] & inside[0]).sum() > 5 and (inside[0] & ~inside[1]).sum() > 5 and (~inside[0]).sum() > 5


def test_the_file_flags_per_vertex_light_and_colour_0_holds_it(vertex_glb, probe_glb):
    """COLOR_0 holds the display's per-vertex shading, which the file alone rebuilds; it differs from the shading
    at the centre (the other export)."""
    document, binary = read_glb(vertex_glb)
    extras = document["scenes"][0]["extras"]["prt"]
    volume = extras["probe_volumes"][0]
    node = next(node for node in document["nodes"] if node.get("name") == "Suzanne")
    mesh = document["meshes"][node["mesh"]]
    prt = mesh["extras"]["prt"]
    assert (prt["dynamic"], prt["probe_light"], prt["light_order"], prt["order"]) == \
        (True, "vertex", ORDER, volume["received_order"])
    attributes = mesh["primitives"][0]["attributes"]
    accessors = {name: accessor(document, binary, index) for name, index in attributes.items()}
    transfer = np.hstack([accessors[name] for name in mesh["extras"]["prt"]["attributes"]])
    world = node_matrix(node)
    positions = accessors["POSITION"] @ world[:3, :3].T + world[:3, 3]
    matrices = view_floats(document, binary, volume["bufferView"]).reshape(volume["probes"], 1, prt["order"] ** 2,
                                                                           ORDER ** 2)
    volumes = [(np.reshape(volume["placement"], (4, 4)), volume["resolution"], np.array(volume["valid"]) != 0,
                matrices.astype(np.float64))]
    turn = world[:3, :3] / np.linalg.norm(world[:3, :3], axis=0)
    shown = shaded_per_vertex(volumes, positions, transfer, 1, light_from_extras(extras, ORDER), turn, prt["order"])
    colours = accessors["COLOR_0"][:, :3]
    assert np.abs(np.clip(shown, 0.0, 1.0) - colours).max() < 2e-5  # linear, clipped to 0-1, 16-bit
    at_centre = suzannes_colours(probe_glb)
    print(f"Suzanne at {START}: per vertex against at her centre, mean {colours.mean():.4f} against "
          f"{at_centre.mean():.4f}, largest difference {np.abs(colours - at_centre).max():.4f}")
    assert np.abs(colours - at_centre).max() > 0.05


def test_the_viewer_lights_the_dynamic_object_per_vertex_as_blender(vertex_file, vertex_glb, browser, tmp_path):
    server = start_server(VIEWER, str(vertex_glb))
    try:
        page = open_viewer(browser, f"{address(server)}?textures=0&readout=0&outline=0", (320, 240))
        state = viewer_state(page)
        assert state["moving"]["volume"] == "PRT Probe Volume"
        assert "lit per vertex by the probes of PRT Probe Volume" in state["readout"]
        before = compare(vertex_file, page, tmp_path, "start", viewer_matrix(page))
        for key in ["ArrowRight"] * 3 + ["BracketLeft"] * 3 + ["PageUp"]:
            page.keyboard.press(key)
        compare(vertex_file, page, tmp_path, "beside the wall", viewer_matrix(page))
        for key in ["ArrowRight"] * 9:
            page.keyboard.press(key)
        after = compare(vertex_file, page, tmp_path, "moved", viewer_matrix(page))
        assert after > 1.2 * before  # out of the wall's shadow
    finally:
        stop_server(server)


def test_a_volume_moved_since_its_bake_is_exported_where_it_was_baked_with_a_note(vertex_file, prt, tmp_path):
    """As the display lights from it: its probes where they were baked."""
    bpy.ops.wm.open_mainfile(filepath=str(vertex_file))
    volume = bpy.data.objects["PRT Probe Volume"]
    baked = np.reshape(volume[probe_volumes.METADATA_KEY]["placement"], (4, 4))
    volume.location.x += 1.0
    bpy.context.view_layer.update()
    done = prt.gltf.export(bpy.context.scene, str(tmp_path / "moved.glb"), "web")
    assert "probe volume 'PRT Probe Volume': moved or scaled since its bake; exported where it was baked" in \
        done["notes"]
    document, _ = read_glb(tmp_path / "moved.glb")
    exported_at = document["scenes"][0]["extras"]["prt"]["probe_volumes"][0]["placement"]
    np.testing.assert_allclose(np.reshape(exported_at, (4, 4)), TO_GLTF @ baked, atol=1e-12)
