"""The viewport's heatmaps: the display colour attribute holds the core colour map of the stored estimated error,
or of the last validation's difference from Cycles, per vertex or per face corner as baked, on one scale; the
legend says the range. The handler belongs to the installed add-on, so its modules are used (`prt`)."""

import importlib

import bpy
import numpy as np
import pytest

from conftest import labels_drawn
from prt_addon.blender import sample_scenes, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, heatmap, rules

GREY = heatmap.missing_rgba(1)[0]


def update():
    bpy.context.view_layer.update()


def bake_scene(samples=16):
    SceneBake(bpy.context, bake.BakeSettings(order=3, mode="shadowed", samples=samples)).run(log=lambda line: None)


@pytest.fixture
def baked(empty_scene):
    """A floor (5 × 5 vertices, smooth: baked per vertex) under a cube (flat faces: baked per face corner), both
    receivers; the cube's shadow gives the floor's vertices different errors."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=4)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0.3, 0.2, 0.8))
    bpy.ops.object.select_all(action="DESELECT")
    bake_scene()
    floor, cube = bpy.data.objects["Grid"], bpy.data.objects["Cube"]
    assert [ob.data[storage.METADATA_KEY]["domain"] for ob in (floor, cube)] == ["POINT", "CORNER"]
    return floor, cube


def stored(mesh, name):
    attribute = mesh.attributes[name]
    values = np.empty(len(attribute.data), dtype=np.float32)
    attribute.data.foreach_get("value", values)
    return values, attribute.domain


def shown(mesh):
    attribute = mesh.color_attributes["prt_color"]
    rgba = np.empty(len(attribute.data) * 4, dtype=np.float32)
    attribute.data.foreach_get("color", rgba)
    return rgba.reshape(-1, 4), attribute.domain


def albedo_factors():
    return {material.node_tree.nodes["PRT Albedo"].inputs[0].default_value
            for material in bpy.data.materials if "_prt_display_of" in material}


@pytest.fixture
def demo(empty_scene):
    """The demo sample scene (a torus over a floor and two walls), baked quickly."""
    sample_scenes.build_demo_scene()
    bake_scene(samples=8)
    return [ob for ob in bpy.context.scene.objects if ob.type == "MESH" and storage.METADATA_KEY in ob.data]


@pytest.mark.parametrize("scene", ["baked", "demo"])
def test_error_heatmap_is_the_core_colour_map_of_the_stored_error(scene, request, prt):
    receivers = request.getfixturevalue(scene)
    display = bpy.context.scene.prt_display
    display.mode = "ERROR"
    update()
    assert display.show_prt, "choosing a heatmap switches the PRT display on"
    errors = {ob.name: stored(ob.data, "_prt_error") for ob in receivers}
    every_error = np.concatenate([values for values, _ in errors.values()])
    assert len(np.unique(every_error)) > 3  # a heatmap with something to show
    top = heatmap.scale_top(every_error)
    assert prt.handlers.engine.legend == prt.heatmaps.Legend("ERROR", top, ())
    for ob in receivers:
        values, domain = errors[ob.name]
        rgba, shown_domain = shown(ob.data)
        assert shown_domain == domain and len(rgba) == len(values)
        np.testing.assert_array_equal(rgba, heatmap.heatmap_rgba(values, top), err_msg=ob.name)
    assert albedo_factors() == {0.0}, "a heatmap shows as it is, not times albedo"


def test_back_to_shaded_shows_the_prt_colours_again(baked):
    bpy.ops.prt.light_add(kind="SUN")
    update()
    display = bpy.context.scene.prt_display
    display.show_prt = True
    update()
    before = {ob.name: shown(ob.data) for ob in baked}
    display.mode = "ERROR"
    update()
    assert not np.array_equal(shown(baked[0].data)[0], before["Grid"][0])
    display.mode = "SHADED"
    update()
    for ob in baked:
        rgba, domain = shown(ob.data)
        assert domain == before[ob.name][1]
        np.testing.assert_array_equal(rgba, before[ob.name][0], err_msg=ob.name)
    assert albedo_factors() == {1.0}


def test_difference_heatmap_shows_the_stored_validation_error_and_grey_where_there_is_none(baked, prt):
    floor, cube = baked
    display = bpy.context.scene.prt_display
    display.mode = "DIFFERENCE"
    update()
    assert prt.handlers.engine.legend.missing == ("Cube", "Grid")
    for ob in baked:
        np.testing.assert_array_equal(shown(ob.data)[0], np.tile(GREY, (len(shown(ob.data)[0]), 1)))
    differences = np.linspace(0.0, 0.03, len(floor.data.vertices))
    storage.write_validation_error(floor.data, differences)
    bpy.context.scene.update_tag()  # as the validation operator does
    update()
    assert prt.handlers.engine.legend == prt.heatmaps.Legend("DIFFERENCE", 0.05, ("Cube",))
    rgba, domain = shown(floor.data)
    assert domain == "POINT"
    np.testing.assert_array_equal(rgba, heatmap.heatmap_rgba(differences.astype(np.float32), 0.05))
    rgba, domain = shown(cube.data)
    assert domain == "POINT" and np.array_equal(rgba, np.tile(GREY, (len(cube.data.vertices), 1)))
    bake_scene()  # a new bake drops the validation of the old one
    assert "_prt_validation_error" not in floor.data.attributes


def test_validate_stores_each_meshs_error_against_cycles_in_its_bake_domain(baked):
    scene = bpy.context.scene
    bpy.ops.prt.light_add(kind="SKY")
    scene.prt_validate.samples, scene.prt_validate.passes = 4, 2
    assert bpy.ops.prt.validate() == {"FINISHED"}
    floor, cube = baked
    assert [stored(ob.data, "_prt_validation_error")[1] for ob in baked] == ["POINT", "CORNER"]
    assert len(stored(floor.data, "_prt_validation_error")[0]) == len(floor.data.vertices)
    assert len(stored(cube.data, "_prt_validation_error")[0]) == len(cube.data.loops)
    result = bpy.context.window_manager.prt_validation
    errors, _ = stored(bpy.data.objects[result.worst_object].data, "_prt_validation_error")
    worst = int(result.worst_vertices.split(",")[0])
    assert errors[worst] == errors.max() > 0


def test_display_panel_draws_the_mode_and_the_legend(baked, prt, addon):
    display = bpy.context.scene.prt_display
    display.mode = "ERROR"
    update()
    drawn = []
    labels = labels_drawn(bpy.types.PRT_PT_display, drawn)
    assert "mode" in drawn
    top = prt.handlers.engine.legend.top
    assert f"Estimated relative error: {heatmap.range_label(top)}" in labels
    assert f"Above {100 * top:.4g} %: the top colour" in labels
    assert labels.count("") == importlib.import_module(f"{addon}.prt_addon.ui.heatmaps").SWATCHES
    assert not [label for label in labels if label.startswith("Grey")]
    display.mode = "DIFFERENCE"
    update()
    assert "Grey, not validated: Cube, Grid" in labels_drawn(bpy.types.PRT_PT_display, drawn)


def test_decided_by_rule_shows_each_points_rule_in_its_colour_and_the_panels_count_them(empty_scene, prt, addon):
    """A cube resting on a floor: its bottom face's corners lie on the floor facing into it, and the floor's vertex
    under the cube lies on the cube's bottom (both black by the contact rule); every other point is measured."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=4)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0.0, 0.0, 0.5))
    bpy.ops.object.select_all(action="DESELECT")
    bake_scene()
    floor, cube = bpy.data.objects["Grid"], bpy.data.objects["Cube"]
    codes = {ob.name: stored_codes(ob.data) for ob in (floor, cube)}
    corner_down = face_normal_z(cube.data) < -0.5
    assert (codes["Cube"][corner_down] == rules.LYING).all() and (codes["Cube"][~corner_down] == 0).all()
    floor_positions = np.array([vertex.co for vertex in floor.data.vertices])
    under = np.all(np.abs(floor_positions[:, :2]) < 0.5, axis=1)
    assert under.sum() == 1 and codes["Grid"][under].tolist() == [rules.LYING]
    assert cube.data["prt"]["decided_by_rule"].to_dict() == {"lying": 4}
    display = bpy.context.scene.prt_display
    display.mode = "RULE"
    update()
    legend = prt.handlers.engine.legend
    assert legend.mode == "RULE" and dict(legend.decided) == {"lying": 5} and legend.missing == ()
    for ob in (floor, cube):
        rgba, _ = shown(ob.data)
        np.testing.assert_array_equal(rgba, heatmap.rule_rgba(codes[ob.name]), err_msg=ob.name)
    assert "Lying on a surface (black): 5 points" in labels_drawn(bpy.types.PRT_PT_display, [])
    bpy.context.view_layer.objects.active = cube
    assert "  4 lying on a surface (black)" in labels_drawn(bpy.types.PRT_PT_bake_info, [])


def stored_codes(mesh) -> np.ndarray:
    attribute = mesh.attributes["_prt_rule"]
    values = np.empty(len(attribute.data), dtype=np.int32)
    attribute.data.foreach_get("value", values)
    return values


def face_normal_z(mesh) -> np.ndarray:
    """Each face corner's face normal's z."""
    return np.array([polygon.normal.z for polygon in mesh.polygons for _ in polygon.loop_indices])
