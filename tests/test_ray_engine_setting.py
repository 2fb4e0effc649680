"""The Ray Engine setting: Auto casts with Embree where it imports and says once, clearly, where it falls back to
BVHTree; Embree asked for where it is not installed is refused in one line before any work, and so is a worker or
farm shard whose job names it; the report, the summary line and the stored bake name the engine and its version;
the engines' bakes agree, and each engine's bake is the same bits with any number of workers."""

import json
import os
import subprocess
import sys
import textwrap

import bpy
import numpy as np
import pytest

from conftest import ROOT
from test_bake_core import FORKED, SPAWNED, assert_bit_identical, disc
from prt_addon.core import bake, engines, job
from prt_addon.core.errors import InputError

pytest.importorskip("embreex")  # CI installs it; without it the fallback is all there is to test


@pytest.fixture
def without_embree(monkeypatch):
    """embreex fails to import in this process, as where no wheel exists for the platform."""
    monkeypatch.setitem(sys.modules, "embreex", None)  # `import embreex` raises ImportError
    monkeypatch.delitem(sys.modules, "prt_addon.core.engines.embree", raising=False)
    monkeypatch.delattr(engines, "embree", raising=False)


@pytest.fixture
def embree_hidden(tmp_path):
    """A PYTHONPATH entry on which embreex fails to import, for a process of its own: a package of that name
    ahead of the installed one, raising ImportError."""
    folder = tmp_path / "no_embree"
    (folder / "embreex").mkdir(parents=True)
    (folder / "embreex" / "__init__.py").write_text("raise ImportError('no Embree for this platform')\n")
    return folder


def cli(*args, hidden=None):
    """`python -m prt_addon ...` with embreex importable, or hidden behind `hidden`."""
    path = os.pathsep.join(map(str, filter(None, [hidden, ROOT])))
    return subprocess.run([sys.executable, "-m", "prt_addon", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, env=dict(os.environ, PYTHONPATH=path))


def test_auto_is_embree_where_it_imports():
    assert engines.choose("auto") == ("embree", None)
    assert engines.choose("bvhtree") == ("bvhtree", None) and engines.choose("embree") == ("embree", None)
    assert engines.label("embree").startswith("Embree 4.") and "via embreex 4." in engines.label("embree")
    assert engines.label("bvhtree", "Blender 5.3.0") == "BVHTree of Blender 5.3.0"


def test_auto_without_embree_is_bvhtree_with_a_note_and_embree_is_refused(without_embree):
    assert engines.choose("auto") == ("bvhtree", engines.AUTO_FALLBACK)
    assert "BVHTree" in engines.AUTO_FALLBACK and "embreex package) is not installed" in engines.AUTO_FALLBACK
    with pytest.raises(InputError, match=r"Ray Engine Embree: .*embreex.* is not installed.*choose Auto or BVHTree"):
        engines.choose("embree")
    with pytest.raises(InputError, match=r"the bake's ray engine is Embree: .*install embreex here"):
        engines.build("embree", np.zeros((3, 3)), np.array([[0, 1, 2]]), 1.0)
    assert engines.choose("bvhtree") == ("bvhtree", None)


def test_the_bake_names_its_engine_in_the_summary_the_report_and_the_stored_bake(tmp_path, sample_scene_files):
    reports = {}
    for setting in ("auto", "bvhtree"):
        out, report = tmp_path / f"{setting}.blend", tmp_path / f"{setting}.json"
        done = cli("bake", sample_scene_files / "suzanne.blend", "--objects", "Plane", "--order", "3", "--samples",
                   "32", "--ray-engine", setting, "--output", out, "--report", report)
        assert done.returncode == 0, done.stderr
        reports[setting] = json.loads(report.read_text())
        line = next(line for line in done.stdout.splitlines() if line.startswith("PRT bake: 1 objects"))
        assert f"k rays/s with {reports[setting]['ray_engine']}, " in line
        assert "warning" not in done.stderr
        bpy.ops.wm.open_mainfile(filepath=str(out), load_ui=False)
        assert bpy.data.objects["Plane"].data["prt"]["ray_engine"] == reports[setting]["ray_engine"]
    bpy.ops.wm.read_homefile(use_empty=True)
    assert reports["auto"]["ray_engine"] == engines.label("embree")
    assert reports["bvhtree"]["ray_engine"] == f"BVHTree of Blender {bpy.app.version_string}"
    embree, tree = (reports[setting]["per_object"]["Plane"] for setting in ("auto", "bvhtree"))
    assert embree["rays"] == tree["rays"] and embree["skipped_vertices"] == tree["skipped_vertices"]
    assert embree["est_rms_rel_error"] == pytest.approx(tree["est_rms_rel_error"], rel=1e-3)


def test_without_embree_auto_bakes_with_bvhtree_saying_so_once_and_embree_is_refused_before_any_work(
        tmp_path, sample_scene_files, embree_hidden):
    scene = sample_scene_files / "suzanne.blend"
    out, report = tmp_path / "out.blend", tmp_path / "report.json"
    done = cli("bake", scene, "--objects", "Plane", "--order", "3", "--samples", "16", "--output", out, "--report",
               report, hidden=embree_hidden)
    assert done.returncode == 0, done.stderr
    said = [line for line in (done.stdout + done.stderr).splitlines() if "embreex" in line]
    assert said == [f"prt:   info    note: {engines.AUTO_FALLBACK}"], said  # among the checks, before any ray
    written = json.loads(report.read_text())
    assert written["ray_engine"].startswith("BVHTree of Blender ") and written["notes"] == [engines.AUTO_FALLBACK]
    refused = cli("bake", scene, "--ray-engine", "embree", "--output", tmp_path / "never.blend", hidden=embree_hidden)
    assert refused.returncode == 1 and not (tmp_path / "never.blend").exists()
    assert refused.stderr.strip().splitlines() == [
        f"prt: error: Ray Engine Embree: {engines.EMBREE_MISSING}; choose Auto or BVHTree"]
    assert "prt: checks" not in refused.stdout  # refused as the request is read, before the checks and any ray


def test_a_spawned_worker_without_embree_fails_naming_it(monkeypatch, embree_hidden):
    """A job file names its engine (core.job_file); a worker where it is not installed stops at once and says so."""
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(embree_hidden), str(ROOT)]))
    rng = np.random.default_rng(5)
    positions = np.column_stack([rng.uniform(-1.5, 1.5, (600, 2)), np.zeros(600)])
    receiver = bake.Receiver("w", positions, np.tile([0.0, 0.0, 1.0], (600, 1)), 21)
    occluders = disc(1.0, 1.0, 64)
    occluders.engine = "embree"
    executor = SPAWNED()
    executor.min_rays, executor.start_s = 0, 0.0  # the worker gets its share of this small job
    with pytest.raises(RuntimeError, match=r"bake worker failed: .*the bake's ray engine is Embree: .*embreex"):
        job.TransferJob([receiver], occluders, bake.BakeSettings(order=3, samples=32), executor).run()


@pytest.mark.parametrize("engine", ["embree", "bvhtree"])
@pytest.mark.parametrize("launch", [SPAWNED, FORKED], ids=["spawned", "forked"])
def test_each_engines_bake_is_the_same_bits_with_workers(engine, launch):
    """Forked workers share the engine built here (Embree's scene is built before they fork); spawned ones build
    their own from the job file. Either way the bits are one process's."""
    rng = np.random.default_rng(5)
    positions = np.column_stack([rng.uniform(-1.5, 1.5, (600, 2)), np.zeros(600)])
    receiver = bake.Receiver("w", positions, np.tile([0.0, 0.0, 1.0], (600, 1)), 21)
    settings = bake.BakeSettings(mode="interreflected", order=3, samples=64)

    def occluders():
        found = disc(1.0, 1.0, 64)
        found.engine = engine
        return found
    one = job.TransferJob([receiver], occluders(), settings).run()[0]
    executor = launch()
    executor.min_rays, executor.start_s = 0, 0.0  # a worker gets its share of this small job
    shared = occluders()
    shared.ray_caster()  # built before the workers start, as the bake builds it
    two = job.TransferJob([receiver], shared, settings, executor).run()[0]
    assert_bit_identical(one, two)
    assert one.rays.sum() > 0 and not np.isnan(one.transfer).any()


def test_the_panels_name_the_engine_that_casts_and_that_cast_the_stored_bake(empty_scene):
    from conftest import FakeLayout
    from test_bake_blender import box, grid

    class Layout(FakeLayout):
        def label(self, text="", **kwargs):
            self.drawn.append(text)

        def menu(self, idname, **kwargs):
            pass

        def operator(self, idname, **kwargs):
            super().operator(idname)
            return type("Properties", (), {})()

    def drawn(panel) -> list:
        found = []
        panel.draw(type("Panel", (), {"layout": Layout(found)})(), bpy.context)
        return found
    grid("Floor")
    bpy.context.view_layer.objects.active = box("Cube")
    settings = empty_scene.prt_bake
    settings.order, settings.samples = 3, 16
    assert settings.ray_engine == "auto"
    bake_panel = drawn(bpy.types.PRT_PT_bake)
    assert "ray_engine" in bake_panel and f"Casts with {engines.label('embree')}" in bake_panel
    settings.ray_engine = "bvhtree"
    assert not any(line.startswith("Casts with") for line in drawn(bpy.types.PRT_PT_bake))
    assert bpy.ops.prt.bake() == {"FINISHED"}
    assert f"Cast with BVHTree of Blender {bpy.app.version_string}" in drawn(bpy.types.PRT_PT_bake_info)
