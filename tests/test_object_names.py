"""Naming objects on the command line: `--objects A,B` splits at commas, `--object NAME` (repeatable) takes a name
exactly as written, so a name with a comma can be baked and validated, also by a Dask cluster's shard tasks."""

import bpy

from conftest import run_cli
from prt_addon.blender import storage
from prt_addon.commands import farm_dask
from prt_addon.commands.cli import build_parser
from prt_addon.commands.common import object_names
from prt_addon.core.bake import BakeSettings

COMMA = "Box, red"


def parsed(*argv):
    return object_names(build_parser().parse_args(["bake", "scene.blend", *argv]))


def test_objects_split_at_commas_and_object_takes_a_name_as_written():
    assert parsed("--objects", "Floor, Wall") == ["Floor", "Wall"]
    assert parsed("--object", COMMA) == [COMMA]
    assert parsed("--objects", "Floor,Wall", "--object", COMMA, "--object", "Floor") == ["Floor", "Wall", COMMA]
    assert parsed() is None


def test_a_dask_shard_task_is_given_every_receiver_by_its_exact_name():
    receivers = [COMMA, "Floor"]
    arguments = farm_dask.bake_arguments(BakeSettings(), receivers)
    assert parsed(*arguments) == receivers


def test_bake_and_validate_take_a_name_with_a_comma(addon, tmp_path):
    bpy.ops.wm.read_homefile(use_empty=True)
    for name, z in ((COMMA, 0.0), ("Box", 1.0), ("red", 2.0)):
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=2, y_subdivisions=2, location=(0.0, 0.0, z))
        bpy.context.object.name = name
    scene, baked = tmp_path / "scene.blend", tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(scene))
    done = run_cli("bake", scene, "--object", COMMA, "--order", "2", "--samples", "8", "--output", baked)
    assert done.returncode == 0, done.stderr
    bpy.ops.wm.open_mainfile(filepath=str(baked), load_ui=False)
    assert sorted(ob.name for ob in bpy.data.objects if storage.METADATA_KEY in ob.data) == [COMMA]
    bpy.ops.wm.read_homefile(use_empty=True)
    checked = run_cli("validate", baked, "--object", COMMA, "--samples", "4", "--passes", "2")
    assert checked.returncode == 0, checked.stderr
    assert f"{COMMA}" in checked.stdout
