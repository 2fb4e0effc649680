"""Bake presets (issue 16): one definition (core.presets) reaches the panel's preset menu and `prt bake --preset`;
explicit options override a preset; the artist's own presets are added and removed through Blender's preset
system; workers default to one per core."""

import argparse
import os
from pathlib import Path

import bpy
import pytest

from conftest import ROOT
from prt_addon.commands.bake import settings_from
from prt_addon.commands.cli import build_parser
from prt_addon.core import presets, settings as spec
from prt_addon.core.bake import BakeSettings

BUNDLED = ROOT / "prt_addon" / "presets" / "prt" / "bake"


def parsed(*argv) -> argparse.Namespace:
    return build_parser().parse_args(["bake", "scene.blend", *argv])


def panel_values(settings) -> dict:
    values = {setting.name: getattr(settings, setting.name) for setting in presets.FIELDS}
    values["bounces"] = None if settings.auto_bounces else settings.bounces
    return values


def approx(values: dict) -> dict:
    return {name: pytest.approx(value) if isinstance(value, float) else value for name, value in values.items()}


@pytest.mark.parametrize("name", presets.PRESETS)
def test_every_preset_is_a_valid_bake_of_every_field(name):
    values = presets.preset_values(name)
    assert set(values) == {setting.name for setting in presets.FIELDS}
    assert BakeSettings(**values).problems() == []


def test_presets_grow_in_accuracy():
    draft, production, final = (BakeSettings(**presets.preset_values(name)) for name in ("draft", "production",
                                                                                         "final"))
    assert draft.order <= production.order <= final.order
    assert draft.target_error == 0 and 0 < final.target_error < production.target_error
    assert final.mode == "interreflected"


@pytest.mark.parametrize("name", presets.PRESETS)
def test_cli_preset_gives_its_values(name):
    chosen = settings_from(parsed("--preset", name.upper()))
    assert {field.name: getattr(chosen, field.name) for field in presets.FIELDS} == presets.preset_values(name)


def test_cli_options_given_override_the_preset_and_the_rest_stays():
    chosen = settings_from(parsed("--preset", "production", "--order", "4", "--target-error", "0", "--seed", "7"))
    expected = BakeSettings(**{**presets.preset_values("production"), "order": 4, "target_error": 0.0, "seed": 7})
    assert chosen == expected  # --order 4 is the default, and still overrides production's own order


def test_cli_without_a_preset_bakes_the_definitions_defaults():
    assert settings_from(parsed()) == BakeSettings()


def test_cli_refuses_an_unknown_preset():
    with pytest.raises(Exception, match="invalid choice: 'fastest'"):
        parsed("--preset", "fastest")


def test_workers_default_to_every_core():
    assert spec.WORKERS.default == 0 and spec.worker_count(0) == os.cpu_count()
    assert spec.worker_count(3) == 3
    assert not hasattr(parsed(), "workers")  # not given: the bake takes the definition's default


@pytest.mark.parametrize("name", presets.PRESETS)
def test_the_panel_operator_applies_the_same_values(empty_scene, name):
    settings = empty_scene.prt_bake
    settings.auto_bounces, settings.bounces, settings.seed, settings.workers = False, 7, 5, 1
    assert bpy.ops.prt.bake_preset(preset=name) == {"FINISHED"}
    assert panel_values(settings) == approx(presets.preset_values(name))
    assert (settings.seed, settings.workers) == (5, 1)  # not a preset's business
    assert settings.to_settings().problems() == []


@pytest.mark.parametrize("name", presets.PRESETS)
def test_each_bundled_preset_file_runs_from_blenders_preset_menu(empty_scene, name):
    path = BUNDLED / f"{presets.label(name)}.py"
    installed = bpy.utils.preset_find(presets.label(name), "prt/bake")
    assert installed and Path(installed).read_text() == path.read_text()  # the installed add-on's, found by Blender
    assert bpy.ops.script.execute_preset(filepath=installed, menu_idname="PRT_MT_bake_presets") == {"FINISHED"}
    assert panel_values(empty_scene.prt_bake) == approx(presets.preset_values(name))
    assert bpy.types.PRT_MT_bake_presets.bl_label == presets.label(name)


def test_the_bundled_files_are_the_presets():
    assert sorted(path.stem for path in BUNDLED.glob("*.py")) == sorted(map(presets.label, presets.PRESETS))


@pytest.fixture
def own_presets(tmp_path, monkeypatch):
    """The user's preset folder, in a temporary folder: Blender writes own presets to user_resource('SCRIPTS')."""
    folder = tmp_path / "presets" / "prt" / "bake"
    real = bpy.utils.user_resource
    monkeypatch.setattr(bpy.utils, "user_resource", lambda kind, path="", create=False: (
        str(tmp_path / path) if kind == "SCRIPTS" else real(kind, path=path, create=create)))
    folder.mkdir(parents=True)
    bpy.utils.register_preset_path(str(tmp_path))
    yield folder
    bpy.utils.unregister_preset_path(str(tmp_path))


def test_an_own_preset_is_added_run_and_removed(empty_scene, own_presets):
    settings = empty_scene.prt_bake
    bpy.ops.prt.bake_preset(preset="final")
    settings.order, settings.samples = 5, 300
    assert bpy.ops.prt.bake_preset_add(name="My Look") == {"FINISHED"}
    (written,) = own_presets.glob("*.py")
    bpy.ops.prt.bake_preset(preset="draft")
    assert bpy.ops.script.execute_preset(filepath=str(written), menu_idname="PRT_MT_bake_presets") == {"FINISHED"}
    assert panel_values(settings) == approx({**presets.preset_values("final"), "order": 5, "samples": 300})
    assert bpy.ops.prt.bake_preset_add(name=written.stem, remove_name=True) == {"FINISHED"}
    assert not written.exists()


def test_a_bundled_preset_cannot_be_removed(empty_scene, own_presets):
    assert bpy.ops.prt.bake_preset_add(name="Production", remove_name=True) == {"CANCELLED"}
    assert bpy.utils.preset_find("Production", "prt/bake")
