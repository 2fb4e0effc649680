"""One parser and one dispatch for `python -m prt_addon ...` (bpy module) and
`blender --background [file.blend] --command prt ...` (a real Blender). Exit 0 on success, 1 with a one-line
reason on failure, 143 after SIGTERM."""

import argparse
from contextlib import contextmanager
import os
import signal
import sys

import bpy

from ..core.errors import InputError
from . import bake, demo, export, light_report, merge, relight, validate, view
from .common import schema_registered

COMMAND_ID = "prt"
# SIGTERM's exit code, 128 + 15 as a shell reports a process SIGTERM ended. The command returns it rather than
# dying by the signal again: only a normal exit runs Blender's own exit handler, which removes its blender_*
# temporary folder.
TERMINATED_EXIT_CODE = 128 + signal.SIGTERM
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


class Terminated(BaseException):
    """SIGTERM arrived (a farm or service manager stopping the command). Raised in the main thread, like Ctrl+C's
    KeyboardInterrupt, so that every `finally` and `with` on the way out runs: temporary folders are removed and
    worker processes ended. Not an Exception, so that no `except Exception` takes it for a failure."""


@contextmanager
def terminated_as_interrupted():
    """Within the block (entered in the main thread, the only one that can set a handler), SIGTERM raises
    Terminated in the main thread. A second SIGTERM is ignored, so that it cannot cut the cleanup short. A forked
    child (a bake worker, a Dask client) inherits the handler but not the block: SIGTERM ends it at once, as the
    process it was forked from expects when it sends one."""
    owner = os.getpid()

    def raise_terminated(signum, frame):
        if os.getpid() != owner:
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        signal.signal(signum, signal.SIG_IGN)
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, raise_terminated)
    if hasattr(signal, "pthread_sigmask"):  # one held back while Blender started (__main__) is taken now
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv, in_blender: bool = False) -> int:
    try:
        with terminated_as_interrupted():
            args = build_parser().parse_args(argv)
            command = COMMANDS[args.command]
            with schema_registered(relighting=getattr(command, "RELIGHTING", False)):
                return command.run(args, in_blender)
    except SystemExit as leaving:  # --help
        return int(leaving.code or 0)
    except KeyboardInterrupt:  # Ctrl+C or a farm's SIGINT: nothing is saved before the work is done
        print("prt: error: cancelled; nothing was written", file=sys.stderr)
        return 1
    except Terminated:  # a farm's SIGTERM: the same way out as Ctrl+C's, with its own exit code
        print("prt: error: terminated (SIGTERM); nothing was written", file=sys.stderr)
        return TERMINATED_EXIT_CODE
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
