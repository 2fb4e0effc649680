"""The extension installs, registers, and unregisters cleanly, the way users install it; and the command line is
an installed package of the venv (pyproject.toml, which setup.sh installs), so `prt` runs in any folder."""

import os
from pathlib import Path
import subprocess
import sys
import tomllib
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
                               "frame_change_post": ["on_frame_change"],
                               "load_post": ["on_load_post", "forget_checklist"]}
    ours = [f for handlers in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post)
            for f in handlers if f.__module__.startswith(ADDON_MODULE)]
    assert all(hasattr(f, "_bpy_persistent") for f in ours)  # kept when another file is loaded


# -- the installed command line ---------------------------------------------------------------------------------

BIN = Path(sys.executable).parent


def without_pythonpath() -> dict:
    return {name: value for name, value in os.environ.items() if name != "PYTHONPATH"}


def test_prt_and_python_m_prt_addon_run_in_any_folder_from_a_checkouts_editable_install(tmp_path):
    """Without PYTHONPATH, in a folder that holds nothing of the project: the venv's `prt` and `python -m prt_addon`
    both answer, and the package they import is a checkout's (editable: the venv runs the checkout as it is)."""
    for command in ([BIN / "prt", "--help"], [sys.executable, "-m", "prt_addon", "--help"]):
        done = subprocess.run(command, cwd=tmp_path, env=without_pythonpath(), capture_output=True, text=True,
                              timeout=300)
        assert done.returncode == 0 and done.stdout.startswith("usage: prt "), (command, done.stderr)
    found = subprocess.run([sys.executable, "-c", "import prt_addon; print(prt_addon.__file__)"], cwd=tmp_path,
                           env=without_pythonpath(), capture_output=True, text=True, timeout=300)
    checkout = Path(found.stdout.strip()).parents[1]
    assert (checkout / "blender_manifest.toml").is_file(), found
    assert tomllib.loads((checkout / "pyproject.toml").read_text())["project"]["scripts"] == {
        "prt": "prt_addon.__main__:console"}


def test_prt_bakes_files_named_from_the_folder_it_runs_in(tmp_path):
    """`prt bake` in a folder of the user's, the paths relative to it (this checkout's code: PYTHONPATH)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=3, y_subdivisions=3)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    bpy.ops.wm.read_homefile(use_empty=True)
    done = subprocess.run([BIN / "prt", "bake", "scene.blend", "--order", "2", "--samples", "8", "--output",
                           "baked.blend"], cwd=tmp_path, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "baked.blend"), load_ui=False)
    try:
        assert "prt" in bpy.data.objects["Grid"].data
    finally:
        bpy.ops.wm.read_homefile(use_empty=True)


def test_the_package_has_the_extensions_version():
    """One version: the extension's manifest's, which the package repeats."""
    package = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert package["version"] == tomllib.loads((ROOT / "blender_manifest.toml").read_text())["version"]
