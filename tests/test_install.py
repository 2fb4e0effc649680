"""The extension installs, registers, and unregisters cleanly, the way users install it: this platform's zip, with
the embreex wheels it bundles for the Embree ray engine; and the command line is an installed package of the venv
(pyproject.toml, which setup.sh installs), so `prt` runs in any folder."""

import hashlib
import importlib.machinery
import importlib.util
import json
import os
from pathlib import Path
import re
import subprocess
import sys
import tomllib
import zipfile

import bpy
import pytest

from conftest import ADDON_MODULE, ROOT, TEST_REPO, USER_EXTENSIONS, blender_ext_tool, this_platform

MANIFEST = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
ADDON_FILES = ("blender_manifest.toml", "__init__.py", "LICENSE", "THIRD_PARTY_LICENSES.txt")
# The embreex wheels each platform's zip must hold, by the wheels' platform tags (PyPI has none for ARM Linux or
# ARM Windows): both Pythons of the supported Blenders, 3.11 (4.5, 5.0) and 3.13 (5.2, 5.3).
WHEEL_TAGS = {
    "linux-x64": "manylinux_2_27_x86_64.manylinux_2_28_x86_64",
    "linux-arm64": None,
    "windows-x64": "win_amd64",
    "windows-arm64": None,
    "macos-x64": "macosx_13_0_x86_64",
    "macos-arm64": "macosx_13_0_arm64",
}
EMBREEX = "embreex-4.4.0.post1"


def test_manifest_validates():
    result = subprocess.run([sys.executable, str(blender_ext_tool()), "validate", str(ROOT)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr


def expected_wheels(platform: str) -> set[str]:
    tag = WHEEL_TAGS[platform]
    return set() if tag is None else {f"wheels/{EMBREEX}-{python}-{python}-{tag}.whl" for python in ("cp311", "cp313")}


def test_zip_holds_only_the_addon_and_this_platforms_wheels(built_zip):
    assert built_zip.name == f"prt-{MANIFEST['version']}-{this_platform().replace('-', '_')}.zip"
    names = zipfile.ZipFile(built_zip).namelist()
    assert {*ADDON_FILES, "prt_addon/__init__.py", "prt_addon/core/sh.py"} <= set(names)
    assert {n for n in names if n.startswith("wheels/")} == expected_wheels(this_platform())
    strays = [n for n in names
              if n not in ADDON_FILES and not n.startswith("wheels/")
              and not (n.startswith("prt_addon/") and n.endswith(".py"))]
    assert strays == []


def test_the_manifest_names_every_platform_and_all_their_wheels():
    assert sorted(MANIFEST["platforms"]) == sorted(WHEEL_TAGS)
    assert {wheel.removeprefix("./") for wheel in MANIFEST["wheels"]} == set().union(
        *map(expected_wheels, WHEEL_TAGS))


def wheels_fetch():
    """wheels/fetch.py as a module."""
    spec = importlib.util.spec_from_file_location("wheels_fetch", ROOT / "wheels" / "fetch.py")
    fetch = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fetch)
    return fetch


def test_fetch_asks_pip_for_each_wheel_by_its_python_and_platform_tags():
    fetch = wheels_fetch()
    assert fetch.pip_download_arguments(
        "embreex-4.4.0.post1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl") == [
        "embreex==4.4.0.post1", "--no-deps", "--only-binary=:all:", "--python-version", "3.11", "--implementation",
        "cp", "--platform", "manylinux_2_27_x86_64", "--platform", "manylinux_2_28_x86_64"]
    assert fetch.pip_download_arguments("embreex-4.4.0.post1-cp313-cp313-win_amd64.whl")[4:] == [
        "3.13", "--implementation", "cp", "--platform", "win_amd64"]


def test_fetch_stops_with_one_line_on_a_listed_wheel_without_a_hash(tmp_path, monkeypatch, capsys):
    fetch = wheels_fetch()
    manifest = tmp_path / "blender_manifest.toml"
    manifest.write_text('wheels = ["./wheels/embreex-4.4.0.post2-cp313-cp313-win_amd64.whl"]\n')
    monkeypatch.setattr(fetch, "MANIFEST", manifest)
    assert fetch.main() == 1
    assert capsys.readouterr().err == ("fetch: embreex-4.4.0.post2-cp313-cp313-win_amd64.whl: in blender_manifest.toml"
                                       " but without a SHA-256 in wheels/fetch.py\n")


@pytest.mark.parametrize("platform", sorted(WHEEL_TAGS))
def test_each_platforms_zip_holds_its_wheels_as_fetched_and_lists_them(built_zips, built_zip, platform):
    """A platform's zip holds that platform's wheels, byte for byte those wheels/fetch.py checked, the same add-on as
    this platform's zip, and a manifest that names that platform and those wheels (Blender installs what it
    lists)."""
    fetch = wheels_fetch()
    with zipfile.ZipFile(built_zips[platform]) as archive, zipfile.ZipFile(built_zip) as reference:
        wheels = {n for n in archive.namelist() if n.startswith("wheels/")}
        assert wheels == expected_wheels(platform)
        for wheel in wheels:
            assert hashlib.sha256(archive.read(wheel)).hexdigest() == fetch.SHA256[Path(wheel).name], wheel
        assert ({n for n in archive.namelist() if not n.startswith("wheels/")}
                == {n for n in reference.namelist() if not n.startswith("wheels/")})
        generated = tomllib.loads(archive.read("blender_manifest.toml").decode())["build"]["generated"]
    assert generated["platforms"] == [platform]
    assert {wheel.removeprefix("./") for wheel in generated["wheels"]} == wheels


def test_setup_installs_the_embreex_the_zips_bundle():
    """The venv's embreex (setup.sh, for the command line's bakes) is the version of the bundled wheels."""
    (pinned,) = re.findall(r"embreex==([^;\s\"']+)", (ROOT / "setup.sh").read_text())
    assert f"embreex-{pinned}" == EMBREEX


# -- the Embree engine's binding, from the installed zip's wheels ----------------------------------------------

def in_blender_with_the_installed_extension(code: str) -> subprocess.CompletedProcess:
    """Runs `code` in a new process that imports bpy as Blender starts, with the user extensions folder of this run
    (conftest): the installed wheels' site-packages come before the venv's, so `import embreex` is the zip's even
    where the venv has its own; and with the installed extension enabled from its repository (`ADDON_MODULE`)."""
    directory = bpy.context.preferences.extensions.repos[TEST_REPO].directory
    prelude = (f"import bpy\n"
               f"bpy.context.preferences.extensions.repos.new(name={TEST_REPO!r}, module={TEST_REPO!r}, "
               f"custom_directory={directory!r}, source='USER')\n"
               f"bpy.ops.preferences.addon_enable(module={ADDON_MODULE!r})\n")
    return subprocess.run([sys.executable, "-c", prelude + code], cwd=USER_EXTENSIONS, env=without_pythonpath(),
                          capture_output=True, text=True, timeout=300)


def installed_site_packages() -> Path:
    """Where Blender extracts the enabled extensions' wheels for this Python."""
    return USER_EXTENSIONS / ".local" / "lib" / "python{}.{}".format(*sys.version_info[:2]) / "site-packages"


ONE_TRIANGLE = """
import embreex
import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh
scene = rtcore_scene.EmbreeScene()
TriangleMesh(scene, np.array([[[0, 0, 1], [1, 0, 1], [0, 1, 1]]], np.float32))
origins = np.array([[0.2, 0.2, 0], [0.8, 0.8, 0], [0.2, 0.2, 0]], np.float32)
directions = np.array([[0, 0, 1], [0, 0, 1], [0, 0, -1]], np.float32)
print(embreex.__file__)
print((scene.run(origins, directions, query="OCCLUDED") >= 0).tolist())
print(scene.run(origins, directions, query="DISTANCE").tolist())
"""


def test_the_zips_embreex_wheel_is_installed_and_occludes_a_ray(addon):
    """Installing this platform's zip extracts its embreex wheel for this Python into the user extensions'
    site-packages, and Blender's Python imports embreex from there: a one-triangle scene (z = 1 over x, y ≥ 0,
    x + y ≤ 1) stops the ray up from (0.2, 0.2, 0) at distance 1, and neither the ray up from (0.8, 0.8, 0), which
    passes beside it, nor the one down from (0.2, 0.2, 0)."""
    if not expected_wheels(this_platform()):
        pytest.skip(f"PyPI has no embreex wheel for {this_platform()}")
    assert Path(bpy.utils.user_resource("EXTENSIONS")) == USER_EXTENSIONS
    site = installed_site_packages()
    assert (site / f"{EMBREEX}.dist-info").is_dir()
    assert (site / "embreex" / f"rtcore_scene{importlib.machinery.EXTENSION_SUFFIXES[0]}").is_file()
    done = in_blender_with_the_installed_extension(ONE_TRIANGLE)
    assert done.returncode == 0, done.stderr
    module, occluded, distances = done.stdout.strip().splitlines()[-3:]
    assert Path(module).is_relative_to(site)
    assert occluded == "[True, False, False]"
    distance = json.loads(distances)
    assert distance[0] == pytest.approx(1.0, abs=1e-6) and min(distance[1:]) > 1e30


EMBREE_BAKE = """
import sys
bpy.ops.mesh.primitive_plane_add(size=4.0)
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.0))
bpy.ops.object.select_all(action="DESELECT")
bpy.data.objects["Plane"].select_set(True)
settings = bpy.context.scene.prt_bake
settings.samples, settings.ray_engine = 64, "embree"
print(bpy.ops.prt.bake())
print(bpy.data.meshes["Plane"]["prt"]["ray_engine"])
print(sys.modules["embreex"].__file__)
"""


def test_the_installed_extension_bakes_with_embree_from_its_wheel(addon):
    """The Bake button with Ray Engine Embree, in a Blender whose embreex is the zip's: the bake finishes, its
    stored bake names Embree, and the embreex it cast with is the one extracted from the zip."""
    if not expected_wheels(this_platform()):
        pytest.skip(f"PyPI has no embreex wheel for {this_platform()}")
    done = in_blender_with_the_installed_extension(EMBREE_BAKE)
    assert done.returncode == 0, done.stderr
    finished, engine, module = done.stdout.strip().splitlines()[-3:]
    assert finished == "{'FINISHED'}" and engine.startswith("Embree"), done.stdout
    assert Path(module).is_relative_to(installed_site_packages())


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
