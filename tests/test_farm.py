"""Farm bakes: shards (`prt bake --shard K/N --out PART.npz`) merged by `prt merge` into the bake one process makes,
bit for bit; the refusals; and the three engines that run them for real: Flamenco's job type (compiled by Node
against a stand-in for its `author` API, its commands then run in dependency order), Open Job Description
(`openjd run`) and Dask (a LocalCluster, and a scheduler with two workers started and stopped here)."""

from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
import functools
import hashlib
import json
import os
import re
import resource
import shlex
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import bpy
import numpy as np
import pytest

import hostile_parts
from conftest import ROOT, run_cli
from test_bake_blender import box, grid
from test_interreflect_blender import coloured, wall
from test_stale import stored
from prt_addon.blender import farm, storage
from prt_addon.blender.execute import execute, local_executor
from prt_addon.commands import farm_dask
from prt_addon.core import executors, outputs, settings as spec
from prt_addon.core.bake import BakeSettings
from prt_addon.core.errors import InputError
from prt_addon.core.workers import shard_chunks

SETTINGS = ("--order", "3", "--samples", "16")
# (mode, receivers): interreflected with two receivers, so two further visible meshes only bounce light.
BAKES = [("unshadowed", None), ("shadowed", None), ("interreflected", "Floor,Red")]
VOLATILE = {"time_s", "date", "bake_id"}  # metadata that differs between any two bakes


def steady(meta) -> dict:
    """The metadata or report that two bakes of one scene share: all but VOLATILE's and the seconds of the error
    curves (its own, and per object)."""
    def kept(key, value):
        if key == "error_curve":
            return [{name: figure for name, figure in dict(row).items() if name != "seconds"} for row in value]
        if key == "per_object":
            return {name: steady(entry) for name, entry in value.items()}
        return value
    return {key: kept(key, value) for key, value in meta.items() if key not in VOLATILE}
FAKE_BLENDER = ROOT / "tests" / "fake_blender.py"
BIN = Path(sys.executable).parent


def room():
    """A floor of 289 vertices (3 chunks), a red and a green wall and a cube: 6 chunks in all."""
    coloured(grid("Floor", size=2.0, cuts=16), (0.8, 0.8, 0.8))
    coloured(wall("Red", 1.0), (0.8, 0.05, 0.05))
    coloured(wall("Green", -1.0), (0.05, 0.8, 0.05))
    return box("Cube", half=0.3, location=(0.0, 0.0, 0.3))


def save_scene(path: Path, build) -> Path:
    bpy.ops.wm.read_homefile(use_empty=True)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    return path


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """The room; the room with its cube moved (its parts are stale); the room without its cube (another scene)."""
    folder = tmp_path_factory.mktemp("farm_scenes")

    def moved():
        room().location.x += 0.2

    def without_cube():
        bpy.data.objects.remove(room())

    return {"room": save_scene(folder / "room.blend", room), "moved": save_scene(folder / "moved.blend", moved),
            "other": save_scene(folder / "other.blend", without_cube)}


def ok(result):
    assert result.returncode == 0, result.stderr
    return result


def bake_options(mode, objects):
    return [*SETTINGS, "--mode", mode, *(["--objects", objects] if objects else [])]


@pytest.fixture(scope="module")
def reference(scenes, tmp_path_factory):
    """One process's bake of the room: (the saved file, its report), once per (mode, receivers)."""
    folder = tmp_path_factory.mktemp("farm_reference")

    @functools.cache
    def bake(mode, objects=None):
        out, report = folder / f"{mode}.blend", folder / f"{mode}.json"
        ok(run_cli("bake", scenes["room"], *bake_options(mode, objects), "--output", out, "--report", report))
        return out, json.loads(report.read_text())
    return bake


def baked(path) -> dict:
    """Every baked object's PRT attributes (raw bytes) and metadata, but what differs between any two bakes."""
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    found = {}
    for ob in bpy.data.objects:
        if ob.type == "MESH" and storage.METADATA_KEY in ob.data:
            attributes, meta = stored(ob)
            found[ob.name] = attributes, steady(meta)
    bpy.ops.wm.read_homefile(use_empty=True)
    assert found
    return found


def assert_same_bake(path, reference_path):
    assert baked(path) == baked(reference_path)


def shard_and_merge(scene, folder: Path, shards: int, options, merge_report=None):
    parts = [folder / "parts" / "deep" / f"part-{shard}.npz" for shard in range(1, shards + 1)]
    for shard, part in enumerate(parts, start=1):
        result = ok(run_cli("bake", scene, "--shard", f"{shard}/{shards}", "--out", part, *options))
        assert f"PRT shard {shard}/{shards}:" in result.stdout
    out = folder / "merged.blend"
    ok(run_cli("merge", scene, *parts, "--output", out, *(["--report", merge_report] if merge_report else [])))
    return out, parts


def description(path) -> dict:
    with np.load(path) as data:
        return json.loads(str(data["part"]))


def part_arrays(path) -> dict:
    """A part's arrays and description, without the seconds it took (its chunks' error curves' first column)."""
    with np.load(path) as data:
        arrays = {name: (data[name][:, 1:] if "curve_" in name else data[name]).tobytes()
                  for name in data.files if name != "part"}
        info = json.loads(str(data["part"]))
    return arrays, {key: value for key, value in info.items() if key not in ("time_s", "cpu_s", "rays_s")}


# -- shards and merge ----------------------------------------------------------------------------------------------

def test_a_shard_with_forked_workers_bakes_the_same_chunks_and_bits_as_with_one_process(empty_scene, scenes):
    bpy.ops.wm.open_mainfile(filepath=str(scenes["room"]), load_ui=False)
    baked_shards = []
    for workers in (1, 2):
        plan = farm.farm_plan(bpy.context, BakeSettings(order=3, samples=16), None)
        local = local_executor(workers)
        local.min_rays = 0  # workers even for this small scene
        shard = executors.FarmShard((1, 2), local)
        execute(plan, shard).run()
        baked_shards.append(shard.kept["bake"])
    one, forked = baked_shards
    assert sorted(one) == sorted(forked) == shard_chunks(farm.part_info(plan, (1, 2)).chunks, 1, 2)
    for index, result in one.items():
        for name in ("transfer", "std_error", "rays", "skipped"):
            assert np.array_equal(getattr(result, name), getattr(forked[index], name)), name


@pytest.mark.parametrize("mode, objects", BAKES, ids=[mode for mode, _ in BAKES])
def test_merged_shards_are_bit_identical_to_one_bake_and_a_retried_shard_writes_the_same_part(
        scenes, reference, tmp_path, mode, objects):
    options = bake_options(mode, objects)
    report = tmp_path / "merged.json"
    out, parts = shard_and_merge(scenes["room"], tmp_path, 4, options, report)
    one, one_report = reference(mode, objects)
    assert_same_bake(out, one)
    merged_report = json.loads(report.read_text())
    for key in ("objects", "rays", "vertices", "skipped_vertices", "est_rms_rel_error", "est_max_rel_error",
                "bounces", "bounce_relative_changes", "subsurface_objects"):
        assert merged_report[key] == one_report[key], key
    for key in ("per_object", "error_curve"):  # all but the seconds of the curves
        assert steady(merged_report)[key] == steady(one_report)[key], key
    assert 0 < merged_report["phases_s"]["shards_s"] < merged_report["time_s"]  # the shards' seconds and the merge's
    # Its rays per second are over the shards' seconds baking (and its own), its workers theirs in all.
    infos = [description(part) for part in parts]
    assert merged_report["workers"] == sum(info["workers"] for info in infos) == 4 * one_report["workers"]
    assert merged_report["phases_s"]["shards_rays_s"] == pytest.approx(sum(info["rays_s"] for info in infos))
    assert merged_report["rays_per_s"] <= merged_report["rays"] / merged_report["phases_s"]["shards_rays_s"]
    umask = os.umask(0)
    os.umask(umask)
    assert {stat.S_IMODE(part.stat().st_mode) for part in parts} == {0o666 & ~umask}  # as any new file's
    first = part_arrays(parts[1])
    ok(run_cli("bake", scenes["room"], "--shard", "2/4", "--out", parts[1], *options))
    assert part_arrays(parts[1]) == first
    assert not list(parts[1].parent.glob(outputs.TEMPORARY_PREFIX + "*"))  # the atomic write left no temporary file


def test_shards_cast_with_the_engine_they_are_given_and_a_merge_refuses_a_part_of_another(scenes, tmp_path):
    """Shards baked with BVHTree merge into BVHTree's one-process bake, bit for bit (the suite's other farm bakes
    cast with Auto's Embree); a part baked with the other engine is refused by name."""
    options = [*bake_options("shadowed", None), "--ray-engine", "bvhtree"]
    one = tmp_path / "one.blend"
    ok(run_cli("bake", scenes["room"], *options, "--output", one))
    out, parts = shard_and_merge(scenes["room"], tmp_path, 2, options)
    assert_same_bake(out, one)
    assert description(parts[0])["settings"]["ray_engine"] == "bvhtree"
    assert description(parts[0])["ray_engine"] == f"BVHTree of Blender {bpy.app.version_string}"
    embree_part, mixed = tmp_path / "embree-2.npz", tmp_path / "mixed.blend"
    ok(run_cli("bake", scenes["room"], "--shard", "2/2", "--out", embree_part, *bake_options("shadowed", None)))
    assert description(embree_part)["settings"]["ray_engine"] == "embree"
    refused(run_cli("merge", scenes["room"], parts[0], embree_part, "--output", mixed),
            f"{embree_part} was baked with the ray engine embree, the others with bvhtree", nothing_at=[mixed])


@pytest.fixture(scope="module")
def shadowed_parts(scenes, tmp_path_factory):
    """Three shadowed parts of the room, and a folder with only those."""
    folder = tmp_path_factory.mktemp("farm_parts")
    parts = [folder / f"part-{shard}.npz" for shard in (1, 2, 3)]
    for shard, part in enumerate(parts, start=1):
        ok(run_cli("bake", scenes["room"], "--shard", f"{shard}/3", "--out", part, *bake_options("shadowed", None)))
    return parts


def digest(path) -> str:
    return hashlib.blake2b(Path(path).read_bytes()).hexdigest()


def refused(result, *words, nothing_at=()):
    """Exit 1 and one line naming what is wrong, and no file written."""
    assert result.returncode == 1, result.stdout
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith("prt: error:"), result.stderr
    for word in words:
        assert word in lines[-1], lines[-1]
    for path in nothing_at:
        assert not Path(path).exists(), path
    return lines[-1]


def test_merge_refuses_missing_duplicate_foreign_and_stale_parts_naming_them_and_writes_nothing(
        scenes, shadowed_parts, tmp_path):
    first, second, third = map(str, shadowed_parts)
    room_digest, out = digest(scenes["room"]), tmp_path / "out.blend"

    def merge(*parts, scene=scenes["room"]):
        return run_cli("merge", scene, *parts, "--output", out, "--report", tmp_path / "r.json")

    refused(merge(first, third), "missing shard 2/3", nothing_at=[out, tmp_path / "r.json"])
    copy = tmp_path / "copy-of-2.npz"
    shutil.copy(second, copy)
    refused(merge(first, second, copy, third), "duplicate shard 2/3", second, str(copy), nothing_at=[out])
    foreign = tmp_path / "foreign.npz"
    ok(run_cli("bake", scenes["other"], "--shard", "2/3", "--out", foreign, *bake_options("shadowed", None)))
    refused(merge(first, str(foreign), third), f"{foreign} is from another scene", "missing shard 2/3",
            nothing_at=[out])
    other_settings = tmp_path / "other-settings.npz"
    ok(run_cli("bake", scenes["room"], "--shard", "2/3", "--out", other_settings, *bake_options("shadowed", None),
               "--seed", "7"))
    refused(merge(first, str(other_settings), third), f"{other_settings} is stale (settings changed",
            nothing_at=[out])
    line = refused(merge(first, second, third, scene=scenes["moved"]), "moved", "occluders changed",
                   nothing_at=[out])
    assert all(part in line for part in (first, second, third))
    ok(merge(first, second, third))  # the same parts, together and of this scene, do merge
    assert digest(scenes["room"]) == room_digest  # the scene file itself is never written with --output


def test_merge_refuses_an_unwritable_output_before_any_work_and_reads_a_parts_folder(
        scenes, shadowed_parts, tmp_path):
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    for option in ("--output", "--report"):
        refused(run_cli("merge", scenes["room"], shadowed_parts[0].parent, option, not_a_folder / "out"),
                "cannot write", nothing_at=[not_a_folder / "out"])
    ok(run_cli("merge", scenes["room"], shadowed_parts[0].parent, "--output", tmp_path / "new" / "out.blend"))
    assert (tmp_path / "new" / "out.blend").exists()


def test_bad_shards_exit_1_with_one_line_and_write_no_part(addon, scenes, tmp_path):
    part = tmp_path / "part.npz"
    for shard in ("4/3", "0/3", "two/3", "1/2/3"):
        refused(run_cli("bake", scenes["room"], "--shard", shard, "--out", part), "--shard", nothing_at=[part])
    refused(run_cli("bake", scenes["room"], "--shard", "1/2"), "--out", nothing_at=[part])
    refused(run_cli("bake", scenes["room"], "--shard", "1/2", "--out", part, "--output", tmp_path / "x.blend"),
            "--output", nothing_at=[part])
    (tmp_path / "file").write_text("")
    refused(run_cli("bake", scenes["room"], "--shard", "1/2", "--out", tmp_path / "file" / "part.npz"),
            "cannot write")
    # Texel and Auto storage bake on one machine: the command line's choice and an object's own are refused.
    refused(run_cli("bake", scenes["room"], "--shard", "1/2", "--out", part, "--storage", "texel"),
            "farm bakes store per vertex", nothing_at=[part])
    auto = tmp_path / "auto.blend"
    bpy.ops.wm.open_mainfile(filepath=str(scenes["room"]), load_ui=False)
    bpy.data.objects["Floor"].prt_storage = "auto"
    bpy.ops.wm.save_as_mainfile(filepath=str(auto))
    refused(run_cli("bake", auto, "--shard", "1/2", "--out", part), "'Floor': Storage Texel or Auto bakes on one "
            "machine", nothing_at=[part])
    # A shard that fails (here: no such file) exits non-zero, so the farm retries it.
    refused(run_cli("bake", tmp_path / "missing.blend", "--shard", "1/2", "--out", part), "no such file",
            nothing_at=[part])


def hostile_part(good: Path, path: Path, **arrays) -> Path:
    """A copy of the part `good` with these arrays replaced (its description: `part`)."""
    with np.load(good) as data:
        members = {name: data[name] for name in data.files}
    np.savez(path, **{**members, **arrays})
    return path


def merge_measured(*args, limit=4 << 30):
    """`prt merge ...` in a new process whose address space is limited to `limit` bytes (a runaway merge fails
    there instead of taking the machine's memory): its result and its peak resident memory in bytes."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        process = subprocess.Popen(
            [sys.executable, "-m", "prt_addon", "merge", *map(str, args)], cwd=ROOT, env=env, stdout=out,
            stderr=err, preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
        _, status, usage = os.wait4(process.pid, 0)
        process.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        return subprocess.CompletedProcess(process.args, process.returncode, out.read(), err.read()), \
            usage.ru_maxrss * 1024


def test_merge_refuses_a_part_with_nan_or_negative_values_naming_it_and_writes_nothing(
        scenes, shadowed_parts, tmp_path):
    first, second, third = shadowed_parts
    out = tmp_path / "out.blend"
    with np.load(second) as data:
        transfer, error = data["transfer_0"].copy(), data["std_error_1"]
    transfer[5, 0] = np.nan
    nan = hostile_part(second, tmp_path / "nan.npz", transfer_0=transfer)
    refused(run_cli("merge", scenes["room"], first, nan, third, "--output", out),
            f"{nan} has NaN or infinite values in transfer_0", nothing_at=[out])
    negative = hostile_part(second, tmp_path / "negative.npz", std_error_1=-error - 1e-3)
    refused(run_cli("merge", scenes["room"], first, negative, third, "--output", out),
            f"{negative} has NaN, infinite or negative values in std_error_1", nothing_at=[out])


def test_merge_refuses_a_billion_shards_and_a_zip_bomb_naming_the_part_in_bounded_memory(
        scenes, shadowed_parts, tmp_path):
    first, second, third = shadowed_parts
    out = tmp_path / "out.blend"
    billion = hostile_part(first, tmp_path / "billion.npz",
                           part=np.array(json.dumps({**description(first), "shards": 10 ** 9})))
    result, peak = merge_measured(scenes["room"], billion, "--output", out)
    refused(result, "missing shards 2/1000000000, 3/1000000000,", f"and 999999991 more (N = 1000000000 in {billion})",
            nothing_at=[out])
    assert peak < 1 << 30, peak
    bomb = tmp_path / "bomb.npz"  # 1.1 MB, of which transfer_0.npy deflates to 1 GiB
    bomb.write_bytes(hostile_parts.with_bomb(second.read_bytes(), "transfer_0"))
    result, peak = merge_measured(scenes["room"], first, bomb, third, "--output", out)
    refused(result, f"{bomb} holds transfer_0.npy of 1073741952 bytes, more than the scene's chunk has",
            nothing_at=[out])
    assert peak < 1 << 30, peak


def test_merge_refuses_truncated_empty_and_misshaped_parts_naming_them(scenes, shadowed_parts, tmp_path):
    first, second, third = shadowed_parts
    out = tmp_path / "out.blend"
    truncated, empty = tmp_path / "truncated.npz", tmp_path / "empty.npz"
    truncated.write_bytes(second.read_bytes()[:-100])
    empty.write_bytes(b"")
    with np.load(second) as data:
        misshaped = hostile_part(second, tmp_path / "misshaped.npz", transfer_0=data["transfer_0"][:, :4])
    for part, words in [(truncated, "is not a readable PRT part file (BadZipFile: "),
                        (empty, "is not a readable PRT part file (BadZipFile: "),
                        (misshaped, "holds transfer_0.npy of shape (128, 4), not (128, 9) as the scene's chunk")]:
        refused(run_cli("merge", scenes["room"], first, part, third, "--output", out), f"{part} {words}",
                nothing_at=[out])


# -- Flamenco ------------------------------------------------------------------------------------------------------

def fake_blender(folder: Path) -> Path:
    """An executable standing in for a worker's Blender: the bpy module running the add-on's `--command`."""
    path = folder / "blender"
    path.write_text(f"#!/bin/sh\nexec {shlex.quote(sys.executable)} {shlex.quote(str(FAKE_BLENDER))} \"$@\"\n")
    path.chmod(0o755)
    return path


def compile_flamenco_job(settings: dict) -> dict:
    node = shutil.which("node")
    if node is None:
        pytest.skip("Node.js is not installed")
    compiled = subprocess.run([node, ROOT / "tests" / "flamenco_author.js", ROOT / "farm" / "flamenco" / "prt_bake.js",
                               json.dumps(settings)], capture_output=True, text=True, timeout=60, check=True)
    return json.loads(compiled.stdout)


def in_dependency_order(tasks: list) -> list:
    done, ordered = set(), []
    while len(ordered) < len(tasks):
        ready = [task for task in tasks if task["name"] not in done and set(task["dependencies"]) <= done]
        assert ready, "a dependency cycle, or a dependency on a task the job does not have"
        ordered += ready
        done |= {task["name"] for task in ready}
    return ordered


def blender_render_command(parameters: dict, blender: Path) -> list[str]:
    """What a Flamenco Worker runs for blender-render: {exe} {exeArgs} {argsBefore} {blendfile} {args}, with the
    Manager's default variables {blender} and {blenderArgs} (-b -y)."""
    exe = parameters["exe"].replace("{blender}", str(blender))
    exe_args = shlex.split(parameters["exeArgs"].replace("{blenderArgs}", "-b -y"))
    return [exe, *exe_args, *parameters["argsBefore"], parameters["blendfile"], *parameters["args"]]


def test_flamenco_job_type_has_the_bake_settings_with_their_defaults(tmp_path):
    job_type = compile_flamenco_job({"blendfile": "x.blend", "parts_dir": "p", "output": "o.blend"})["job_type"]
    defaults = {setting["key"]: setting.get("default") for setting in job_type["settings"]}
    for setting in spec.BAKE:
        assert defaults[setting.name] == ("auto" if setting.auto else setting.default), setting.name
    assert defaults["shards"] >= 1
    assert {"blendfile", "parts_dir", "output"} <= {s["key"] for s in job_type["settings"] if s.get("required")}


def test_flamenco_job_bakes_n_shards_and_a_merge_that_depends_on_them_bit_identical_to_one_bake(
        scenes, reference, tmp_path):
    job = compile_flamenco_job({"blendfile": str(scenes["room"]), "shards": 3, "parts_dir": str(tmp_path / "parts"),
                                "output": str(tmp_path / "baked.blend"), "order": 3, "samples": 16})
    tasks = job["tasks"]
    assert [task["name"] for task in tasks] == ["bake-1-of-3", "bake-2-of-3", "bake-3-of-3", "merge"]
    assert all(task["type"] == "blender" and [c["name"] for c in task["commands"]] == ["blender-render"]
               for task in tasks)
    assert all(task["dependencies"] == [] for task in tasks[:3])
    assert tasks[3]["dependencies"] == ["bake-1-of-3", "bake-2-of-3", "bake-3-of-3"]
    for shard, task in enumerate(tasks[:3], start=1):
        args = task["commands"][0]["parameters"]["args"]
        assert args[:5] == ["--command", "prt", "bake", "--shard", f"{shard}/3"]
    blender = fake_blender(tmp_path)
    for task in in_dependency_order(tasks):
        ok(subprocess.run(blender_render_command(task["commands"][0]["parameters"], blender), capture_output=True,
                          text=True, timeout=600))
    assert_same_bake(tmp_path / "baked.blend", reference("shadowed")[0])


def test_flamenco_job_with_a_prt_command_runs_it_for_every_task_bit_identical_to_one_bake(
        scenes, reference, tmp_path):
    """The setting "PRT command" (here the venv's `prt`, this checkout's code through PYTHONPATH): every task is an
    exec of `prt bake FILE ...` or `prt merge FILE PARTS...`, which a Worker runs as it is."""
    job = compile_flamenco_job({"blendfile": str(scenes["room"]), "shards": 2, "parts_dir": str(tmp_path / "parts"),
                                "output": str(tmp_path / "baked.blend"), "order": 3, "samples": 16,
                                "prt_command": f" {BIN / 'prt'} "})
    commands = [task["commands"][0] for task in in_dependency_order(job["tasks"])]
    assert [command["name"] for command in commands] == ["exec"] * 3
    assert [command["parameters"]["args"][:2] for command in commands] == [
        ["bake", str(scenes["room"])], ["bake", str(scenes["room"])], ["merge", str(scenes["room"])]]
    for command in commands:
        ok(subprocess.run([command["parameters"]["exe"], *command["parameters"]["args"]], capture_output=True,
                          text=True, timeout=600, env=dict(os.environ, PYTHONPATH=str(ROOT))))
    assert_same_bake(tmp_path / "baked.blend", reference("shadowed")[0])


# -- Open Job Description ------------------------------------------------------------------------------------------

def test_openjd_template_runs_bake_over_1_to_n_then_merge_bit_identical_to_one_bake(scenes, reference, tmp_path):
    openjd = BIN / "openjd"
    assert openjd.exists(), "openjd-cli is a dev dependency (requirements-dev.txt)"
    out = tmp_path / "baked.blend"
    parameters = {"BlendFile": scenes["room"], "PartsDir": tmp_path / "parts", "Output": out, "Shards": 3,
                  "Order": 3, "Samples": 16,
                  "PrtCommand": f"{shlex.quote(str(fake_blender(tmp_path)))} -b --command prt"}
    command = [openjd, "run", ROOT / "farm" / "openjd" / "prt_bake.template.yaml", "--step", "Merge",
               "--run-dependencies", *sum((["-p", f"{key}={value}"] for key, value in parameters.items()), [])]
    result = ok(subprocess.run(command, capture_output=True, text=True, timeout=600))
    assert "Session ended successfully" in result.stdout
    assert sorted(path.name for path in (tmp_path / "parts").iterdir()) == [f"part-{k}-of-3.npz" for k in (1, 2, 3)]
    assert_same_bake(out, reference("shadowed")[0])


# -- the manual's commands ---------------------------------------------------------------------------------------------

def farms_block(marker: str) -> str:
    """The sh block of the manual's Farms page (docs/farms.md) that holds `marker`, as printed."""
    blocks = re.findall(r"^```sh\n(.*?)^```", (ROOT / "docs" / "farms.md").read_text(), re.MULTILINE | re.DOTALL)
    found = [block for block in blocks if marker in block]
    assert found, f"docs/farms.md has no sh block with {marker!r}"
    return found[0]


@pytest.fixture(scope="module")
def default_bake(scenes, tmp_path_factory):
    """The room baked by one process at the default settings, which the manual's farm commands keep."""
    out = tmp_path_factory.mktemp("farm_default") / "one.blend"
    ok(run_cli("bake", scenes["room"], "--output", out))
    return out


@pytest.mark.parametrize("marker", ["openjd run", "--dask local:"])
def test_the_manuals_farm_commands_run_as_printed_with_only_the_bpy_module(scenes, default_bake, tmp_path, marker):
    """In a folder laid out as the Farms page's commands expect (the checkout's farm/, the venv as .venv, the room at
    the .blend path the block bakes), bash runs the block as printed, and the bake it saves (the block's other
    .blend path) is one process's bit for bit. PYTHONPATH points the venv's command at this checkout."""
    block = farms_block(marker)
    scene, saved = re.findall(r"(?:\$PWD/)?((?:[\w.-]+/)*[\w.-]+\.blend)", block)
    (tmp_path / "farm").symlink_to(ROOT / "farm")
    (tmp_path / ".venv").symlink_to(Path(sys.prefix))
    (tmp_path / scene).parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(scenes["room"], tmp_path / scene)
    done = ok(subprocess.run(["bash", "-e", "-c", block], cwd=tmp_path, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                             capture_output=True, text=True, timeout=600))
    print(f"{marker}: ran {block!r}; its last line: {done.stdout.strip().splitlines()[-1]!r}")
    assert_same_bake(tmp_path / saved, default_bake)


# -- Dask ----------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("mode, objects", BAKES[1:], ids=[mode for mode, _ in BAKES[1:]])
def test_dask_local_cluster_bake_is_bit_identical_to_one_bake(scenes, reference, tmp_path, mode, objects):
    out = tmp_path / "baked.blend"
    result = ok(run_cli("bake", scenes["room"], "--dask", "local:2", *bake_options(mode, objects),
                        "--output", out))
    assert "PRT dask: 2 shards on local:2" in result.stdout
    assert_same_bake(out, reference(mode, objects)[0])


def test_dask_refuses_a_bad_cluster_or_scene_with_one_line_and_writes_nothing(scenes, tmp_path):
    out = tmp_path / "baked.blend"
    refused(run_cli("bake", scenes["room"], "--dask", "local:0", "--output", out), "local:N", nothing_at=[out])
    # The scene is gathered while the client starts the cluster: its refusal ends the client too.
    refused(run_cli("bake", scenes["room"], "--dask", "local:2", "--objects", "Nothing", "--output", out),
            "'Nothing'", nothing_at=[out])


@contextmanager
def threads_as_workers(folder: Path):
    """Stands in for the Dask client of local:2: two threads each run a shard's task; their parts' bytes written."""
    with ThreadPoolExecutor(2) as pool:
        baked = list(pool.map(lambda shard: farm_dask.run_shard("room.blend", (shard, 2), []), (1, 2)))
    parts = [folder / f"part-{shard}.npz" for shard in (1, 2)]
    for part, content in zip(parts, baked):
        part.write_bytes(content)
    yield [str(part) for part in parts]


def test_local_dask_shards_are_forks_of_the_baking_process_and_a_failed_one_is_named(tmp_path):
    def bake_here(shard, part):
        Path(part).write_text(f"{shard} {os.getpid()} {os.getppid()}")
    cluster = farm_dask.DaskBake(functools.partial(threads_as_workers, tmp_path), local=True)
    try:
        said = [Path(part).read_text().split() for part in cluster.parts(bake_here)]
    finally:
        cluster.close()
    assert [words[:2] for words in said] == [["(1,", "2)"], ["(2,", "2)"]]
    assert {words[3] for words in said} == {str(os.getpid())} and len({words[2] for words in said}) == 2

    def failing(shard, part):
        if shard == (2, 2):
            raise InputError("no rays today")
        bake_here(shard, part)
    cluster = farm_dask.DaskBake(functools.partial(threads_as_workers, tmp_path), local=True)
    try:
        with pytest.raises(InputError, match=r"shard 2/2 failed: prt: error: no rays today"):
            cluster.parts(failing)
    finally:
        cluster.close()


def started(command, log: Path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with open(log, "w") as output:
        return subprocess.Popen([sys.executable, "-m", *command], stdout=output, stderr=subprocess.STDOUT, env=env)


def stop(process):
    process.terminate()
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def test_dask_scheduler_with_two_worker_processes_bakes_bit_identical_to_one_bake(scenes, reference, tmp_path):
    from dask.distributed import Client
    scheduler_file = tmp_path / "scheduler.json"
    processes = [started(["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                          "--no-dashboard", "--scheduler-file", str(scheduler_file)], tmp_path / "scheduler.log")]
    try:
        processes += [started(["distributed.cli.dask_worker", "--scheduler-file", str(scheduler_file),
                               "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"],
                              tmp_path / f"worker{index}.log") for index in (1, 2)]
        with Client(scheduler_file=str(scheduler_file), timeout=120) as client:
            client.wait_for_workers(2, timeout=120)
            address = client.scheduler.address
        out = tmp_path / "baked.blend"
        result = ok(run_cli("bake", scenes["room"], "--dask", address, *bake_options("shadowed", None),
                            "--output", out))
        assert f"PRT dask: 2 shards on {address}" in result.stdout
        assert_same_bake(out, reference("shadowed")[0])
    finally:
        for process in reversed(processes):
            stop(process)

