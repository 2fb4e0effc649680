"""One parser and one dispatch for `python -m prt_addon ...` (bpy module) and
`blender --background [file.blend] --command prt ...` (a real Blender). Exit 0 on success, 1 with a one-line
reason on failure."""

import argparse
import sys

import bpy

from ..core.errors import InputError
from . import bake, demo, export, light_report, merge, relight, validate, view
from .common import addon_registered

COMMAND_ID = "prt"
COMMANDS = {getattr(module, "COMMAND", module.__name__.rsplit(".", 1)[-1]): module
            for module in (bake, merge, export, relight, validate, light_report, demo, view)}
_cli_handle = None


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would exit with 2; we promise 1 and one line
        raise InputError(f"{self.prog}: {message}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="prt", description="Precomputed radiance transfer for Blender.")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    commands.required = True
    for module in COMMANDS.values():
        module.add_parser(commands)
    return parser


def main(argv, in_blender: bool = False) -> int:
    try:
        args = build_parser().parse_args(argv)
        with addon_registered():
            return COMMANDS[args.command].run(args, in_blender)
    except SystemExit as leaving:  # --help
        return int(leaving.code or 0)
    except KeyboardInterrupt:  # Ctrl+C or a farm's SIGINT: nothing is saved before the work is done
        print("prt: error: cancelled; nothing was written", file=sys.stderr)
        return 1
    except InputError as failure:
        print(f"prt: error: {failure}", file=sys.stderr)
        return 1
    except Exception as failure:  # any other failure still gets its one line
        print(f"prt: error: {type(failure).__name__}: {failure}", file=sys.stderr)
        return 1


def blender_command(argv) -> int:
    return main(list(argv), in_blender=True)


def register_command():
    global _cli_handle
    _cli_handle = bpy.utils.register_cli_command(COMMAND_ID, blender_command)


def unregister_command():
    global _cli_handle
    if _cli_handle is not None:
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
