"""Files baked by earlier versions keep working: their bake reads back, relights to the same colours and renders.

`data/baked_by_0.1.0.blend` was baked and saved by the add-on at commit 5ee8426 (before the restructure into
core/, blender/, commands/ and ui/): a UV sphere over a 12 × 12 grid, order 4, shadowed, 64 samples, seed 3, with
an SH sun (strength 2) and sky (0.2) and the PRT display on, so it holds the colours that version computed.
Saved by Blender 5.0, whose file format older Blenders cannot read.
"""

import subprocess
import sys

import bpy
import numpy as np
import pytest

from conftest import ROOT, run_cli
from prt_addon.blender import storage

BAKED_BY_0_1_0 = ROOT / "tests" / "data" / "baked_by_0.1.0.blend"

pytestmark = pytest.mark.skipif(bpy.app.version < (5, 0, 0), reason="the file was saved by Blender 5.0")

READ_SAVED_COLOURS = """
import sys
import bpy
import numpy as np
bpy.ops.wm.open_mainfile(filepath=sys.argv[1], load_ui=False)
saved = {}
for mesh in bpy.data.meshes:
    values = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["prt_color"].data.foreach_get("color", values)
    saved[mesh.name] = values.reshape(-1, 4)
np.savez(sys.argv[2], **saved)
"""


def saved_colours(tmp_path) -> dict:
    """The colours as 0.1.0 wrote them, read by a process without the add-on (no handler can touch them)."""
    out = tmp_path / "saved.npz"
    subprocess.run([sys.executable, "-c", READ_SAVED_COLOURS, str(BAKED_BY_0_1_0), str(out)], check=True,
                   timeout=120, capture_output=True)
    with np.load(out) as data:
        return {name: data[name] for name in data.files}


def test_a_file_baked_by_0_1_0_relights_to_the_colours_it_was_saved_with(empty_scene, prt, tmp_path):
    before = saved_colours(tmp_path)
    bpy.ops.wm.open_mainfile(filepath=str(BAKED_BY_0_1_0), load_ui=False)
    for mesh in bpy.data.meshes:
        mesh.color_attributes.remove(mesh.color_attributes["prt_color"])  # the colours must be computed anew
        transfer, meta = storage.read_transfer(mesh)
        assert (meta["order"], meta["mode"], transfer.shape) == (4, "shadowed", (len(mesh.vertices), 16))
    bpy.context.scene.prt_display.window = "none"  # 0.1.0's default, which its files do not store; now Auto
    prt.handlers.engine.forget()
    prt.handlers.engine.refresh(bpy.context.scene, bpy.context.evaluated_depsgraph_get())
    assert set(before) == {"Sphere", "Grid"}
    for name, colours in before.items():
        after = np.empty(colours.size, dtype=np.float32)
        bpy.data.meshes[name].color_attributes["prt_color"].data.foreach_get("color", after)
        assert colours[:, :3].max() > 0.1  # lit, not an empty layer
        np.testing.assert_allclose(after.reshape(-1, 4), colours, rtol=1e-5, atol=1e-6)


def test_prt_relight_renders_a_file_baked_by_0_1_0(tmp_path):
    image = tmp_path / "relit.png"
    result = run_cli("relight", BAKED_BY_0_1_0, "--light", 0, "--light-theta", 60, "--engine", "WORKBENCH",
                     "--resolution", "48x36", "--render", image, timeout=300)
    assert result.returncode == 0, result.stderr
    assert image.stat().st_size > 0 and "rendered" in result.stdout
