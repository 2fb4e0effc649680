"""The bake as users run it: the operator of the installed add-on, storage, undo, bad input, the CLI."""

import json
import math
import os
import signal
import subprocess
import sys

import bpy
import numpy as np
import pytest

from conftest import ROOT, run_cli
from interrupts import ctrl_c_reaches
from prt_addon.blender import storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import lobes
from prt_addon.core.bake import BakeSettings
from prt_addon.core.errors import InputError, StaleBake

COEFFICIENT_NAMES = [f"_prt_t{j:02d}" for j in range(6)]  # order 4: 16 coefficients, 3 per attribute


def add_mesh(name, vertices, faces, location=(0.0, 0.0, 0.0)):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in vertices], [], [tuple(f) for f in faces])
    mesh.update()
    ob = bpy.data.objects.new(name, mesh)
    ob.location = location
    bpy.context.collection.objects.link(ob)
    return ob


def grid(name, size=4.0, cuts=8, z=0.0):
    """A square of (cuts+1)² vertices facing +Z."""
    ticks = np.linspace(-size / 2, size / 2, cuts + 1)
    vertices = [(x, y, z) for y in ticks for x in ticks]
    faces = [(r * (cuts + 1) + c, r * (cuts + 1) + c + 1, (r + 1) * (cuts + 1) + c + 1, (r + 1) * (cuts + 1) + c)
             for r in range(cuts) for c in range(cuts)]
    return add_mesh(name, vertices, faces)


def box(name, half=0.5, location=(0.0, 0.0, 1.0)):
    v = [(x, y, z) for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return add_mesh(name, v, faces, location)


def select(*objects):
    names = {ob.name for ob in objects}
    for ob in bpy.data.objects:  # the view layer lists new objects only after an update
        ob.select_set(ob.name in names)


def bake(**settings):
    scene_settings = bpy.context.scene.prt_bake
    for key, value in {"order": 4, "samples": 64, "mode": "shadowed", **settings}.items():
        setattr(scene_settings, key, value)
    return bpy.ops.prt.bake()


def transfer_of(ob):
    return storage.read_transfer(ob.data)


def test_bake_stores_attributes_and_metadata(empty_scene):
    floor, cube = grid("Floor"), box("Cube")
    select(floor)
    assert bake() == {"FINISHED"}
    names = [a.name for a in floor.data.attributes if a.name.startswith("_prt_")]
    assert sorted(names) == sorted(COEFFICIENT_NAMES + ["_prt_error", "_prt_rule"])
    assert all(floor.data.attributes[n].domain == "POINT" for n in names)
    transfer, meta = transfer_of(floor)
    assert transfer.shape == (81, 16) and transfer.dtype == np.float32
    assert meta["order"] == 4 and meta["mode"] == "shadowed" and meta["vertex_count"] == 81
    assert meta["rays"] > 0 and 0 < meta["est_rms_rel_error"] <= meta["est_max_rel_error"] < 1
    assert "prt" not in cube.data  # not selected: an occluder only
    # The vertex under the cube is darker under a constant sky than an open corner; the corner is exact.
    centre, corner = 40, 0
    assert transfer[centre, 0] < 0.8 * transfer[corner, 0]
    open_value = lobes.cosine_transfer(4, np.array([[0.0, 0.0, 1.0]]))[0]
    assert abs(transfer[corner, 0] - open_value[0]) < 0.02


def test_unselected_scene_bakes_every_visible_mesh_and_hidden_ones_do_not_occlude(empty_scene):
    floor, cube = grid("Floor"), box("Cube")
    select()
    cube.hide_set(True)
    assert bake() == {"FINISHED"}
    assert "prt" in floor.data and "prt" not in cube.data
    transfer, meta = transfer_of(floor)
    assert meta["skipped_vertices"] == 81  # nothing visible above a flat floor: exact, no rays
    # and the user is told that nothing else was there to cast shadows
    scene_bake = SceneBake(bpy.context, BakeSettings(samples=16), ["Floor"])
    assert any("no visible mesh besides the receivers" in note for note in scene_bake.notes)
    np.testing.assert_allclose(transfer, np.tile(lobes.cosine_transfer(4, np.array([[0, 0, 1.0]])), (81, 1)),
                               atol=1e-6)


def test_flat_objects_become_closed_form_occluders_in_world_space(empty_scene):
    grid("Floor")
    box("Cube", location=(3.0, 0.0, 1.0))
    shelf = grid("Shelf", size=1.0, cuts=3)
    shelf.location, shelf.rotation_euler = (0.0, 0.0, 1.5), (np.pi, 0.0, 0.0)  # facing down at the floor
    hidden = grid("Hidden", size=8.0)
    hidden.hide_set(True)
    occluders = SceneBake(bpy.context, BakeSettings(samples=16), ["Floor"]).plan.occluders
    floor_corners, shelf_corners = occluders.polygons  # the largest first; not the cube, not the hidden plane
    assert len(floor_corners) == len(shelf_corners) == 4
    np.testing.assert_allclose(sorted(map(tuple, floor_corners)),
                               [(-2, -2, 0), (-2, 2, 0), (2, -2, 0), (2, 2, 0)], atol=1e-6)
    np.testing.assert_allclose(sorted(map(tuple, shelf_corners)),
                               [(-0.5, -0.5, 1.5), (-0.5, 0.5, 1.5), (0.5, -0.5, 1.5), (0.5, 0.5, 1.5)], atol=1e-6)


def test_array_modifier_copies_cast_shadows(empty_scene):
    floor, cube = grid("Floor"), box("Cube", location=(-1.5, 0.0, 0.7), half=0.3)
    array = cube.modifiers.new("Array", "ARRAY")
    array.count, array.relative_offset_displace = 2, (5.0, 0.0, 0.0)  # the copy sits above x = +1.5
    select(floor)
    bake()
    transfer, _ = transfer_of(floor)
    positions = np.array([v.co[:] for v in floor.data.vertices])
    under_copy = np.argmin(np.linalg.norm(positions - [1.5, 0.0, 0.0], axis=1))
    mirror = np.argmin(np.linalg.norm(positions - [0.0, 1.5, 0.0], axis=1))
    assert transfer[under_copy, 0] < 0.8 * transfer[mirror, 0]


def test_rebake_replaces_and_undo_restores(empty_scene):
    floor, _ = grid("Floor"), box("Cube")
    select(floor)
    bake(order=4)
    first, _ = transfer_of(floor)
    bpy.ops.ed.undo_push(message="order 4")  # from Python, steps are pushed explicitly, as the UI does
    bake(order=2)
    assert [a.name for a in floor.data.attributes if a.name.startswith("_prt_t")] == ["_prt_t00", "_prt_t01"]
    assert transfer_of(floor)[1]["order"] == 2
    bpy.ops.ed.undo_push(message="order 2")
    bpy.ops.ed.undo()
    floor = bpy.data.objects["Floor"]
    restored, meta = transfer_of(floor)
    assert meta["order"] == 4
    np.testing.assert_array_equal(restored, first)


def test_saved_file_keeps_everything(empty_scene, tmp_path):
    floor, _ = grid("Floor"), box("Cube")
    select(floor)
    bake()
    before, meta_before = transfer_of(floor)
    path = str(tmp_path / "baked.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    after, meta_after = transfer_of(bpy.data.objects["Floor"])
    np.testing.assert_array_equal(before, after)
    assert meta_before == meta_after


@pytest.mark.parametrize("workers", [1, 2])
def test_cancelled_bake_leaves_previous_data_exactly(empty_scene, workers):
    floor, _ = grid("Floor", cuts=40), box("Cube")
    select(floor)
    bake(order=3)
    before, meta_before = transfer_of(floor)
    scene_bake = SceneBake(bpy.context, BakeSettings(order=4, samples=4096), ["Floor"], workers=workers)
    scene_bake.executor.min_rays, scene_bake.executor.start_s = 0, 0.0
    assert not scene_bake.step(0.05)  # part of the work, as the modal operator does per timer event
    scene_bake.cancel()
    after, meta_after = transfer_of(floor)
    np.testing.assert_array_equal(before, after)
    assert meta_before == meta_after and meta_after["order"] == 3


def test_stale_bake_is_detected(empty_scene):
    floor, _ = grid("Floor"), box("Cube")
    select(floor)
    bake()
    floor.data.vertices.add(1)
    with pytest.raises(StaleBake, match="Floor.*81 vertices.*82"):
        transfer_of(floor)


# -- bad input: a clear message naming the object, the others still bake, nothing lost -----------------
def _faceless():
    return add_mesh("Points", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [])


def _non_finite():
    ob = grid("Broken", size=1.0, cuts=2, z=3.0)
    ob.data.vertices[4].co = (math.nan, 0.0, math.inf)
    return ob


def _topology_modifier():
    ob = box("Subdivided", location=(3.0, 3.0, 1.0))
    ob.modifiers.new("Subdivision", "SUBSURF")
    return ob


def _shared_mesh():
    ob = box("Twin", location=(-3.0, -3.0, 1.0))
    ob.data = bpy.data.objects["Floor"].data
    return ob


@pytest.mark.parametrize("make_bad, words", [
    (_faceless, "has no faces"),
    (_non_finite, "non-finite"),
    (_topology_modifier, "modifiers change the vertex or face corner count"),
    (_shared_mesh, "shares its mesh"),
])
def test_bad_object_is_named_and_others_still_bake(empty_scene, make_bad, words):
    floor, cube = grid("Floor"), box("Cube")
    select(cube)
    bake()
    cube_before, meta_before = transfer_of(cube)
    bad = make_bad()
    scene_bake = SceneBake(bpy.context, BakeSettings(samples=16), ["Floor", bad.name])
    scene_bake.run(log=lambda line: None)
    assert "prt" in floor.data
    if bad.data is not floor.data:
        assert "prt" not in bad.data
    cube_after, meta_after = transfer_of(cube)  # an earlier bake elsewhere is untouched
    np.testing.assert_array_equal(cube_before, cube_after)
    assert meta_before == meta_after
    assert len(scene_bake.problems) == 1
    assert f"{bad.name!r}" in scene_bake.problems[0] and words in scene_bake.problems[0]


def test_loose_and_degenerate_vertices_get_zero_transfer_with_a_note(empty_scene):
    ob = add_mesh("Mixed", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (5, 5, 5), (2, 2, 0), (2, 2, 0), (2, 2, 0)],
                  [(0, 1, 2), (4, 5, 6)])
    scene_bake = SceneBake(bpy.context, BakeSettings(samples=16), ["Mixed"])
    scene_bake.run(log=lambda line: None)
    transfer, _ = transfer_of(ob)
    assert np.all(transfer[3:] == 0) and np.all(transfer[:3, 0] > 0.2)
    assert any("'Mixed'" in n and "4 vertices are loose" in n for n in scene_bake.notes)


def test_edit_mode_and_bad_settings_are_refused_before_any_work(empty_scene):
    floor = grid("Floor")
    with pytest.raises(InputError, match="order must be 1-16"):
        SceneBake(bpy.context, BakeSettings(order=17), ["Floor"])
    bpy.context.view_layer.objects.active = floor
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        with pytest.raises(InputError, match="'Floor' is in Edit Mode"):
            SceneBake(bpy.context, BakeSettings(), ["Floor"])
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")


# -- command line --------------------------------------------------------------------------------------
def test_cli_help_lists_the_commands():
    result = run_cli("--help")
    assert result.returncode == 0
    for command in ("bake", "export", "demo"):
        assert command in result.stdout


@pytest.mark.parametrize("args, words", [
    (("bake", "no_such_file.blend"), "no such file"),
    (("bake", "{suzanne}", "--order", "17", "--output", "x.blend"), "order must be"),
    (("bake", "{suzanne}", "--objects", "Nobody"), "no object named 'Nobody'"),
    (("frobnicate",), "invalid choice"),
])
def test_cli_failures_exit_1_with_one_line(args, words, sample_scene_files):
    result = run_cli(*(arg.format(suzanne=sample_scene_files / "suzanne.blend") for arg in args))
    assert result.returncode == 1
    lines = [line for line in result.stderr.splitlines() if line.startswith("prt:")]
    assert len(lines) == 1 and words in lines[0], result.stderr


def test_cli_bake_interrupted_exits_1_with_one_line_and_leaves_the_file(tmp_path, sample_scene_files):
    """Ctrl+C (or a farm's SIGINT) during a bake with forked workers: exit 1, one line, the file as it was."""
    path = tmp_path / "suzanne.blend"
    path.write_bytes((sample_scene_files / "suzanne.blend").read_bytes())
    before = path.read_bytes()
    command = [sys.executable, "-m", "prt_addon", "bake", str(path), "--samples", "16384", "--workers", "2"]
    process = subprocess.Popen(command, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_reaches)
    try:
        for line in process.stdout:  # the bake is under way once it reports progress
            if "left" in line:
                break
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=120)
    finally:
        process.kill()
    errors = [line for line in stderr.splitlines() if line.startswith("prt: error")]
    assert process.returncode == 1 and errors == ["prt: error: cancelled; nothing was written"], stderr
    assert path.read_bytes() == before


def test_cli_bake_report_and_export(tmp_path, sample_scene_files):
    out, report, npz = tmp_path / "out.blend", tmp_path / "r.json", tmp_path / "t.npz"
    result = run_cli("bake", sample_scene_files / "suzanne.blend", "--objects", "Plane", "--order", "3",
                     "--samples", "32", "--workers", "2", "--output", out, "--report", report)
    assert result.returncode == 0, result.stderr
    assert "left" in result.stdout and "PRT bake: 1 objects, 441 vertices" in result.stdout
    data = json.loads(report.read_text())
    for key in ("objects", "vertices", "order", "mode", "samples", "rays", "skipped_vertices", "time_s",
                "rays_per_s", "est_rms_rel_error", "est_max_rel_error"):
        assert key in data
    assert data["objects"] == ["Plane"] and data["vertices"] == 441 and data["order"] == 3
    assert data["rays"] == 32 * (441 - data["skipped_vertices"]) and data["rays_per_s"] > 0
    result = run_cli("export", out, "--object", "Plane", "--npz", npz)
    assert result.returncode == 0, result.stderr
    exported = np.load(npz)
    assert exported["transfer"].shape == (441, 1, 9) and exported["positions"].shape == (441, 3)
    assert json.loads(str(exported["metadata"]))["order"] == 3
    # Under Suzanne the plane is shadowed: its darkest vertex is well below the open sky value.
    assert exported["transfer"][:, 0, 0].min() < 0.7 * exported["transfer"][:, 0, 0].max()
