"""Stale probe volumes: a probe volume's bake stores what its probes depend on (where they stand, how many, the
static scene that shadows them and reflects light to them, the settings); a check says what changed, the panel and
the display say so, and Bake Stale rebakes the stale volumes only, leaving the fresh ones and the receivers as they
were, byte for byte.

The scene: a floor, a wall (a box), a dynamic sphere and two probe volumes, baked shadowed at low samples (what is
checked is what is rebaked, not the light).
"""

import bpy
import numpy as np
import pytest

from conftest import add_light, labels_drawn, run_cli
from test_stale import stored
from prt_addon.blender import fingerprint, probe_volumes
from prt_addon.core.bake import BakeSettings
from prt_addon.core.fingerprint import PROBE_CHANGES

SETTINGS = {"order": 3, "samples": 16, "mode": "shadowed", "workers": 1}


def use_settings(**changed):
    for key, value in {**SETTINGS, **changed}.items():
        setattr(bpy.context.scene.prt_bake, key, value)


def add_volume(location, scale, resolution):
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    volume.location, volume.scale, volume.prt_probe_resolution = location, scale, resolution
    return volume


@pytest.fixture
def scene(empty_scene):
    """(floor, wall, sphere, volume A, volume B), all baked; nothing selected."""
    bpy.ops.mesh.primitive_plane_add(size=8.0)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.0), scale=(0.4, 4.0, 2.0))
    wall = bpy.context.object
    bpy.ops.mesh.primitive_uv_sphere_add(segments=12, ring_count=6, radius=0.3, location=(-1.5, 0.0, 0.7))
    sphere = bpy.context.object
    sphere.prt_dynamic = True
    first = add_volume((-1.5, 0.0, 1.0), (1.0, 1.0, 1.0), (2, 2, 2))
    second = add_volume((1.5, 0.0, 1.0), (1.0, 1.0, 1.0), (3, 1, 2))
    bpy.ops.object.select_all(action="DESELECT")
    use_settings()
    assert bpy.ops.prt.bake() == {"FINISHED"}
    return floor, wall, sphere, first, second


def stale(**settings) -> dict:
    current = bpy.context.scene.prt_bake.to_settings()
    return fingerprint.stale_volumes(bpy.context, BakeSettings(**{**vars(current), **settings}))


def probes_stored(volume) -> tuple:
    """The volume's arrays' bytes and metadata: what must not change when its bake is kept."""
    return (bytes(np.frombuffer(volume[probe_volumes.TRANSFER_KEY], dtype=np.float32)),
            bytes(np.frombuffer(volume[probe_volumes.VALID_KEY], dtype=np.int32)),
            volume[probe_volumes.METADATA_KEY].to_dict())


def test_a_probe_volume_stores_its_fingerprint_and_is_up_to_date(scene):
    *_, first, second = scene
    meta = first[probe_volumes.METADATA_KEY].to_dict()
    assert sorted(meta[fingerprint.FINGERPRINT_KEY]) == sorted(PROBE_CHANGES)
    assert stale() == {first.name: [], second.name: []}


def test_what_makes_a_probe_volume_stale(scene):
    floor, wall, sphere, first, second = scene
    sphere.location = (1.5, 0.5, 1.2)  # a dynamic object is in no probe's bake
    sphere.rotation_euler.z = 1.0
    assert stale() == {first.name: [], second.name: []}
    assert stale(target_error=0.01) == {first.name: [], second.name: []}  # a shadowed probe casts Samples rays
    assert stale(samples=32) == {first.name: ["settings changed"], second.name: ["settings changed"]}
    first.location.x += 0.25
    second.scale.z = 1.5
    assert stale() == {first.name: ["moved or scaled"], second.name: ["moved or scaled"]}
    first.location.x -= 0.25
    second.scale.z = 1.0
    first.empty_display_size = 1.5
    second.prt_probe_resolution = (3, 1, 3)
    assert stale() == {first.name: ["moved or scaled"], second.name: ["resolution changed"]}
    first.empty_display_size = 1.0
    second.prt_probe_resolution = (3, 1, 2)
    assert stale() == {first.name: [], second.name: []}
    wall.location.x += 0.1  # a static wall: every probe may see it
    assert stale() == {first.name: ["static scene changed"], second.name: ["static scene changed"]}
    assert stale(mode="unshadowed") == {}  # an unshadowed bake bakes no probes


def test_bake_stale_rebakes_a_moved_volume_alone_and_leaves_everything_else_byte_identical(scene):
    floor, wall, sphere, first, second = scene
    receivers = {ob.name: stored(ob) for ob in (floor, wall, sphere)}
    kept = probes_stored(second)
    old = probes_stored(first)
    first.location.x -= 0.5
    assert stale() == {first.name: ["moved or scaled"], second.name: []}
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert stale() == {first.name: [], second.name: []}
    assert probes_stored(second) == kept
    assert {ob.name: stored(ob) for ob in (floor, wall, sphere)} == receivers
    assert probes_stored(first)[2]["bake_id"] != old[2]["bake_id"]
    placement = np.array(first[probe_volumes.METADATA_KEY]["placement"]).reshape(4, 4)
    np.testing.assert_allclose(placement, np.array(first.matrix_world), atol=1e-6)
    rebaked = probes_stored(first)
    assert bpy.ops.prt.bake_stale() == {"CANCELLED"}  # nothing stale: nothing baked, nothing written
    assert probes_stored(first) == rebaked and probes_stored(second) == kept


def test_bake_stale_rebakes_volumes_with_the_receivers_a_moved_wall_made_stale(scene):
    floor, wall, sphere, first, second = scene
    dynamic = stored(sphere)
    ids = {volume.name: volume[probe_volumes.METADATA_KEY]["bake_id"] for volume in (first, second)}
    wall.location.x += 0.1
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert stale() == {first.name: [], second.name: []}
    assert all(volume[probe_volumes.METADATA_KEY]["bake_id"] != ids[volume.name] for volume in (first, second))
    assert stored(sphere) == dynamic  # the dynamic sphere does not see the wall
    assert fingerprint.stale_receivers(bpy.context, bpy.context.scene.prt_bake.to_settings()) == {
        floor.name: [], wall.name: [], sphere.name: []}


@pytest.mark.parametrize("mode", ["shadowed", "interreflected"])
def test_a_volume_rebaked_alone_holds_the_probes_a_whole_bake_gives(scene, mode):
    """Rebaked alone, with no receiver stale, a volume is baked against the same scene (interreflected: the
    surfaces solved as bouncers, since none is a receiver) with the same rays (its probes' are keyed by its name,
    not by the volumes baked with it): its probes are those of a bake of everything, bit for bit."""
    floor, wall, sphere, first, second = scene
    use_settings(mode=mode)
    assert bpy.ops.prt.bake() == {"FINISHED"}
    second.location.x += 0.5
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    alone = probe_volumes.read(second)
    assert bpy.ops.prt.bake() == {"FINISHED"}
    whole = probe_volumes.read(second)
    np.testing.assert_array_equal(alone.matrices, whole.matrices)
    np.testing.assert_array_equal(alone.valid, whole.valid)


def panel(volume) -> list[str]:
    bpy.context.view_layer.objects.active = volume
    return labels_drawn(bpy.types.PRT_PT_probe_volume, [])


def test_the_panel_says_at_once_that_a_volume_moved_and_after_check_that_the_scene_changed(scene):
    floor, wall, sphere, first, second = scene
    assert "Status not checked" in panel(first)
    assert bpy.ops.prt.check_stale() == {"FINISHED"}
    assert any(line.startswith("Up to date (") for line in panel(first))
    first.location.x += 0.5
    second.prt_probe_resolution = (2, 1, 2)
    bpy.context.view_layer.update()
    assert "Stale: moved or scaled since the bake" in panel(first)  # before any Check: a matrix's digest
    assert "Stale: resolution changed since the bake" in panel(second)
    wall.location.x += 0.1
    assert bpy.ops.prt.check_stale() == {"FINISHED"}
    assert any(line.startswith("Stale: moved or scaled, static scene changed (") for line in panel(first))
    assert any(line.startswith("Stale: resolution changed, static scene changed (") for line in panel(second))
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert "Status not checked" in panel(first)  # a new bake: the check was of the old one
    assert not any(line.startswith("Stale:") for line in panel(first) + panel(second))


def test_the_display_lights_from_a_moved_volume_where_it_was_baked_and_says_so(scene, capfd):
    """The probes stay where they were baked: a dynamic sphere inside them is lit as before the volume moved."""
    floor, wall, sphere, first, second = scene
    add_light(theta=1.0, phi=0.0, strength=3.0, angular_radius=0.0)  # the wall shadows the sphere
    sphere.location.z += 0.01  # a refresh with the sphere where the probes are
    bpy.context.view_layer.update()
    before = np.array([colour.color[:] for colour in sphere.data.color_attributes["prt_color"].data])
    first.location.x -= 3.0  # away from the sphere: it would get the distant light alone from the volume here
    sphere.location.z -= 0.01
    bpy.context.view_layer.update()
    sphere.location.z += 0.01
    bpy.context.view_layer.update()
    after = np.array([colour.color[:] for colour in sphere.data.color_attributes["prt_color"].data])
    np.testing.assert_array_equal(after, before)
    del first[probe_volumes.METADATA_KEY]  # without its probes, the distant light: the wall's shadow is gone
    sphere.location.z -= 0.01
    bpy.context.view_layer.update()
    unshadowed = np.array([colour.color[:] for colour in sphere.data.color_attributes["prt_color"].data])
    assert unshadowed[:, 0].mean() > 1.5 * before[:, 0].mean()
    assert (f"PRT: probe volume {first.name!r}: moved or scaled since its bake; lighting from its probes where they "
            f"were baked until Bake Stale rebakes it") in capfd.readouterr().out


def test_cli_stale_only_rebakes_a_moved_volume_alone_then_nothing(scene, tmp_path):
    *_, first, second = scene
    first.location.y += 0.3
    path = tmp_path / "probes.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    options = ("--order", "3", "--samples", "16", "--mode", "shadowed", "--stale-only")
    result = run_cli("bake", path, *options)
    assert result.returncode == 0, result.stderr
    assert (f"PRT bake stale: rebaking 0 of 3 objects and 1 of 2 probe volumes: {first.name} (moved or scaled)"
            in result.stdout)
    assert "PRT bake: 0 objects" in result.stdout and "; 8 probes in 1 probe volume, 128 rays" in result.stdout
    baked = path.read_bytes()
    result = run_cli("bake", path, *options)
    assert result.returncode == 0, result.stderr
    assert "PRT bake stale: nothing to rebake, 3 objects and 2 probe volumes up to date" in result.stdout
    assert path.read_bytes() == baked


def test_bake_stale_rebakes_a_stale_dynamic_object_and_a_moved_volume_together(scene):
    """The dynamic object bakes alone, in its own frame; the volume with the static scene, which stays as it was."""
    floor, wall, sphere, first, second = scene
    static = {ob.name: stored(ob) for ob in (floor, wall)}
    kept, dynamic_id = probes_stored(second), stored(sphere)[1]["bake_id"]
    sphere.data.vertices[0].co.z += 0.05  # its own geometry: a dynamic object's only stale part but settings
    first.location.z += 0.2
    assert fingerprint.stale_receivers(bpy.context, bpy.context.scene.prt_bake.to_settings())[sphere.name] == [
        "geometry changed"]
    assert bpy.ops.prt.bake_stale() == {"FINISHED"}
    assert stale() == {first.name: [], second.name: []}
    assert stored(sphere)[1]["bake_id"] != dynamic_id
    assert {ob.name: stored(ob) for ob in (floor, wall)} == static and probes_stored(second) == kept
