"""Shared fixtures. bpy is imported lazily so the core's tests run without it."""

import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

EXTENSION_ID = "prt"
TEST_REPO = "prt_test_repo"
ADDON_MODULE = f"bl_ext.{TEST_REPO}.{EXTENSION_ID}"

# Blender's user extensions folder for this run and the processes it starts, set before bpy is imported: installing
# the extension extracts its wheels into <this>/.local/lib/pythonX.Y/site-packages, not into the user's own.
USER_EXTENSIONS = Path(tempfile.mkdtemp(prefix="prt_user_extensions_"))
os.environ["BLENDER_USER_EXTENSIONS"] = str(USER_EXTENSIONS)


def pytest_sessionfinish(session, exitstatus):
    session.config.prt_exit_status = int(exitstatus)
    shutil.rmtree(USER_EXTENSIONS, ignore_errors=True)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Blender 4.5's bpy module can hang at the very end of a process: a static destructor destroys the condition
    variable its delayed file-close thread still waits on (seen after this suite: ~GlobalState blocked in
    pthread_cond_destroy while delayed_close_thread_run waits). Once pytest has printed and saved everything, such
    a process leaves at once with pytest's exit status instead of running C++ static destructors."""
    bpy = sys.modules.get("bpy")
    if bpy is not None and bpy.app.version < (5, 0, 0) and hasattr(config, "prt_exit_status"):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(config.prt_exit_status)


def blender_ext_tool() -> Path:
    import bpy
    return Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"


def this_platform() -> str:
    """Blender's name of this machine's platform (e.g. linux-x64), which picks the zip it installs."""
    spec = importlib.util.spec_from_file_location("blender_ext", blender_ext_tool())
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool.platform_from_this_system()


@pytest.fixture(scope="session")
def built_zips(tmp_path_factory) -> dict[str, Path]:
    """{platform: its zip}: the extension built by Blender's own tool from this checkout, one zip per platform of
    the manifest (`build --split-platforms`), each with the manifest's wheels for that platform."""
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    missing = [wheel for wheel in manifest["wheels"] if not (ROOT / wheel).is_file()]
    assert not missing, f"{missing[0]} is missing: run `python wheels/fetch.py` (setup.sh does)"
    out = tmp_path_factory.mktemp("build")
    done = subprocess.run([sys.executable, str(blender_ext_tool()), "build", "--split-platforms", "--source-dir",
                           str(ROOT), "--output-dir", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    version = manifest["version"]
    return {platform: out / f"{EXTENSION_ID}-{version}-{platform.replace('-', '_')}.zip"
            for platform in manifest["platforms"]}


@pytest.fixture(scope="session")
def built_zip(built_zips) -> Path:
    """This platform's zip: the one a user of this machine installs."""
    return built_zips[this_platform()]


@pytest.fixture(scope="session")
def sample_scene_files(tmp_path_factory) -> Path:
    """The folder of the sample scenes, built by sample_scenes/make_scenes.py in this Blender's file format, as
    setup.sh builds them."""
    folder = tmp_path_factory.mktemp("sample_scenes")
    subprocess.run([sys.executable, str(ROOT / "sample_scenes" / "make_scenes.py"), str(folder)], check=True,
                   capture_output=True, timeout=300)
    return folder


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


@pytest.fixture
def prt(addon):
    """The installed add-on's modules: where identity matters (its property groups, handlers and light
    classes), use these rather than the checkout's `prt_addon`."""
    class Modules:
        def __getattr__(self, name):
            room = "ui" if name == "overlays" else "blender"
            return importlib.import_module(f"{addon}.prt_addon.{room}.{name}")
    return Modules()


class FakeLayout:
    """Stands in for a UILayout: records the properties a panel draws and checks that they exist."""

    def __init__(self, drawn):
        self.drawn = drawn
        self.enabled = True
        self.use_property_split = False

    def _child(self, *args, **kwargs):
        return self

    row = column = _child

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        self.drawn.append(name)

    def template_list(self, list_type, list_id, data, name, active_data, active_name, **kwargs):
        import bpy
        assert hasattr(bpy.types, list_type)
        assert name in data.bl_rna.properties and active_name in active_data.bl_rna.properties

    def template_ID(self, data, name, **kwargs):
        self.prop(data, name)

    def operator(self, idname, **kwargs):
        import bpy
        category, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, category), name), idname

    def operator_menu_enum(self, idname, name, **kwargs):
        self.operator(idname)

    def label(self, **kwargs):
        pass

    def progress(self, **kwargs):
        pass


def labels_drawn(panel, drawn: list) -> list[str]:
    """The texts of the labels `panel` draws now, the properties it draws added to `drawn`."""
    import bpy
    labels = []

    class Layout(FakeLayout):
        def label(self, text="", **kwargs):
            labels.append(text)

    panel.draw(SimpleNamespace(layout=Layout(drawn)), bpy.context)
    return labels


def add_light(kind="SUN", **settings):
    """An SH light added as the panel's + button adds it, then set."""
    import bpy
    bpy.ops.prt.light_add(kind=kind)
    light = bpy.context.scene.prt_lights[-1]
    for name, value in settings.items():
        setattr(light, name, value)
    return light


def run_cli(*args, cwd=ROOT, timeout=600):
    """`python -m prt_addon ...` in a fresh process, as a user runs it; a command that hangs fails the test
    (subprocess.TimeoutExpired) instead of stalling the suite."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "prt_addon", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def start_cli(args, folder: Path, command=("-m", "prt_addon")) -> subprocess.Popen:
    """`python -m prt_addon ARGS` started in the background, as a farm starts it, with a TMPDIR of its own
    (folder/tmp, made here) and its stdout and stderr in folder/stdout.txt and folder/stderr.txt, which a test can
    read while it runs. `command` replaces `-m prt_addon` (e.g. `-c SCRIPT`)."""
    (folder / "tmp").mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT), TMPDIR=str(folder / "tmp"))
    with open(folder / "stdout.txt", "w") as out, open(folder / "stderr.txt", "w") as errors:
        return subprocess.Popen([sys.executable, *command, *map(str, args)], cwd=ROOT, env=env, stdout=out,
                                stderr=errors)


def wait_until(condition, what: str, process=None, timeout_s: float = 120.0):
    """Polls `condition()` until it is truthy and returns it; fails after `timeout_s`, or as soon as `process`
    has ended without it."""
    deadline = time.monotonic() + timeout_s
    while not (found := condition()):
        if process is not None and process.poll() is not None:
            raise AssertionError(f"the process ended (exit code {process.returncode}) before {what}")
        if time.monotonic() > deadline:
            raise AssertionError(f"no {what} after {timeout_s:.0f} s")
        time.sleep(0.05)
    return found


@pytest.fixture
def chunks_baked_here(monkeypatch):
    """The first rows of the chunks the test's own process bakes, in order; worker processes run the same code
    elsewhere, unrecorded."""
    from prt_addon.core import estimator
    here, real, baked = os.getpid(), estimator.bake_chunk, []

    def recorded(caster, receiver, rows, settings):
        if os.getpid() == here:
            baked.append(int(rows[0]))
        return real(caster, receiver, rows, settings)

    monkeypatch.setattr(estimator, "bake_chunk", recorded)
    return baked
