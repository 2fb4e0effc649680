"""Stale-only rebakes: each bake stores a fingerprint of what its transfer depends on; a check says what changed;
Bake Stale (operator and `prt bake --stale-only`) rebakes only the objects whose fingerprint changed and leaves the
others' stored data byte for byte as it was."""

import bpy
import numpy as np
import pytest

from conftest import FakeLayout, run_cli
from test_bake_blender import box, grid, select
from prt_addon.blender import fingerprint, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core.bake import BakeSettings
from prt_addon.core.fingerprint import PARTS


def use_settings(**settings):
    scene_settings = bpy.context.scene.prt_bake
    for key, value in {"order": 3, "samples": 16, "mode": "shadowed", "workers": 1, **settings}.items():
        setattr(scene_settings, key, value)


def stored(ob) -> tuple[bytes, dict]:
    """Every PRT attribute's raw bytes, by name, and the metadata: what must not change when a bake is kept."""
    mesh = ob.data
    data = {}
    for attribute in mesh.attributes:
        if attribute.name.startswith(storage.ATTRIBUTE_PREFIX):
            field = {"FLOAT_VECTOR": "vector", "FLOAT": "value", "INT": "value"}[attribute.data_type]
            width = 3 if field == "vector" else 1
            values = np.empty(len(attribute.data) * width,
                              dtype=np.int32 if attribute.data_type == "INT" else np.float32)
            attribute.data.foreach_get(field, values)
            data[attribute.name] = values.tobytes()
    return data, mesh[storage.METADATA_KEY].to_dict()


def changes(names=None, **settings):
    scene_settings = bpy.context.scene.prt_bake.to_settings()
    return fingerprint.stale_receivers(bpy.context, BakeSettings(**{**vars(scene_settings), **settings}), names)


@pytest.fixture
def room(empty_scene):
    """A floor, a cube on it and a box beside it, all baked (shadowed, order 3, 16 samples): nothing selected, so
    every visible mesh is a receiver."""
    objects = grid("Floor"), box("Cube"), box("Box", half=0.3, location=(1.4, 1.0, 0.3))
    select()
    use_settings()
    assert bpy.ops.prt.bake() == {"FINISHED"}
    return objects


def test_a_bake_stores_its_fingerprint_and_is_up_to_date(room):
    for ob in room:
        meta = ob.data[storage.METADATA_KEY].to_dict()
        assert sorted(meta[fingerprint.FINGERPRINT_KEY]) == sorted(PARTS)
    assert changes() == {"Floor": [], "Cube": [], "Box": []}


def test_moving_one_object_makes_the_others_stale_through_their_shadows_and_bake_stale_rebakes_them(room):
    floor, cube, box_ = room
    before = {ob.name: stored(ob) for ob in room}
    cube.location.x += 0.7
    assert changes() == {"Floor": ["occluders changed"], "Cube": ["moved"], "Box": ["occluders changed"]}
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    for ob in room:
        attributes, meta = stored(ob)
        assert meta["bake_id"] != before[ob.name][1]["bake_id"]
    floor_before = np.frombuffer(before["Floor"][0]["_prt_t00"], dtype=np.float32)
    floor_after = np.frombuffer(stored(floor)[0]["_prt_t00"], dtype=np.float32)
    assert not np.array_equal(floor_before, floor_after)  # the cube's shadow moved
    assert changes() == {"Floor": [], "Cube": [], "Box": []}


def test_bake_stale_leaves_what_did_not_change_byte_identical_and_then_rebakes_nothing(empty_scene):
    """Unshadowed transfer depends on nothing but the object and the settings: moving one object makes only it
    stale."""
    room = grid("Floor"), box("Cube"), box("Box", half=0.3, location=(1.4, 1.0, 0.3))
    select()
    use_settings(mode="unshadowed")
    assert bpy.ops.prt.bake() == {"FINISHED"}
    before = {ob.name: stored(ob) for ob in room}
    room[1].location.x += 0.7
    room[1].rotation_euler.z += 0.4
    assert changes() == {"Floor": [], "Cube": ["moved"], "Box": []}
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert stored(room[0]) == before["Floor"] and stored(room[2]) == before["Box"]
    attributes, meta = stored(room[1])
    assert attributes != before["Cube"][0] and meta["bake_id"] != before["Cube"][1]["bake_id"]
    assert meta[fingerprint.FINGERPRINT_KEY]["transform"] != before["Cube"][1][fingerprint.FINGERPRINT_KEY]["transform"]
    assert changes() == {"Floor": [], "Cube": [], "Box": []}
    after = {ob.name: stored(ob) for ob in room}
    assert bpy.ops.prt.bake_stale() == {"CANCELLED"}  # nothing to rebake: nothing is written
    assert {ob.name: stored(ob) for ob in room} == after


def test_a_subsurface_material_rebakes_only_its_object_in_a_shadowed_bake(room):
    floor, cube, box_ = room
    before = {ob.name: stored(ob) for ob in room}
    material = bpy.data.materials.new("Wax")
    if material.node_tree is None:  # Blender 4.5: nodes only on request
        material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 0.5
    cube.data.materials.append(material)
    assert changes() == {"Floor": [], "Cube": ["materials changed"], "Box": []}
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert stored(floor) == before["Floor"] and stored(box_) == before["Box"]
    assert stored(cube)[0] != before["Cube"][0]
    assert changes() == {"Floor": [], "Cube": [], "Box": []}


def test_what_each_change_is_called(room):
    floor, cube, box_ = room
    assert changes(samples=32) == {name: ["settings changed"] for name in ("Floor", "Cube", "Box")}
    assert changes(bounces=7) == {"Floor": [], "Cube": [], "Box": []}  # a shadowed bake reads no bounces
    cube.data.vertices[0].co.z -= 0.1
    cube.data.update()
    assert changes() == {"Floor": ["occluders changed"], "Cube": ["geometry changed"], "Box": ["occluders changed"]}
    cube.data.vertices[0].co.z += 0.1
    cube.data.update()
    assert changes() == {"Floor": [], "Cube": [], "Box": []}  # back where it was baked: up to date again
    for polygon in box_.data.polygons:  # the corner normals change, not the triangles that cast shadows
        polygon.use_smooth = True
    box_.data.update()
    assert changes() == {"Floor": [], "Cube": [], "Box": ["geometry changed"]}
    displace = floor.modifiers.new("Displace", "DISPLACE")  # the evaluated surface is what counts
    displace.strength = 0.05
    assert changes() == {"Floor": ["geometry changed"], "Cube": ["occluders changed"],
                         "Box": ["geometry changed", "occluders changed"]}
    floor.modifiers.remove(displace)
    box_.hide_set(True)
    assert changes(["Floor", "Cube"]) == {"Floor": ["occluders changed"], "Cube": ["occluders changed"]}


def red_material():
    red = bpy.data.materials.new("Red")
    red.diffuse_color = (0.8, 0.1, 0.1, 1.0)
    if red.node_tree is not None:  # Blender 5: the Principled BSDF's Base Color is the albedo
        red.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.8, 0.1, 0.1, 1.0)
    return red


def test_a_shadowed_bake_does_not_depend_on_albedo(room):
    room[1].data.materials.append(red_material())
    assert changes() == {"Floor": [], "Cube": [], "Box": []}


def test_an_interreflected_bake_depends_on_every_surface_s_albedo(empty_scene):
    room = grid("Floor"), box("Cube")
    select()
    use_settings(mode="interreflected", bounces=1, auto_bounces=False)
    assert bpy.ops.prt.bake() == {"FINISHED"}
    assert changes() == {"Floor": [], "Cube": []}
    room[1].data.materials.append(red_material())
    assert changes() == {"Floor": ["occluders changed"], "Cube": ["materials changed"]}


def test_never_baked_and_older_bakes_are_stale(room):
    floor, cube, box_ = room
    del cube.data[storage.METADATA_KEY][fingerprint.FINGERPRINT_KEY]  # as a bake before fingerprints
    extra = box("Extra", half=0.2, location=(-1.5, -1.5, 0.2))
    assert changes() == {"Floor": ["occluders changed"], "Cube": ["baked without a fingerprint"],
                         "Box": ["occluders changed"], "Extra": ["not baked"]}
    select(extra)  # the selection is what Bake Stale considers
    assert changes() == {"Extra": ["not baked"]}
    before = {ob.name: stored(ob) for ob in room}
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert {ob.name: stored(ob) for ob in room} == before
    assert storage.METADATA_KEY in extra.data


def test_a_cancelled_stale_bake_keeps_every_earlier_bake(room):
    floor, cube, box_ = room
    cube.location.x += 0.7
    before = {ob.name: stored(ob) for ob in room}
    stale = [name for name, words in changes().items() if words]
    assert stale == ["Floor", "Cube", "Box"]
    # 2^20 rays per vertex: a 100 M ray bake, far from done after one step on any machine.
    settings = BakeSettings(order=3, samples=1 << 20, max_samples=1 << 20)
    scene_bake = SceneBake(bpy.context, settings, stale)
    assert not scene_bake.step(0.05)  # part of the work, as the modal operator does per timer event
    scene_bake.cancel()
    assert {ob.name: stored(ob) for ob in room} == before
    assert changes() == {"Floor": ["occluders changed"], "Cube": ["moved"], "Box": ["occluders changed"]}


class LabelLayout(FakeLayout):
    """Records the labels' text too."""

    def label(self, text="", **kwargs):
        self.drawn.append(text)


def draw_stored_bake_panel(ob) -> list:
    bpy.context.view_layer.objects.active = ob
    drawn = []
    bpy.types.PRT_PT_bake_info.draw(type("Panel", (), {"layout": LabelLayout(drawn)})(), bpy.context)
    return drawn


def test_the_panel_says_what_the_last_check_found_for_the_stored_bake(room):
    floor, cube, box_ = room
    assert "Status not checked" in draw_stored_bake_panel(cube)
    assert bpy.ops.prt.check_stale() == {"FINISHED"}
    assert any(line.startswith("Up to date (") for line in draw_stored_bake_panel(cube))
    cube.location.x += 0.5
    assert bpy.ops.prt.check_stale() == {"FINISHED"}
    assert any(line.startswith("Stale: moved (") for line in draw_stored_bake_panel(cube))
    assert any(line.startswith("Stale: occluders changed (") for line in draw_stored_bake_panel(floor))
    assert bpy.ops.prt.bake() == {"FINISHED"}
    assert "Status not checked" in draw_stored_bake_panel(cube)  # a new bake: the check was of the old one


def test_cli_stale_only_bakes_what_is_not_baked_then_nothing_then_what_changed(tmp_path, sample_scene_files):
    path = tmp_path / "suzanne.blend"
    path.write_bytes((sample_scene_files / "suzanne.blend").read_bytes())
    options = ("--order", "2", "--samples", "16", "--stale-only")
    result = run_cli("bake", path, *options)
    assert result.returncode == 0, result.stderr
    assert "PRT bake stale: rebaking 2 of 2 objects: " in result.stdout and "Plane (not baked)" in result.stdout
    assert "PRT bake: 2 objects" in result.stdout
    baked = path.read_bytes()
    result = run_cli("bake", path, *options)
    assert result.returncode == 0, result.stderr
    assert "PRT bake stale: nothing to rebake, 2 objects up to date" in result.stdout
    assert "PRT bake:" not in result.stdout
    assert path.read_bytes() == baked  # nothing written
    result = run_cli("bake", path, "--order", "3", "--samples", "16", "--stale-only", "--objects", "Plane")
    assert result.returncode == 0, result.stderr
    assert "PRT bake stale: rebaking 1 of 1 objects: Plane (settings changed)" in result.stdout
