"""The saved settings' schema (blender.schema) registers without the interface: every command runs with the schema
registered, with the relighting handlers where it relies on them, never with a panel or an operator, and leaves
nothing registered behind (Blender 4.5's module hangs at exit otherwise)."""

import json
import os
import subprocess
import sys

from conftest import ROOT

# Each command with arguments that parse; its run() is replaced by one that records what is registered.
ARGUMENTS = {"bake": [], "merge": ["part.npz"], "export": ["f.blend"], "relight": ["f.blend", "--render", "o.png"],
             "validate": [], "light-report": [], "demo": [], "view": ["f.blend"]}

SCRIPT = """
import json, sys
import bpy
from prt_addon.commands import cli

def state():
    handlers = bpy.app.handlers
    return {"scene": [name for name in ("prt_bake", "prt_lights", "prt_active_light", "prt_display", "prt_validate")
                      if hasattr(bpy.types.Scene, name)],
            "object": hasattr(bpy.types.Object, "prt_storage") and hasattr(bpy.types.Object, "prt_uv_map"),
            "interface": [name for name in dir(bpy.types) if name.startswith(("PRT_OT", "PRT_PT", "PRT_MT", "PRT_UL"))]
                         + [name for name in sys.modules if name.startswith("prt_addon.ui")],
            "handlers": sorted(f.__name__ for hs in (handlers.depsgraph_update_post, handlers.frame_change_post,
                                                     handlers.load_post) for f in hs
                               if getattr(f, "__module__", "").startswith("prt_addon"))}

during = {}

def recorder(name):
    def run(args, in_blender):
        during[name] = state()
        return 0
    return run

for name, arguments in json.loads(sys.argv[1]).items():
    cli.COMMANDS[name].run = recorder(name)
    assert cli.main([name, *arguments]) == 0, name
print(json.dumps({"during": during, "after": state()}))
"""


def test_a_command_registers_the_schema_and_the_handlers_it_needs_never_the_interface():
    result = subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(ARGUMENTS)], cwd=ROOT, capture_output=True,
                            text=True, timeout=300, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout.splitlines()[-1])
    assert set(found["during"]) == set(ARGUMENTS)
    relighting = {"bake", "merge", "validate"}  # they save a file (its PRT colours) or render the PRT display
    for name, state in found["during"].items():
        assert state["scene"] == ["prt_bake", "prt_lights", "prt_active_light", "prt_display", "prt_validate"], name
        assert state["object"] and state["interface"] == [], name
        expected = ["on_depsgraph_update", "on_frame_change", "on_load_post"] if name in relighting else []
        assert state["handlers"] == expected, name
    assert found["after"] == {"scene": [], "object": False, "interface": [], "handlers": []}
