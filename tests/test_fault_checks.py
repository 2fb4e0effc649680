"""The checks of messy models' faults (blender.fault_checks) against closed-form cases, and the checklist's Select
button (PRT_OT_select_faults), which selects exactly the faces at fault."""

import bpy
import pytest

from prt_addon.blender import fault_checks
from prt_addon.core import checks
from test_bake_blender import add_mesh, box, grid
from test_checks import findings, gathered

# box()'s faces: -x, +x, -y, +y, -z, +z
MINUS_X, PLUS_X, MINUS_Y, PLUS_Y, MINUS_Z, PLUS_Z = range(6)


def crossing_boxes():
    """A = [0, 1]³ and B = [0.3, 1.6] × [0.55, 1.7] × [0.7, 1.8]: they overlap at A's corner (1, 1, 1), so A's +x,
    +y and +z faces pass through B and B's -x, -y and -z faces through A (generic offsets: no crossing runs along a
    triangle's diagonal)."""
    a = box("A", location=(0.5, 0.5, 0.5))
    b = box("B", location=(0.95, 1.125, 1.25))
    b.scale = (1.3, 1.15, 1.1)
    return a, b


def selected_faces(ob) -> set:
    bpy.ops.object.mode_set(mode="OBJECT")
    return {face.index for face in ob.data.polygons if face.select}


def test_faces_crossing_another_object_are_named_with_it_and_selected_exactly(empty_scene):
    a, b = crossing_boxes()
    (check,) = [check for check in findings(gathered(["A", "B"]), "'A'") if check.select[1:] == ("crossing",)]
    assert check.level == checks.WARNING and check.text.startswith("3 faces cross 'B'")
    assert check.select == ("A", "crossing")
    assert set(fault_checks.fault_faces(b, "crossing", [a]).tolist()) == {MINUS_X, MINUS_Y, MINUS_Z}
    assert bpy.ops.prt.select_faults(object_name="A", fault="crossing") == {"FINISHED"}
    assert bpy.context.mode == "EDIT_MESH" and bpy.context.view_layer.objects.active == a
    assert selected_faces(a) == {PLUS_X, PLUS_Y, PLUS_Z}
    assert "UNDO" in bpy.types.PRT_OT_select_faults.bl_options


def test_boxes_that_only_touch_have_no_fault(empty_scene):
    box("A", location=(0.5, 0.5, 0.5))
    box("B", location=(0.5, 0.5, 1.5))  # standing on A
    assert [check for check in findings(gathered(["A", "B"]), "'A'") if check.select] == []


def test_a_part_inside_another_is_found_and_the_outer_one_is_not(empty_scene):
    box("Outer", half=1.0, location=(0.0, 0.0, 1.0))
    box("Inner", half=0.25, location=(0.1, -0.2, 1.3))
    scene_bake = gathered(["Outer", "Inner"])
    (inner,) = [check for check in findings(scene_bake, "'Inner'") if check.select]
    assert inner.select == ("Inner", "inside") and inner.text.startswith("6 faces of parts inside another")
    assert [check for check in findings(scene_bake, "'Outer'") if check.select] == []


@pytest.mark.parametrize("flipped", [(0,), (3, 9, 14)])
def test_faces_wound_against_their_custom_normals_are_counted_and_selected(empty_scene, flipped):
    """A floor of 16 quads whose custom normals all point up, with the faces `flipped` wound downward: their corners
    point against their faces, the others' do not."""
    floor = grid("Floor", cuts=4)
    mesh = floor.data
    for index in flipped:
        polygon = mesh.polygons[index]
        polygon.flip()
    mesh.normals_split_custom_set([(0.0, 0.0, 1.0)] * len(mesh.loops))
    (check,) = [check for check in findings(gathered(["Floor"]), "'Floor'") if check.select]
    assert check.select == ("Floor", "against") and check.text.startswith(f"{len(flipped)} faces with corners")
    assert bpy.ops.prt.select_faults(object_name="Floor", fault="against") == {"FINISHED"}
    assert selected_faces(floor) == set(flipped)


def test_an_unknown_object_is_refused_in_one_line(empty_scene):
    with pytest.raises(RuntimeError, match="no mesh object named 'Nothing'"):
        bpy.ops.prt.select_faults(object_name="Nothing", fault="thin")
