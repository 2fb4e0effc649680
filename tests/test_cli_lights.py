"""SH lights from the command line (issue 16): `prt bake` and `prt relight` add them with --sun, --env, --sky, so a
file baked without the interface relights at once; a file's own lights stay unless --replace-lights."""

import math

import bpy
import numpy as np
import pytest

from conftest import run_cli
from prt_addon.blender import storage
from test_relight import read_png

SMALL = ("--engine", "WORKBENCH", "--resolution", "48x36")


@pytest.fixture(scope="module")
def baked_plane(sample_scene_files, tmp_path_factory):
    """Suzanne's floor, baked from the command line, without SH lights."""
    path = tmp_path_factory.mktemp("cli_lights") / "plane.blend"
    result = run_cli("bake", sample_scene_files / "suzanne.blend", "--objects", "Plane", "--order", "2",
                     "--samples", "16", "--output", path)
    assert result.returncode == 0, result.stderr
    return path


def lights_of(path):
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    return [(entry.kind, round(math.degrees(entry.theta), 3), round(math.degrees(entry.phi), 3), entry.strength)
            if entry.kind == "SUN" else (entry.kind, entry.strength) for entry in bpy.context.scene.prt_lights]


def test_relight_adds_a_sun_to_a_cli_baked_file_and_renders(baked_plane, tmp_path):
    out = tmp_path / "relit.png"
    result = run_cli("relight", baked_plane, "--sun", "40,120,2", *SMALL, "--render", out)
    assert result.returncode == 0, result.stderr
    assert "added SH light: sun 'Sun': θ 40.0°, φ 120.0°, radius 2.50°, irradiance (2, 2, 2)" in result.stdout
    image = read_png(str(out))
    assert image.shape == (36, 48, 4) and np.ptp(image[..., :3]) > 0.1  # lit and shadowed, not one flat colour


def test_a_brighter_sun_renders_brighter(baked_plane, tmp_path):
    means = []
    for irradiance in ("0.5", "1.5"):
        out = tmp_path / f"sun_{irradiance}.png"
        result = run_cli("relight", baked_plane, "--sun", f"0,0,{irradiance}", *SMALL, "--render", out)
        assert result.returncode == 0, result.stderr
        means.append(read_png(str(out))[..., :3].mean())
    assert means[1] > means[0]


def test_bake_saves_the_lights_so_the_file_relights_without_options(addon, sample_scene_files, tmp_path):
    path = tmp_path / "lit.blend"
    result = run_cli("bake", sample_scene_files / "suzanne.blend", "--objects", "Plane", "--order", "2",
                     "--samples", "16", "--sun", "30,45,3", "--sun", "80,-90", "--sky", "0.25", "--output", path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("added SH light:") == 3
    assert lights_of(path) == [("SUN", 30.0, 45.0, 3.0), ("SUN", 80.0, -90.0, 1.0), ("SKY", 0.25)]
    relit = run_cli("relight", path, *SMALL, "--render", tmp_path / "relit.png")
    assert relit.returncode == 0, relit.stderr


def test_a_cli_bake_saves_the_colours_its_lights_give(addon, sample_scene_files, tmp_path):
    """`prt bake` runs with the relighting handlers, so its file is saved with the PRT colours under the lights it
    was given. A sky of radiance L is the DC coefficient 2√π·L alone (which no window tapers): each vertex's colour
    is its DC transfer times that."""
    path = tmp_path / "sky.blend"
    result = run_cli("bake", sample_scene_files / "suzanne.blend", "--objects", "Plane", "--order", "2",
                     "--samples", "16", "--sky", "0.5", "--output", path)
    assert result.returncode == 0, result.stderr
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    mesh = bpy.data.objects["Plane"].data
    saved = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["prt_color"].data.foreach_get("color", saved)
    transfer, _ = storage.read_transfer(mesh)
    expected = np.maximum(transfer[:, 0].astype(np.float64) * 2 * math.sqrt(math.pi) * 0.5, 0.0)  # grey albedo
    assert expected.max() > 0.1  # lit, not black
    np.testing.assert_allclose(saved.reshape(-1, 4)[:, :3], np.repeat(expected[:, None], 3, axis=1), rtol=1e-5,
                               atol=1e-6)


def test_a_files_lights_stay_unless_replaced(addon, baked_plane, tmp_path):
    path = tmp_path / "lit.blend"
    bpy.ops.wm.open_mainfile(filepath=str(baked_plane), load_ui=False)
    bpy.ops.prt.light_add(kind="SKY")
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    refused = run_cli("relight", path, "--sun", "10,0", *SMALL, "--render", tmp_path / "b.png")
    assert refused.returncode == 1
    assert "already has 1 SH lights ('Sky'); give --replace-lights" in refused.stderr
    replaced = run_cli("bake", path, "--order", "2", "--samples", "16", "--sun", "10,20", "--replace-lights")
    assert replaced.returncode == 0, replaced.stderr
    assert lights_of(path) == [("SUN", 10.0, 20.0, 1.0)]


def test_an_environment_image_with_a_rotation(baked_plane, tmp_path):
    image = bpy.data.images.new("Sky", 16, 8, float_buffer=True)
    image.pixels.foreach_set(np.tile([0.4, 0.5, 0.6, 1.0], 16 * 8).astype(np.float32))
    image.filepath_raw, image.file_format = str(tmp_path / "sky.exr"), "OPEN_EXR"
    image.save()
    result = run_cli("relight", baked_plane, "--env", tmp_path / "sky.exr", "--env-rotation", "90", *SMALL,
                     "--render", tmp_path / "env.png")
    assert result.returncode == 0, result.stderr
    assert "added SH light: environment 'Environment': sky.exr" in result.stdout


@pytest.mark.parametrize("args, words", [
    (("--sun", "190,0"), "θ must be 0-180"),
    (("--sun", "10,20,30,40"), "--sun takes THETA,PHI or THETA,PHI,IRRADIANCE"),
    (("--sun", "10,20,-1"), "irradiance must be at least 0"),
    (("--sky", "-0.5"), "--sky takes a number of at least 0"),
    (("--env", "no_such.exr"), "--env: no such image: no_such.exr"),
    (("--env-rotation", "30"), "give --env IMAGE too"),
    (("--samples", "0"), "--samples takes a whole number of at least 1"),
    (("--light", "-1"), "--light takes a whole number of at least 0"),
])
def test_bad_light_options_are_refused_by_name(baked_plane, tmp_path, args, words):
    result = run_cli("relight", baked_plane, *args, "--render", tmp_path / "x.png", cwd=tmp_path)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("prt:")]
    assert len(errors) == 1 and words in errors[0]


def test_a_file_without_lights_and_without_options_says_how_to_add_them(baked_plane, tmp_path):
    result = run_cli("relight", baked_plane, "--render", tmp_path / "x.png")
    assert result.returncode == 1 and "give --sun, --env or --sky" in result.stderr
