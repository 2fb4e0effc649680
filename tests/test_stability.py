"""Stiff and extreme geometry gives finite, correct transfer; failures halfway never cost data."""

import os
import sys

import bpy
import numpy as np
import pytest

from prt_addon.blender import storage
from prt_addon.blender.execute import first_job
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import estimator, executors, lobes, sh
from prt_addon.core.bake import BakeSettings
from prt_addon.core.errors import StaleBake
from quadrature import sphere_quadrature
from test_bake_blender import add_mesh, box, grid, transfer_of

UP = np.array([[0.0, 0.0, 1.0]])


def bake_objects(names, **settings):
    scene_bake = SceneBake(bpy.context, BakeSettings(**{"order": 4, "samples": 256, **settings}), names)
    scene_bake.run(log=lambda line: None)
    return scene_bake


def std_error_of(ob):
    """The bake's estimated relative error per vertex (× lobes.unshadowed_norm gives the absolute one)."""
    values = np.empty(len(ob.data.vertices), dtype=np.float32)
    ob.data.attributes["_prt_error"].data.foreach_get("value", values)
    return values


def quarter_space_transfer(normal, order=4):
    """(1/π)∫ V max(n·ω,0) Y dω for V = [ω_y > 0 and ω_z > 0], by fine quadrature (a vertex on the inner edge
    where a floor (z = 0) meets a wall (y = 0))."""
    directions, weights = sphere_quadrature(400)
    visible = (directions[:, 1] > 0) & (directions[:, 2] > 0)
    cosine = np.maximum(directions @ normal, 0.0)
    return (weights * visible * cosine) @ sh.evaluate(order, directions) / np.pi


def transfer_facing_a_square(facing, distance, half_size, order=4):
    """Quadrature reference for a vertex facing ±Z at the centre of a square of half size `half_size` at
    `distance` along its normal: (1/π)∫ V max(n·ω,0) Y dω."""
    directions, weights = sphere_quadrature(600)
    along = facing * directions[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = distance / along
        hits = (along > 0) & (np.abs(reach * directions[:, 0]) <= half_size) & \
            (np.abs(reach * directions[:, 1]) <= half_size)
    return (weights * np.maximum(along, 0.0) * ~hits) @ sh.evaluate(order, directions) / np.pi


def concave_crease():
    """Floor (z = 0, y ≥ 0) and wall (y = 0, z ≥ 0) sharing their edge along x: one mesh, flat-shaded."""
    ticks = np.linspace(-2.0, 2.0, 9)
    floor = [(x, y, 0.0) for y in np.linspace(0.0, 4.0, 9) for x in ticks]
    wall = [(x, 0.0, z) for z in np.linspace(0.5, 4.0, 8) for x in ticks]
    vertices = floor + wall
    faces = [(r * 9 + c, r * 9 + c + 1, (r + 1) * 9 + c + 1, (r + 1) * 9 + c) for r in range(8) for c in range(8)]
    wall_rows = [list(range(9))] + [[81 + r * 9 + c for c in range(9)] for r in range(8)]
    faces += [(a[c + 1], a[c], b[c], b[c + 1]) for a, b in zip(wall_rows, wall_rows[1:]) for c in range(8)]
    return add_mesh("Crease", vertices, faces)


def test_vertex_on_a_smooth_concave_crease_sees_the_quarter_space(empty_scene):
    ob = concave_crease()
    ob.data.shade_smooth()  # one normal at the crease, averaged between the faces
    bake_objects(["Crease"], samples=4096)
    transfer, _ = transfer_of(ob)
    crease_vertex = 4  # (0, 0, 0)
    normal = np.array(ob.data.vertex_normals[crease_vertex].vector)
    assert abs(normal[1] - normal[2]) < 1e-6 and normal[1] > 0.7  # averaged between the faces
    expected = quarter_space_transfer(normal)
    error = np.abs(transfer[crease_vertex] - expected)
    assert np.isfinite(transfer).all()
    assert np.linalg.norm(error) < 5 * std_error_of(ob)[crease_vertex] * lobes.unshadowed_norm(4) + 2e-3


def test_flat_concave_crease_splits_into_the_floors_and_the_walls_point_each_seeing_the_quarter_space(empty_scene):
    """Flat-shaded, the crease's vertices are shaded with the floor's normal on the floor and the wall's on the
    wall, as Blender shades (and Cycles bakes) them: one transfer each, stored per face corner."""
    ob = concave_crease()
    bake_objects(["Crease"], samples=4096)
    transfer, meta = transfer_of(ob)
    corner_points = storage.corner_points_of(ob.data)
    assert meta["domain"] == "CORNER" and meta["split_vertices"] == 9 and meta["points"] == len(ob.data.vertices) + 9
    assert len(transfer) == meta["points"] and np.isfinite(transfer).all()
    crease_vertex = 4  # (0, 0, 0)
    corners = [loop.index for loop in ob.data.loops if loop.vertex_index == crease_vertex]
    face_of_corner = {corner: face.normal for face in ob.data.polygons for corner in face.loop_indices}
    seen = set()
    for corner in corners:
        point = corner_points[corner]
        normal = np.array(face_of_corner[corner])
        expected = quarter_space_transfer(normal)
        assert np.linalg.norm(transfer[point] - expected) < 0.02 * np.linalg.norm(expected), normal
        seen.add((point, tuple(np.round(normal, 6))))
    assert {normal for _, normal in seen} == {(0.0, 0.0, 1.0), (0.0, 1.0, 0.0)}
    assert len({point for point, _ in seen}) == 2


def test_coplanar_overlapping_faces_do_not_shadow_each_other(empty_scene):
    first, second = grid("First", cuts=4), grid("Second", cuts=4)
    second.location.x = 0.5  # overlapping, z-fighting copy
    bake_objects(["First", "Second"])
    exact = lobes.cosine_transfer(4, UP)
    for ob in (first, second):
        transfer, meta = transfer_of(ob)
        np.testing.assert_allclose(transfer, np.repeat(exact, len(transfer), 0), atol=1e-6)
        assert meta["skipped_vertices"] == len(transfer)


def test_two_sided_thin_sheet_and_flipped_normals_stay_finite_and_bounded(empty_scene):
    floor = grid("Floor", cuts=6)
    top = grid("SheetTop", size=1.0, cuts=4, z=1.0)
    bottom = grid("SheetBottom", size=1.0, cuts=4, z=1.0 - 1e-4)
    bottom.data.flip_normals()  # the sheet's underside faces the floor
    bake_objects(["Floor", "SheetTop", "SheetBottom"])
    exact = lobes.cosine_transfer(4, UP)[0]
    top_t, _ = transfer_of(top)
    bottom_t, _ = transfer_of(bottom)
    floor_t, _ = transfer_of(floor)
    assert all(np.isfinite(t).all() for t in (top_t, bottom_t, floor_t))
    np.testing.assert_allclose(top_t, np.tile(exact, (len(top_t), 1)), atol=1e-6)  # nothing above the top
    # The underside's centre looks down at the 4 × 4 floor; the floor's centre looks up at the 1 × 1 sheet.
    centre = np.argmin(np.linalg.norm(np.array([v.co[:] for v in bottom.data.vertices])[:, :2], axis=1))
    below = np.argmin(np.linalg.norm(np.array([v.co[:] for v in floor.data.vertices]), axis=1))
    scale = lobes.unshadowed_norm(4)
    assert np.linalg.norm(bottom_t[centre] - transfer_facing_a_square(-1, 1.0 - 1e-4, 2.0)) < \
        5 * std_error_of(bottom)[centre] * scale + 2e-3
    assert np.linalg.norm(floor_t[below] - transfer_facing_a_square(+1, 1.0 - 1e-4, 0.5)) < \
        5 * std_error_of(floor)[below] * scale + 2e-3


def test_needles_non_manifold_edges_and_duplicate_vertices(empty_scene):
    floor = grid("Floor", cuts=6)
    # Needle triangles (aspect 1e6), three faces on one edge, and a duplicated (unwelded) vertex at (0, 0, 0.3).
    vertices = [(-1, 0, 0.5), (1, 0, 0.5), (0, 1e-6, 0.5), (0, 0, 0.3), (0, 0, 0.3), (0.5, 0.5, 1.0),
                (0.5, -0.5, 1.0), (-0.5, 0.5, 1.0)]
    faces = [(0, 1, 2), (0, 1, 5), (0, 1, 6), (0, 1, 7), (3, 5, 6), (4, 6, 7)]
    odd = add_mesh("Odd", vertices, faces)
    bake_objects(["Floor", "Odd"], samples=1024)
    odd_t, _ = transfer_of(odd)
    floor_t, _ = transfer_of(floor)
    assert np.isfinite(odd_t).all() and np.isfinite(floor_t).all()
    exact = lobes.cosine_transfer(4, UP)[0]
    assert np.all(floor_t[:, 0] <= exact[0] + 1e-6) and np.all(floor_t[:, 0] >= 0)
    assert np.all(odd_t[:, 0] >= -1e-6) and np.all(odd_t[:, 0] <= exact[0] + 1e-6)


@pytest.mark.parametrize("scale, offset", [(1e-4, 0.0), (1e4, 0.0), (1.0, 1e5)])
def test_object_transforms_scale_and_offset_do_not_change_the_bake(empty_scene, scale, offset):
    floor, cube = grid("Floor"), box("Cube")
    bake_objects(["Floor"], seed=3)
    reference, _ = transfer_of(floor)
    for ob in (floor, cube):
        ob.scale = (scale,) * 3
        ob.location = tuple(np.array(ob.location) * scale + offset)
    bake_objects(["Floor"], seed=3)
    moved, _ = transfer_of(floor)
    np.testing.assert_allclose(moved, reference, atol=1e-5)


def spawned_worker_out_of_memory(scene_bake, monkeypatch):
    scene_bake.executor = executors.SpawnedWorkers(2, [sys.executable, "-c",
                                                       "import sys; sys.exit('worker ran out of memory')"])
    scene_bake.executor.min_rays, scene_bake.executor.start_s = 0, 0.0
    return "worker ran out of memory"


def forked_worker_out_of_memory_on_its_third_chunk(scene_bake, monkeypatch):
    assert isinstance(scene_bake.executor, executors.ForkedWorkers)
    # the worker bakes every chunk: it reaches a third
    scene_bake.executor.owners = [1] * len(first_job(scene_bake.plan, scene_bake.executor).chunks)
    baking_process, real_bake_chunk, chunks_baked = os.getpid(), estimator.bake_chunk, []

    def failing_in_the_worker(*args):
        if os.getpid() != baking_process:
            chunks_baked.append(args[2])
            if len(chunks_baked) == 3:
                raise MemoryError("worker ran out of memory on its third chunk")
        return real_bake_chunk(*args)

    monkeypatch.setattr(estimator, "bake_chunk", failing_in_the_worker)
    return "MemoryError: worker ran out of memory on its third chunk"


@pytest.mark.parametrize("make_a_worker_fail", [spawned_worker_out_of_memory,
                                                forked_worker_out_of_memory_on_its_third_chunk])
def test_a_worker_failing_halfway_is_reported_and_keeps_the_previous_data(empty_scene, monkeypatch,
                                                                          make_a_worker_fail):
    floor, _ = grid("Floor", cuts=30), box("Cube")
    bake_objects(["Floor"], order=3)
    before, meta_before = transfer_of(floor)
    scene_bake = SceneBake(bpy.context, BakeSettings(order=4, samples=64), ["Floor"], workers=2)
    scene_bake.executor.min_rays = 0
    message = make_a_worker_fail(scene_bake, monkeypatch)
    with pytest.raises(RuntimeError, match=message):
        scene_bake.run(log=lambda line: None)
    after, meta_after = transfer_of(floor)
    np.testing.assert_array_equal(before, after)
    assert meta_before == meta_after


def test_saving_in_the_middle_of_a_bake_saves_the_previous_bake(empty_scene, tmp_path):
    floor, _ = grid("Floor", cuts=40), box("Cube")
    bake_objects(["Floor"], order=3)
    before, _ = transfer_of(floor)
    scene_bake = SceneBake(bpy.context, BakeSettings(order=4, samples=2048), ["Floor"])
    scene_bake.step(0.05)
    path = str(tmp_path / "midway.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    while not scene_bake.step(0.5):
        pass
    scene_bake.store()
    assert transfer_of(floor)[1]["order"] == 4
    bpy.ops.wm.open_mainfile(filepath=path)
    saved, meta = transfer_of(bpy.data.objects["Floor"])
    np.testing.assert_array_equal(saved, before)
    assert meta["order"] == 3


def test_attributes_deleted_by_hand_are_reported_not_misread(empty_scene):
    floor, _ = grid("Floor"), box("Cube")
    bake_objects(["Floor"])
    floor.data.attributes.remove(floor.data.attributes["_prt_t03"])
    with pytest.raises(StaleBake, match="lost its PRT attributes _prt_t03"):
        transfer_of(floor)


def test_linked_library_data_is_refused_by_name(empty_scene, tmp_path):
    library = str(tmp_path / "library.blend")
    grid("Linked", cuts=2)
    bpy.ops.wm.save_as_mainfile(filepath=library)
    bpy.ops.wm.read_homefile(use_empty=True)
    with bpy.data.libraries.load(library, link=True) as (source, target):
        target.objects = ["Linked"]
    bpy.context.collection.objects.link(target.objects[0])
    grid("Local", cuts=2)
    scene_bake = SceneBake(bpy.context, BakeSettings(samples=16), ["Linked", "Local"])
    assert any("'Linked'" in p and "linked library data" in p for p in scene_bake.problems)
    scene_bake.run(log=lambda line: None)
    assert "prt" in bpy.data.objects["Local"].data
