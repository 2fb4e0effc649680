"""Outputs never clobber inputs, and are written whole or not at all (issue 31, rows 1, 6 and 7): core.outputs'
rules on their own, then every command's outputs, run in this process (`cli.main`) so that a test can stop the work
(a refusal must come before it) or make a write fail midway, as a full disk does."""

import errno
import hashlib
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import bpy
import numpy as np
import pytest
from matplotlib import pyplot

from conftest import add_light
from test_bake_blender import grid
from prt_addon.blender import gltf, lights, outputs as blender_outputs, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.commands import bake as bake_command, cli, export, merge, relight, validate
from prt_addon.core import outputs
from prt_addon.core.bake import BakeSettings
from prt_addon.core.errors import InputError

SMALL = ("--engine", "WORKBENCH", "--resolution", "16x12")


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def listing(folder) -> list[str]:
    return sorted(str(path.relative_to(folder)) for path in Path(folder).rglob("*"))


def full_disk_after(count: int):
    """A write that puts `count` characters (as a full disk does) and then fails with ENOSPC."""
    def write(handle, text):
        handle.write(text[:count])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return write


# -- the rules -----------------------------------------------------------------------------------------------------
def test_one_file_is_seen_under_every_name_and_two_files_are_not(tmp_path, monkeypatch):
    (tmp_path / "sub").mkdir()
    scene = tmp_path / "scene.blend"
    scene.write_text("scene")
    (tmp_path / "link.blend").symlink_to(scene)
    (tmp_path / "linked_folder").symlink_to(tmp_path)
    os.link(scene, tmp_path / "hard.blend")
    monkeypatch.chdir(tmp_path / "sub")
    for name in ("../scene.blend", str(scene), "../sub/../scene.blend", str(tmp_path / "link.blend"),
                 str(tmp_path / "hard.blend"), str(tmp_path / "linked_folder" / "scene.blend")):
        assert outputs.same_file(name, str(scene)), name
    assert outputs.same_file("new.json", str(tmp_path / "sub" / "new.json"))  # neither exists yet
    (tmp_path / "copy.blend").write_text("scene")
    assert not outputs.same_file(str(tmp_path / "copy.blend"), str(scene))  # equal bytes, another file
    assert not outputs.same_file("new.json", "other.json")


def test_what_cannot_be_written_is_named_and_missing_folders_are_fine(tmp_path):
    (tmp_path / "notes.txt").write_text("")
    kept = tmp_path / "kept.json"
    kept.write_text("{}")
    kept.chmod(0o444)
    assert outputs.unwritable(str(tmp_path / "new" / "deeper" / "r.json")) is None
    assert outputs.unwritable(str(tmp_path)) == f"cannot write {tmp_path}: it is a folder"
    assert outputs.unwritable(str(tmp_path / "notes.txt" / "r.json")) == (
        f"cannot write {tmp_path / 'notes.txt' / 'r.json'}: {tmp_path / 'notes.txt'} is not a folder")
    assert outputs.unwritable(str(kept)) == f"cannot write {kept}: the file there is read-only"


def test_refusals_name_each_clash_and_the_unwritable_in_one_line(tmp_path):
    scene = str(tmp_path / "scene.blend")
    with pytest.raises(InputError) as refused:
        outputs.check([("--output", str(tmp_path / "out.blend")), ("--report", str(tmp_path / "out.blend")),
                       ("--plot", scene), ("--heatmap", str(tmp_path)), ("--npz", None)], [("the open file", scene)])
    assert str(refused.value) == (
        f"--report {tmp_path / 'out.blend'} is the same file as --output; --plot {scene} would replace the open file "
        f"{scene}; cannot write {tmp_path}: it is a folder; nothing was done")
    outputs.check([("--report", str(tmp_path / "r.json"))], [("the open file", scene)])  # no clash: no error


def test_a_write_that_fails_midway_leaves_the_previous_file_and_no_temporary(tmp_path):
    report = tmp_path / "r.json"
    report.write_text("previous")
    for failure, raised in ((OSError(errno.ENOSPC, "No space left on device"), InputError),
                            (KeyboardInterrupt(), KeyboardInterrupt)):
        with pytest.raises(raised):
            with outputs.replacing(str(report)) as temporary, open(temporary, "w") as handle:
                handle.write('{"half": ')
                raise failure
        assert report.read_text() == "previous" and listing(tmp_path) == ["r.json"]
    outputs.write_json(str(report), {"whole": 1})
    assert json.loads(report.read_text()) == {"whole": 1} and listing(tmp_path) == ["r.json"]


def test_a_new_file_gets_the_usual_permissions_a_replaced_one_keeps_its_own_and_links_are_written_through(
        tmp_path):
    mask = os.umask(0o022)
    try:
        outputs.write_json(str(tmp_path / "new.json"), [])
    finally:
        os.umask(mask)
    assert (tmp_path / "new.json").stat().st_mode & 0o777 == 0o644  # not a temporary file's 0600
    shared = tmp_path / "shared.json"
    shared.write_text("[]")
    shared.chmod(0o664)
    outputs.write_json(str(shared), [1])
    assert shared.stat().st_mode & 0o777 == 0o664
    (tmp_path / "link.json").symlink_to(shared)
    outputs.write_json(str(tmp_path / "link.json"), [2])
    assert (tmp_path / "link.json").is_symlink() and json.loads(shared.read_text()) == [2]


def test_an_image_cut_short_is_told_from_a_whole_one(tmp_path):
    """The images are written by matplotlib (Pillow's JPEG), not by the code under test."""
    picture = np.random.default_rng(1).random((24, 32, 3))
    for name in ("whole.png", "whole.jpg"):
        pyplot.imsave(tmp_path / name, picture)
        data = (tmp_path / name).read_bytes()
        assert outputs.image_is_whole(str(tmp_path / name)), name
        for cut in (len(data) // 3, len(data) - 5, len(data) - 1):
            (tmp_path / "cut").write_bytes(data[:cut])
            assert not outputs.image_is_whole(str(tmp_path / "cut")), (name, cut)
    damaged = bytearray((tmp_path / "whole.png").read_bytes())
    damaged[40] ^= 0xFF  # inside the first chunk: its CRC no longer holds
    (tmp_path / "damaged.png").write_bytes(bytes(damaged))
    assert not outputs.image_is_whole(str(tmp_path / "damaged.png"))


# -- the commands ----------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def scene_file(addon, tmp_path_factory):
    """A 3 × 3 vertex grid baked unshadowed (no rays), a camera over it, a sky SH light, and an image it uses
    (texture.png, beside it, by a relative path)."""
    folder = tmp_path_factory.mktemp("outputs")
    bpy.ops.wm.read_homefile(use_empty=True)
    grid("Grid", size=2.0, cuts=2)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, 3.0)
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    SceneBake(bpy.context, BakeSettings(order=2, mode="unshadowed", samples=8)).run(log=lambda line: None)
    add_light("SKY", strength=1.0)
    pyplot.imsave(folder / "texture.png", np.full((4, 4, 3), 0.5))
    texture = bpy.data.images.load(str(folder / "texture.png"))
    texture.filepath, texture.use_fake_user = "//texture.png", True
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "scene.blend"))
    bpy.ops.wm.read_homefile(use_empty=True)
    return folder / "scene.blend"


@pytest.fixture
def scene(scene_file, tmp_path):
    """A copy of the scene file and its texture in the test's own folder."""
    shutil.copy(scene_file, tmp_path / "scene.blend")
    shutil.copy(scene_file.parent / "texture.png", tmp_path / "texture.png")
    return tmp_path / "scene.blend"


class WorkStarted(Exception):
    pass


@pytest.fixture
def no_work(monkeypatch):
    """Every command's work stops at once: a refusal that is to come before any work must come before this."""
    def work(*args, **kwargs):
        raise WorkStarted("the work started")
    for module, name in ((validate, "Validation"), (validate, "validate_image"), (lights, "scene_fidelity"),
                         (bake_command, "read_request"), (bake_command, "bake_shard"), (merge, "merge_parts"),
                         (storage, "read_transfer"), (gltf, "export"), (relight, "Relighter"), (relight, "render")):
        monkeypatch.setattr(module, name, work)


def run(capfd, *args):
    """The command in this process: (exit code, its stdout, its stderr lines)."""
    code = cli.main([str(arg) for arg in args])
    said = capfd.readouterr()
    return code, said.out, said.err.strip().splitlines()


def refused(capfd, *args) -> str:
    code, _, lines = run(capfd, *args)
    assert code == 1 and len(lines) == 1 and lines[0].startswith("prt: error: "), lines
    assert "work started" not in lines[0], lines[0]
    return lines[0]


def test_an_output_naming_an_input_under_any_name_is_refused_before_work_and_changes_nothing(
        scene, tmp_path, capfd, no_work, monkeypatch):
    """Row 1: each shape the issue found, and the other pairings: --output, --render, --npz, --gltf, merge's
    outputs against its parts, an image the .blend uses, links and relative names."""
    folder, before = tmp_path, digest(scene)
    (folder / "link.glb").symlink_to(scene)
    os.link(scene, folder / "hard.png")
    part = folder / "part.npz"
    part.write_bytes(b"a part")
    other = folder / "other.blend"
    monkeypatch.chdir(folder)
    files = listing(folder)
    cases = [
        (("validate", scene, "--report", scene), f"--report {scene} would replace the open file"),
        (("light-report", scene, "--report", scene), f"--report {scene} would replace the open file"),
        (("bake", scene, "--shard", "1/2", "--out", scene), f"--out {scene} would replace the open file"),
        (("bake", scene, "--report", scene), f"--report {scene} is the same file as the bake saved over the open file"),
        (("bake", scene, "--output", other, "--report", scene), f"--report {scene} would replace the open file"),
        (("bake", scene, "--output", other, "--report", other), f"--report {other} is the same file as --output"),
        (("bake", scene, "--env", "texture.png", "--output", "texture.png"), "--output texture.png would replace "
                                                                             "--env texture.png"),
        (("merge", scene, part, "--output", part), f"--output {part} would replace the part file {part}"),
        (("merge", scene, part, "--report", "scene.blend"), "--report scene.blend is the same file as the bake saved"),
        (("export", scene, "--object", "Grid", "--npz", "./scene.blend"), "--npz ./scene.blend would replace the "
                                                                          "open file"),
        (("export", scene, "--gltf", folder / "link.glb"), f"--gltf {folder / 'link.glb'} would replace the open "
                                                           f"file"),
        (("relight", "scene.blend", *SMALL, "--render", folder / "hard.png"), "would replace the open file"),
        (("relight", scene, *SMALL, "--render", "texture.png"), f"--render texture.png would replace a file the "
                                                                f"open .blend uses, {folder / 'texture.png'}"),
        (("validate", scene, "--image", "--heatmap", "texture.png"), "--heatmap texture.png would replace a file "
                                                                     "the open .blend uses"),
    ]
    for args, words in cases:
        line = refused(capfd, *args)
        assert words in line and line.endswith("; nothing was done"), (args, line)
        assert digest(scene) == before and listing(folder) == files, args


def test_an_unwritable_output_is_refused_before_work(scene, tmp_path, capfd, no_work):
    """Row 6: a read-only file there (refused even for root) or a file where a folder should be, in every command
    that writes, before its work (validate's Cycles passes, a render, an export, a bake)."""
    kept = tmp_path / "kept.out"
    kept.write_text("previous")
    kept.chmod(0o444)
    (tmp_path / "notes.txt").write_text("")
    under_a_file = tmp_path / "notes.txt" / "out.png"
    before = digest(scene)
    for args, path in [(("validate", scene, "--report"), kept), (("light-report", scene, "--report"), kept),
                       (("bake", scene, "--report"), kept), (("bake", scene, "--output"), kept),
                       (("bake", scene, "--shard", "1/2", "--out"), kept),
                       (("merge", scene, tmp_path / "part.npz", "--report"), kept),
                       (("export", scene, "--object", "Grid", "--npz"), kept),
                       (("export", scene, "--gltf"), tmp_path / "notes.txt" / "out.glb"),
                       (("relight", scene, *SMALL, "--render"), under_a_file),
                       (("validate", scene, "--image", "--heatmap"), under_a_file),
                       (("light-report", scene, "--plot"), under_a_file)]:
        line = refused(capfd, *args, path)
        assert f"cannot write {path}:" in line, line
    assert kept.read_text() == "previous" and digest(scene) == before


def test_a_report_cut_short_by_a_full_disk_leaves_the_previous_report_and_no_temporary(scene, tmp_path, capfd,
                                                                                        monkeypatch):
    """Row 6: `--report` on a full disk left a 0-byte JSON in place of the previous one."""
    report = tmp_path / "reports" / "lights.json"
    report.parent.mkdir()
    report.write_text("previous")
    real_dump = json.dump
    monkeypatch.setattr(json, "dump", lambda data, handle, **kw: full_disk_after(1)(handle, json.dumps(data)))
    code, out, lines = run(capfd, "light-report", scene, "--report", report)
    assert code == 1 and "No space left on device" in lines[-1], lines
    assert "recommended: order" in out  # the work was done; only the write failed
    assert report.read_text() == "previous" and listing(report.parent) == ["lights.json"]
    monkeypatch.setattr(json, "dump", real_dump)
    assert run(capfd, "light-report", scene, "--report", report)[0] == 0
    assert json.loads(report.read_text())["recommended_order"] >= 1


def test_a_glb_cut_short_leaves_the_previous_glb_and_no_temporary(scene, tmp_path, capfd, monkeypatch):
    """Row 6: `--gltf` on a full disk left a truncated .glb."""
    out = tmp_path / "out" / "scene.glb"
    out.parent.mkdir()
    out.write_bytes(b"glTF previous")
    real_finish = gltf._finish_file

    def cut_short(path, *args):
        real_finish(path, *args)
        data = Path(path).read_bytes()
        Path(path).write_bytes(data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(gltf, "_finish_file", cut_short)
    code, _, lines = run(capfd, "export", scene, "--gltf", out)
    assert code == 1 and "No space left on device" in lines[-1], lines
    assert out.read_bytes() == b"glTF previous" and listing(out.parent) == ["scene.glb"]
    monkeypatch.setattr(gltf, "_finish_file", real_finish)
    code, said, _ = run(capfd, "export", scene, "--gltf", out)
    assert code == 0 and f"wrote {out}" in said and out.read_bytes()[:4] == b"glTF"


@pytest.fixture
def tiny_disk(tmp_path):
    """A 64 KiB tmpfs folder, for what Blender's own C code writes (a render, a .blend) on a full disk; skipped
    where this process may not mount one."""
    folder = tmp_path / "tiny"
    folder.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def test_on_a_full_disk_blenders_own_writes_leave_the_previous_files(scene, tiny_disk, capfd):
    """Row 6, where no monkeypatch reaches: Blender's PNG writer cuts a render short without a word (it is checked
    after writing), and Blender's .blend save fails whole."""
    render, saved = tiny_disk / "render.png", tiny_disk / "baked.blend"
    render.write_bytes(b"previous render")
    saved.write_bytes(b"previous blend")
    code, _, lines = run(capfd, "relight", scene, "--engine", "WORKBENCH", "--resolution", "640x480",
                         "--render", render)
    assert code == 1 and lines[-1].startswith(f"prt: error: cannot write {render}: the image was cut short"), lines
    bpy.ops.wm.open_mainfile(filepath=str(scene))
    bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=64)  # more than the disk takes
    # Blender's own reason differs by version (5.x "Failed to write blendfile", 4.5 "File exists"); ours follows it.
    reason = re.escape(f"cannot save {saved}: ") + ".+; any previous file there is as it was"
    with pytest.raises(InputError, match=reason):
        blender_outputs.save_blend(str(saved))
    assert render.read_bytes() == b"previous render" and saved.read_bytes() == b"previous blend"
    assert listing(tiny_disk) == ["baked.blend", "render.png"]


@pytest.mark.parametrize("compress", [True, False])
def test_a_blend_file_is_whole_only_to_its_last_byte(tmp_path, compress):
    """What finds a .blend that Blender cut short without a word: the file as saved is whole, without its last
    byte or its second half it is not."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_uv_sphere_add()
    whole = tmp_path / "whole.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(whole), copy=True, compress=compress)
    data = whole.read_bytes()
    assert outputs.blend_is_whole(str(whole))
    for cut in (data[:-1], data[: len(data) // 2], b""):
        short = tmp_path / "short.blend"
        short.write_bytes(cut)
        assert not outputs.blend_is_whole(str(short))


def test_a_render_is_written_in_its_suffixs_format_at_exactly_the_path_printed(scene, tmp_path, capfd):
    """Row 7: `--render out.jpg` wrote out.png."""
    out = tmp_path / "renders" / "out.jpg"
    code, said, lines = run(capfd, "relight", scene, *SMALL, "--render", out)
    assert code == 0, lines
    data = out.read_bytes()
    assert data[:2] == b"\xff\xd8" and data[-2:] == b"\xff\xd9"  # a JPEG, whole
    assert listing(out.parent) == ["out.jpg"] and f"rendered {out} with" in said


def test_an_npz_is_written_at_exactly_the_path_given(scene, tmp_path, capfd):
    """Row 7: `--npz out/x` wrote out/x.npz."""
    out = tmp_path / "new" / "x"
    code, said, lines = run(capfd, "export", scene, "--object", "Grid", "--npz", out)
    assert code == 0, lines
    assert listing(out.parent) == ["x"] and f"prt: wrote {out}: 9 vertices" in said
    bpy.ops.wm.open_mainfile(filepath=str(scene))
    with np.load(out) as exported:
        np.testing.assert_array_equal(exported["transfer"].reshape(9, -1),
                                      storage.read_transfer(bpy.data.objects["Grid"].data)[0].reshape(9, -1))


def test_a_suffix_whose_format_is_not_written_is_refused_before_work_naming_those_that_are(
        scene, tmp_path, capfd, no_work):
    """Row 7: `--gltf scene.gltf` wrote scene.glb and then failed; the other image options likewise follow their
    suffix."""
    for args, words in [(("export", scene, "--gltf", tmp_path / "scene.gltf"), "must be .glb"),
                        (("relight", scene, *SMALL, "--render", tmp_path / "out.gif"), "must be .png or .jpg or .jpeg"),
                        (("validate", scene, "--image", "--heatmap", tmp_path / "h.tga"), "must be .png or .jpg"),
                        (("light-report", scene, "--plot", tmp_path / "p.eps"), "must be .png or .svg or .pdf")]:
        line = refused(capfd, *args)
        assert words in line and "the file's format follows its suffix" in line, line
    assert listing(tmp_path) == ["scene.blend", "texture.png"]


def test_a_bake_saved_elsewhere_is_a_copy_the_session_keeps_its_file_and_relative_paths_still_resolve(
        scene, tmp_path, capfd):
    """The .blend goes through Blender's own temporary file (`path@`, checked on a full disk above); saved
    elsewhere (`--output`), the session keeps the file it opened, and the copy's relative paths still find their
    files."""
    copy = tmp_path / "copies" / "deeper" / "copy.blend"
    code, _, lines = run(capfd, "bake", scene, "--order", "2", "--samples", "8", "--mode", "unshadowed",
                         "--output", copy)
    assert code == 0, lines
    assert bpy.data.filepath == str(scene)
    bpy.ops.wm.open_mainfile(filepath=str(copy))
    assert os.path.normpath(bpy.path.abspath(bpy.data.images["texture.png"].filepath)) == str(tmp_path / "texture.png")
    assert storage.read_transfer(bpy.data.objects["Grid"].data)[0].shape[0] == 9
