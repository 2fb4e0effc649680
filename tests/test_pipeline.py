"""A bake in its four steps (blender.scene_bake): the request and the plan, and so the sidebar's Check, leave every
datablock as it was and cast no ray of the bake, even where a texel receiver needs PRT's own lightmap UV map (packed
on a temporary copy) and an Auto receiver needs its probes; storing adds the UV map; Auto's probes are a step of the
execution, with its progress and cancel."""

import importlib

import bpy
import numpy as np
import pytest

from prt_addon.blender import texel_maps
from prt_addon.blender.execute import execute
from prt_addon.blender.plan import plan_bake
from prt_addon.blender.request import read_request
from prt_addon.blender.store import store
from prt_addon.core import bake, executors, estimator, ray_caster
from prt_addon.core.bake import BakeSettings
from datablocks import datablocks
from test_texels import ball, floor_quad

SETTINGS = BakeSettings(order=3, samples=256)


def scene():
    """A floor without a UV map stored per texel (PRT must add its lightmap UV map), a patio whose own UV map serves
    Auto (its probes decide), and a ball per vertex."""
    floor = floor_quad(cuts=2)
    floor.data.uv_layers.remove(floor.data.uv_layers[0])
    floor.prt_storage, floor.prt_resolution = "texel", 32
    patio = floor_quad(size=2.0, name="Patio")
    patio.location.x = 4.0
    patio.prt_storage = "auto"
    ball()
    for ob in bpy.data.objects:
        ob.select_set(False)
    return floor, patio


@pytest.fixture
def no_rays(monkeypatch):
    """Any ray engine built or chunk baked fails the test."""
    def cast(*args, **kwargs):
        pytest.fail("a ray was cast")
    monkeypatch.setattr(ray_caster.RayCaster, "__init__", cast)
    monkeypatch.setattr(bake.Occluders, "ray_caster", cast)
    monkeypatch.setattr(estimator, "bake_chunk", cast)


def test_the_request_and_the_plan_leave_every_datablock_and_cast_no_ray(empty_scene, no_rays):
    floor, patio = scene()
    before = datablocks()
    plan = plan_bake(read_request(bpy.context, SETTINGS))
    assert datablocks() == before
    assert texel_maps.PRT_UV_MAP not in floor.data.uv_layers and len(bpy.data.meshes) == 3
    planned = {receiver.name: receiver for receiver in plan.receivers}
    assert planned["Floor"].layout.uv_map == texel_maps.PRT_UV_MAP  # the pack's UVs, to be added when stored
    assert planned["Floor"].layout.uvs.shape == (len(floor.data.loops), 2)
    assert [candidate.name for candidate in plan.pending] == ["Patio"]  # its probes are the execution's


def test_the_check_button_writes_nothing_and_casts_no_ray_of_the_bake(empty_scene, addon, monkeypatch):
    scene()
    bpy.context.scene.prt_bake.samples = SETTINGS.samples
    before = datablocks()
    installed = importlib.import_module(f"{addon}.prt_addon.core.estimator")  # the one the operator runs
    baked, real = [], installed.bake_chunk
    monkeypatch.setattr(installed, "bake_chunk", lambda caster, receiver, *rest: (
        baked.append(receiver.name), real(caster, receiver, *rest))[1])
    assert bpy.ops.prt.check_bake() == {"FINISHED"}
    assert baked == []  # no chunk of the bake or of Auto's probes, and no sample to time
    assert datablocks() == before
    checklist = importlib.import_module(f"{addon}.prt_addon.ui.checks").last_checklist()  # for the panel
    assert [check.subject for check in checklist][:4] == ["output", "workers", "memory", "time"]


def test_storing_adds_the_lightmap_uv_map_the_plan_packed(empty_scene):
    floor, patio = scene()
    plan = plan_bake(read_request(bpy.context, SETTINGS))
    planned = next(receiver for receiver in plan.receivers if receiver.name == "Floor").layout.uvs
    report = store(plan, execute(plan, executors.InProcess()).run())
    layers = floor.data.uv_layers
    assert [layer.name for layer in layers] == [texel_maps.PRT_UV_MAP] and layers.active.name == texel_maps.PRT_UV_MAP
    uvs = np.empty(2 * len(floor.data.loops), dtype=np.float32)
    layers[texel_maps.PRT_UV_MAP].uv.foreach_get("vector", uvs)
    np.testing.assert_array_equal(uvs.reshape(-1, 2), planned)
    assert [layer.name for layer in patio.data.uv_layers] == ["UVMap"]  # Auto used the patio's own
    assert any(line.startswith("'Patio': Auto") for line in report.storage)


def test_autos_probes_step_with_the_bake_and_a_cancel_leaves_the_file(empty_scene):
    scene()
    before = datablocks()
    execution = execute(plan_bake(read_request(bpy.context, SETTINGS)), executors.InProcess())
    while execution.progress.fraction == 0.0:  # the probes' first chunk done, as a modal timer event sees it
        assert not execution.step(0.01)
    assert execution.auto.done_vertices > 0 and execution.main is None  # still probing: the bake waits for them
    assert execution.progress.fraction < 1.0
    execution.cancel()
    assert datablocks() == before
