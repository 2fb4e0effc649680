"""Shared fixtures. bpy is imported lazily so the core's tests run without it."""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

EXTENSION_ID = "prt"
TEST_REPO = "prt_test_repo"
ADDON_MODULE = f"bl_ext.{TEST_REPO}.{EXTENSION_ID}"


def blender_ext_tool() -> Path:
    import bpy
    return Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"


@pytest.fixture(scope="session")
def built_zip(tmp_path_factory) -> Path:
    """The extension zip, built by Blender's own tool from this checkout."""
    out = tmp_path_factory.mktemp("build")
    subprocess.run([sys.executable, str(blender_ext_tool()), "build", "--source-dir", str(ROOT),
                    "--output-dir", str(out)], check=True, capture_output=True, text=True)
    (zip_path,) = out.glob("*.zip")
    return zip_path


@pytest.fixture(scope="session")
def addon(built_zip):
    """The zip installed the way "Install from Disk" does, into a fresh local repository, and enabled."""
    import bpy
    directory = tempfile.mkdtemp(prefix="prt_extensions_")
    bpy.context.preferences.extensions.repos.new(
        name=TEST_REPO, module=TEST_REPO, custom_directory=directory, source="USER")
    bpy.ops.extensions.package_install_files(filepath=str(built_zip), repo=TEST_REPO, enable_on_install=True)
    yield ADDON_MODULE
    if ADDON_MODULE in bpy.context.preferences.addons:
        bpy.ops.preferences.addon_disable(module=ADDON_MODULE)


@pytest.fixture
def empty_scene(addon):
    """A fresh empty file with the add-on enabled."""
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)
    yield bpy.context.scene
    bpy.ops.wm.read_homefile(use_empty=True)


def run_cli(*args, cwd=ROOT, timeout=600):
    """`python -m prt_addon ...` in a fresh process, as a user runs it."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "prt_addon", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)
