"""Checks before any ray (issue 16): what they find in a scene, what they estimate, and that an error stops a bake
before any work is spent, in the interface and on the command line, leaving an earlier bake as it was."""

import importlib
import json
import os

import bpy
import numpy as np
import pytest

from conftest import run_cli
from prt_addon.blender import checks as scene_checks
from prt_addon.blender.execute import first_job
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, checks, engines, estimator
from prt_addon.core.bake import BakeSettings
from test_bake_blender import add_mesh, bake as bake_in_the_panel, box, grid, select, transfer_of

ATTRIBUTE_BYTES = {"FLOAT_VECTOR": 12, "FLOAT": 4, "INT": 4}


def gathered(names, **settings):
    return SceneBake(bpy.context, BakeSettings(**{"samples": 16, **settings}), names, workers=1)


def findings(scene_bake, subject):
    return [check for check in scene_checks.scene_checks(bpy.context, scene_bake.plan, scene_bake.executor)
            if check.subject == subject]


# -- paths -------------------------------------------------------------------------------------------------------
def test_an_output_in_missing_folders_is_fine_they_are_created_but_not_a_read_only_file(tmp_path):
    assert checks.writable_check(str(tmp_path / "missing" / "deeper" / "out.blend"), "output",
                                 required=True).level == checks.OK
    (tmp_path / "kept.blend").write_text("")
    (tmp_path / "kept.blend").chmod(0o444)  # read-only for everyone: refused even for root, who could write it
    check = checks.writable_check(str(tmp_path / "kept.blend"), "output", required=True)
    assert check.level == checks.ERROR and "the file there is read-only" in check.text


def test_an_output_under_a_file_is_an_error_and_a_warning_where_saving_can_wait(tmp_path):
    (tmp_path / "notes.txt").write_text("a file, not a folder")
    path = str(tmp_path / "notes.txt" / "out.blend")
    assert checks.writable_check(path, "output", required=True).level == checks.ERROR
    check = checks.writable_check(path, "output", required=False)
    assert check.level == checks.WARNING and "is not a folder" in check.text


def test_an_output_in_a_writable_folder_is_fine(tmp_path):
    assert checks.writable_check(str(tmp_path / "out.blend"), "output", required=True).level == checks.OK


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write in any folder")
def test_an_output_in_a_read_only_folder_is_an_error(tmp_path):
    tmp_path.chmod(0o555)
    try:
        check = checks.writable_check(str(tmp_path / "out.blend"), "output", required=True)
    finally:
        tmp_path.chmod(0o755)
    assert check.level == checks.ERROR and "no permission" in check.text


def test_workers_need_a_writable_temporary_folder_but_not_a_saved_file(tmp_path):
    assert checks.workers_check(1, "/no/such/folder").level == checks.OK  # one process writes no job file
    assert checks.workers_check(2, str(tmp_path)).level == checks.OK
    check = checks.workers_check(2, str(tmp_path / "missing"))
    assert check.level == checks.ERROR and str(tmp_path / "missing") in check.text


def test_an_unsaved_file_is_information_in_the_panel_and_an_error_on_the_command_line(empty_scene):
    assert not bpy.data.filepath
    assert scene_checks.output_check(None, required=False).level == checks.INFO
    check = scene_checks.output_check(None, required=True)
    assert check.level == checks.ERROR and "--output" in check.text


# -- memory and time -----------------------------------------------------------------------------------------------
def size(**fields):
    values = dict(points=10_000, stored_rows=10_000, split_corners=0, occluder_vertices=20_000,
                  occluder_triangles=40_000, order=4, channels=1, rays=2_560_000, hits_per_ray=0.0, processes=1,
                  spawned=False)
    return checks.BakeSize(**(values | fields))


def test_memory_grows_with_the_points_order_hits_and_spawned_workers():
    base = checks.bake_bytes(size())
    assert checks.bake_bytes(size(points=20_000)) > base
    assert checks.bake_bytes(size(order=8)) > base
    assert checks.bake_bytes(size(hits_per_ray=0.5)) > base + 2_560_000 * 0.5 * 48  # a record is 48 bytes at least
    # spawned workers are Blenders of their own that load the occluders and build their own ray tree; forked ones
    # share this process's
    assert checks.bake_bytes(size(processes=4, spawned=True)) - checks.bake_bytes(size(processes=4)) > \
        3 * (40_000 * checks.TRIANGLE_BYTES + checks.SPAWNED_BYTES)
    # Embree's scene is held beside the BVHTree of the contact search
    assert checks.bake_bytes(size(ray_engine="embree")) - base == 40_000 * checks.EMBREE_TRIANGLE_BYTES


@pytest.mark.parametrize("available, level", [(None, checks.INFO), (10 << 20, checks.ERROR),
                                              (int(1.1 * checks.bake_bytes(size())), checks.WARNING),
                                              (64 << 30, checks.OK)])
def test_memory_is_graded_against_what_is_available(available, level):
    check = checks.memory_check([size()], available)
    assert check.level == level and check.subject == "memory"


def test_parts_baked_one_after_another_need_the_largest_ones_memory_and_keep_every_result():
    """A bake with dynamic parts: each part's rays and ray tree live while it bakes, its result until all are
    stored."""
    static, part = size(), size(points=500, stored_rows=2_000, occluder_vertices=500, occluder_triangles=1_000)
    check = checks.memory_check([static, part], None)
    needed, stored = checks.bake_bytes(static), checks.stored_bytes(static) + checks.stored_bytes(part)
    assert f"needs about {checks.format_bytes(needed)}, its result {checks.format_bytes(stored)}" in check.text
    assert checks.stored_bytes(part) == 2_000 * (18 + 2) * 4  # 16 coefficients in vectors of 3, error and rule


def test_available_memory_is_the_systems_and_at_most_its_total():
    with open("/proc/meminfo", encoding="ascii") as meminfo:
        total = next(int(line.split()[1]) * 1024 for line in meminfo if line.startswith("MemTotal:"))
    assert 0 < checks.available_memory() <= total


def test_the_stored_estimate_is_exactly_the_attributes_a_bake_writes(empty_scene):
    floor, cube = grid("Floor"), box("Cube")
    cube.data.shade_flat()  # its corners' normals differ: stored per face corner, with each corner's point
    scene_bake = gathered(["Floor", "Cube"])
    first = first_job(scene_bake.plan, scene_bake.executor)
    estimated = checks.stored_bytes(scene_checks.bake_size(scene_bake.plan, first, False))
    scene_bake.run(log=lambda line: None)
    written = sum(len(attribute.data) * ATTRIBUTE_BYTES[attribute.data_type]
                  for ob in (floor, cube) for attribute in ob.data.attributes if attribute.name.startswith("_prt_"))
    assert scene_bake.plan.receivers[1].layout.corner_points is not None
    assert estimated == written


def test_the_time_estimate_is_the_tree_the_workers_start_and_the_rays_shared_at_the_engines_rate():
    rate = engines.RATES["bvhtree"]
    rays, triangles = 4_000_000, 600_000
    assert checks.estimated_seconds(rays, triangles, "bvhtree", 1) == pytest.approx(
        triangles / rate.triangles_per_s + rays / rate.rays_per_s)
    assert checks.estimated_seconds(rays, triangles, "bvhtree", 4, start_s=1.0) == pytest.approx(
        triangles / rate.triangles_per_s + 1.0 + rays / rate.rays_per_s / 4)
    assert checks.estimated_seconds(0, triangles, "bvhtree", 1) == 0.0  # nothing to cast: no tree either
    settings = BakeSettings(target_error=0.01, samples=256, max_samples=4096)
    text = checks.time_check(rays, 20.5, "bvhtree", settings, 1).text
    assert "about 20.5s" in text and "4000000 rays" in text and "with bvhtree" in text and "up to 16× the rays" in text
    assert checks.time_check(0, 0.0, None, settings, 1).level == checks.OK


def test_the_checks_size_a_bake_from_its_plan_without_casting_a_ray(empty_scene, monkeypatch):
    """The rays are the first round's (points × samples); an interreflected bake counts a recorded hit per ray."""
    grid("Floor")
    box("Cube")
    monkeypatch.setattr(estimator, "bake_chunk", lambda *args: pytest.fail("a ray was cast"))
    for mode, hits in (("shadowed", 0.0), ("interreflected", checks.HITS_PER_RAY)):
        scene_bake = gathered(["Floor", "Cube"], mode=mode)
        first = first_job(scene_bake.plan, scene_bake.executor)
        size = scene_checks.bake_size(scene_bake.plan, first, False)
        assert size.rays == first.total_vertices * scene_bake.plan.settings.samples > 0
        assert size.hits_per_ray == hits
    unshadowed = gathered(["Floor", "Cube"], mode="unshadowed")
    assert scene_checks.bake_size(unshadowed.plan, first_job(unshadowed.plan, unshadowed.executor), False).rays == 0


# -- the objects -------------------------------------------------------------------------------------------------
def test_a_mirrored_object_is_named_with_its_scale(empty_scene):
    grid("Floor")
    cube = box("Cube")
    cube.scale = (-1.0, 1.0, 1.0)
    (check,) = findings(gathered(["Floor"]), "'Cube'")  # an occluder: its faces' fronts decide contact and bounces
    assert check.level == checks.WARNING and "negative scale (-1, 1, 1)" in check.text
    child = box("Child", location=(2.0, 0.0, 1.0))
    child.parent = cube
    assert any("mirrored by a parent" in check.text for check in findings(gathered(["Floor"]), "'Child'"))
    assert findings(gathered(["Floor"], mode="unshadowed"), "'Cube'") == []  # no rays: the winding does not matter


def test_a_receiver_hidden_in_renders_is_a_warning(empty_scene):
    cube = box("Cube")
    cube.hide_render = True
    (check,) = findings(gathered(["Cube"]), "'Cube'")
    assert check.level == checks.WARNING and "hidden in renders" in check.text


def test_zero_area_faces_are_counted(empty_scene):
    add_mesh("Sliver", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 2, 0), (2, 2, 0), (3, 2, 0)], [(0, 1, 2), (3, 4, 5)])
    check = next(check for check in findings(gathered(["Sliver"]), "'Sliver'") if check.level == checks.WARNING)
    assert "1 zero-area and 0 sliver faces" in check.text and check.select == ("Sliver", "thin")


def test_open_and_non_manifold_edges_are_information(empty_scene):
    grid("Floor", cuts=8)
    (floor,) = findings(gathered(["Floor"]), "'Floor'")
    assert floor.level == checks.INFO and "32 open boundary edges" in floor.text
    box("Cube")
    assert findings(gathered(["Cube"]), "'Cube'") == []  # closed: nothing to say
    add_mesh("Fin", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1)], [(0, 1, 2), (0, 1, 3), (0, 1, 4)])
    (fin,) = findings(gathered(["Fin"]), "'Fin'")
    assert "6 open boundary edges and 1 non-manifold edges" in fin.text


def test_objects_that_will_not_bake_are_listed_as_warnings(empty_scene):
    box("Cube")
    add_mesh("Loose", [(0, 0, 0), (1, 0, 0)], [])
    (check,) = findings(gathered(["Cube", "Loose"]), "not baked")
    assert check.level == checks.WARNING and "'Loose' has no faces" in check.text


# -- a bake stops on an error, before any ray ---------------------------------------------------------------------
def test_the_bake_operator_stops_on_an_error_and_keeps_the_earlier_bake(empty_scene, addon, monkeypatch):
    cube = box("Cube")
    select(cube)
    bake_in_the_panel()
    before, meta_before = transfer_of(cube)
    installed = importlib.import_module(f"{addon}.prt_addon.core.checks")  # the one the operator runs
    found_estimator = importlib.import_module(f"{addon}.prt_addon.core.estimator")
    baked, real = [], found_estimator.bake_chunk
    monkeypatch.setattr(found_estimator, "bake_chunk", lambda caster, receiver, *rest: (
        baked.append(receiver.name), real(caster, receiver, *rest))[1])
    monkeypatch.setattr(installed, "available_memory", lambda: 1 << 20)  # no memory to spare
    with pytest.raises(RuntimeError, match="memory: the bake needs about .* more than the 1.0 MB available"):
        bake_in_the_panel(order=6)
    assert baked == []  # the checks cast no ray
    after, meta_after = transfer_of(cube)
    np.testing.assert_array_equal(before, after)
    assert meta_after == meta_before
    checklist = importlib.import_module(f"{addon}.prt_addon.ui.checks").last_checklist()
    levels = {check.subject: check.level for check in checklist}
    assert levels["memory"] == checks.ERROR and levels["output"] == checks.INFO  # the panel lists why
    monkeypatch.undo()
    assert bake_in_the_panel(order=6) == {"FINISHED"} and transfer_of(cube)[1]["order"] == 6  # with memory: bakes


def test_the_check_button_lists_every_finding_in_the_panel_until_another_file_is_opened(empty_scene, addon):
    grid("Floor")
    cube = box("Cube")
    cube.scale = (1.0, -2.0, 1.0)
    assert bpy.ops.prt.check_bake() == {"FINISHED"}
    panel = importlib.import_module(f"{addon}.prt_addon.ui.checks")
    items = panel.last_checklist()
    assert [item.subject for item in items][:4] == ["output", "workers", "memory", "time"]
    assert any(item.subject == "'Cube'" and "negative scale (1, -2, 1)" in item.text for item in items)
    bpy.ops.wm.read_homefile(use_empty=True)
    assert panel.last_checklist() == []  # it described the objects of the file closed


def test_the_panel_draws_the_checklist_under_the_bake_button(empty_scene):
    from conftest import FakeLayout
    box("Cube")
    bpy.ops.prt.check_bake()
    drawn, labels = [], []

    class Layout(FakeLayout):
        def label(self, text="", **kwargs):
            labels.append(text)

        def menu(self, idname, **kwargs):
            assert hasattr(bpy.types, idname)

        def operator(self, idname, **kwargs):
            super().operator(idname)
            return type("Properties", (), {})()

    bpy.types.PRT_PT_bake.draw(type("Panel", (), {"layout": Layout(drawn)})(), bpy.context)
    assert any(text.startswith("memory: the bake needs about") for text in labels)


# -- the command line ----------------------------------------------------------------------------------------------
def test_cli_refuses_an_output_under_a_file_before_baking_and_leaves_the_file(tmp_path, sample_scene_files):
    path = tmp_path / "suzanne.blend"
    path.write_bytes((sample_scene_files / "suzanne.blend").read_bytes())
    before = path.read_bytes()
    (tmp_path / "notes.txt").write_text("a file, not a folder")
    result = run_cli("bake", path, "--output", tmp_path / "notes.txt" / "out.blend", cwd=tmp_path)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("prt:")]
    assert len(errors) == 1 and f"{tmp_path / 'notes.txt'} is not a folder" in errors[0]
    assert "PRT bake" not in result.stdout  # not one progress line: nothing was baked
    assert path.read_bytes() == before


@pytest.mark.parametrize("option, value, words", [
    ("--target-error", "5", "target error must be 0-1, not 5"),
    ("--target-error", "-0.01", "target error must be 0-1"),
    ("--target-error", "nan", "target error must be 0-1"),
    ("--workers", "-1", "workers must be 0-64"),
    ("--samples", "4", "samples must be 8-1048576"),
    ("--order", "0", "order must be 1-16"),
    ("--bounce-tolerance", "0.9", "tolerance must be 1e-08-0.5"),
])
def test_cli_refuses_every_setting_out_of_its_range_as_it_is_read(option, value, words):
    result = run_cli("bake", "never_opened.blend", option, value)
    assert result.returncode == 1
    assert words in result.stderr and option in result.stderr and "no such file" not in result.stderr


def test_cli_prints_the_checks_in_order_before_baking_and_names_a_mirrored_object(tmp_path, empty_scene):
    grid("Floor")
    box("Cube").scale = (-1.0, 1.0, 1.0)
    path = tmp_path / "mirrored.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    result = run_cli("bake", path, "--samples", "16", "--workers", "0", "--report", tmp_path / "r.json")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    start = lines.index("prt: checks before any ray:")
    listed = [line.split()[2] for line in lines[start + 1:start + 5]]
    assert listed == ["output:", "workers:", "memory:", "time:"]
    mirrored = next(index for index, line in enumerate(lines) if "'Cube': negative scale (-1, 1, 1)" in line)
    first_progress = next(index for index, line in enumerate(lines) if line.startswith("PRT bake:"))
    assert start < mirrored < first_progress
    assert json.loads((tmp_path / "r.json").read_text())["workers"] == os.cpu_count()  # 0: one per core
