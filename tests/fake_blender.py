"""Stands in for Blender's executable on a farm worker in the tests (no Blender binary here, only the bpy module):
`fake_blender.py [-b] [-y] [FILE] --command prt ARGS...` opens FILE, if given, and runs the add-on's command line
as a real Blender's `--command` does (in_blender: the open file is the default)."""

import sys
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from prt_addon.commands import cli  # noqa: E402


def main(argv) -> int:
    at = argv.index("--command") if "--command" in argv else argv.index("-c")
    before, (command_id, *arguments) = argv[:at], argv[at + 1:]
    assert command_id == cli.COMMAND_ID, command_id
    files = [argument for argument in before if not argument.startswith("-")]
    if files:
        bpy.ops.wm.open_mainfile(filepath=files[0], load_ui=False)
    return cli.main(arguments, in_blender=True)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
