"""The extension installs, registers, and unregisters cleanly, the way users install it."""

import subprocess
import sys
import zipfile

import bpy
import pytest

from conftest import ADDON_MODULE, ROOT, blender_ext_tool


def test_manifest_validates():
    result = subprocess.run([sys.executable, str(blender_ext_tool()), "validate", str(ROOT)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr


def test_zip_holds_only_the_addon(built_zip):
    names = zipfile.ZipFile(built_zip).namelist()
    assert {"blender_manifest.toml", "__init__.py", "LICENSE", "prt_addon/__init__.py",
            "prt_addon/core/sh.py"} <= set(names)
    strays = [n for n in names
              if n not in ("blender_manifest.toml", "__init__.py", "LICENSE")
              and not (n.startswith("prt_addon/") and n.endswith(".py"))]
    assert strays == []


def _our_classes():
    return [cls for cls in bpy.types.Operator.__subclasses__() + bpy.types.Panel.__subclasses__()
            + bpy.types.PropertyGroup.__subclasses__() + bpy.types.UIList.__subclasses__()
            if cls.__module__.startswith(ADDON_MODULE)]


def _our_handlers():
    """{handler list name: [function names]} of our functions in bpy.app.handlers."""
    found = {}
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if not name.startswith("_") and isinstance(handlers, list):
            ours = [f.__name__ for f in handlers if getattr(f, "__module__", "").startswith(ADDON_MODULE)]
            if ours:
                found[name] = ours
    return found


def test_registered_with_blender_names(addon):
    assert addon in bpy.context.preferences.addons
    for op in ("bake", "clear", "light_add", "light_remove"):
        assert getattr(bpy.ops.prt, op).idname() == f"PRT_OT_{op}"
    for panel in ("PRT_PT_bake", "PRT_PT_lights"):
        assert getattr(bpy.types, panel).bl_category == "PRT"
    names = [cls.__name__ for cls in _our_classes()]
    assert "PRT_OT_bake" in names
    for name in names:
        kind = name.split("_")[1]
        assert name.startswith("PRT_") and kind in {"OT", "PT", "PG", "UL", "MT"}, name


@pytest.mark.parametrize("cycle", [1, 2])
def test_disable_enable_leaves_nothing_behind(addon, cycle):
    bpy.ops.preferences.addon_disable(module=addon)
    assert not hasattr(bpy.types, "PRT_OT_bake")
    assert not hasattr(bpy.types.Scene, "prt_bake")
    assert _our_handlers() == {}
    assert not hasattr(bpy.types.Scene, "prt_lights")
    bpy.ops.preferences.addon_enable(module=addon)
    assert hasattr(bpy.types, "PRT_OT_bake")
    assert bpy.context.scene.prt_bake.order == 4
    assert _our_handlers() == {"depsgraph_update_post": ["on_depsgraph_update"],
                               "frame_change_post": ["on_frame_change"], "load_post": ["on_load_post"]}
    ours = [f for handlers in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post)
            for f in handlers if f.__module__.startswith(ADDON_MODULE)]
    assert all(hasattr(f, "_bpy_persistent") for f in ours)  # kept when another file is loaded
