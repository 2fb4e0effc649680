"""One definition of the bake settings (core.settings) reaches all three places that use it: the sidebar's
properties, the command line's options and help, and BakeSettings' defaults and range checks."""

import argparse

import bpy
import pytest

from prt_addon.commands.cli import build_parser
from prt_addon.core import settings as spec
from prt_addon.core.bake import BakeSettings

EVERY = spec.BAKE + (spec.WORKERS,)


def bake_options() -> dict:
    """{dest: action} of `prt bake`."""
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {action.dest: action for action in commands.choices["bake"]._actions}


@pytest.mark.parametrize("setting", EVERY, ids=lambda s: s.name)
def test_panel_property_has_the_settings_label_default_and_range(addon, setting):
    prop = bpy.types.Scene.bl_rna.properties["prt_bake"].fixed_type.properties[setting.name]
    assert (prop.name, prop.description) == (setting.label, setting.description)
    if setting.choices:
        assert [(item.identifier, item.name, item.description) for item in prop.enum_items] == list(setting.choices)
        assert prop.default == setting.default
        return
    assert prop.default == pytest.approx(setting.default)
    assert prop.hard_min == pytest.approx(setting.minimum)
    if setting.maximum is not None:
        assert prop.hard_max == pytest.approx(setting.maximum)


@pytest.mark.parametrize("setting", EVERY, ids=lambda s: s.name)
def test_command_line_option_has_the_settings_default_range_and_help(setting):
    option = bake_options()[setting.name]
    assert option.option_strings == ["--" + setting.name.replace("_", "-")]
    assert option.default is argparse.SUPPRESS  # left out when not given, so a preset's value can stand
    assert option.help.startswith(setting.description)
    assert option.help.endswith(f"default {'auto' if setting.auto else setting.default}")
    if setting.choices:
        assert option.choices == [identifier for identifier, _, _ in setting.choices]
    else:
        assert setting.range_text() in option.help


@pytest.mark.parametrize("setting", spec.BAKE, ids=lambda s: s.name)
def test_bake_settings_defaults_are_the_definitions(setting):
    expected = None if setting.auto else setting.default
    assert getattr(BakeSettings(), setting.name) == expected
    assert BakeSettings().problems() == []


@pytest.mark.parametrize("setting", [s for s in spec.BAKE if s.maximum is not None], ids=lambda s: s.name)
def test_a_value_past_the_range_is_refused_by_name(setting):
    over = setting.maximum * 2 + 1
    problems = BakeSettings(**{setting.name: type(setting.default)(over)}).problems()
    assert any(problem.startswith(f"{setting.label.lower()} must be {setting.range_text()}") for problem in problems)


def test_panel_auto_bounces_map_to_none(addon, empty_scene):
    settings = empty_scene.prt_bake
    assert settings.to_settings().bounces is None  # auto, as the command line's default
    settings.auto_bounces, settings.bounces = False, 3
    assert settings.to_settings().bounces == 3
