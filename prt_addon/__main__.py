"""`python -m prt_addon <command> ...` and the `prt` command (pyproject.toml's console script), with the bpy
module."""

import signal
import sys


def hold_sigterm():
    """Holds SIGTERM back (where the system can): it waits while the bpy module starts and while it ends, which
    make and remove its blender_* temporary folder, so that a farm's SIGTERM cannot end the process between the
    two. The command in between takes it as Ctrl+C (cli.terminated_as_interrupted)."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})


def console() -> int:
    """The command line's exit status for the process's arguments, SIGTERM held back while the bpy module starts and
    while it ends (hold_sigterm)."""
    hold_sigterm()
    import bpy  # noqa: F401  (must come before mathutils, which the core uses)

    from .commands.cli import main
    code = main(sys.argv[1:])
    hold_sigterm()
    return code


if __name__ == "__main__":
    sys.exit(console())
