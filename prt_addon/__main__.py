"""`python -m prt_addon <command> ...` with the bpy module."""

import sys

import bpy  # noqa: F401  (must come before mathutils, which the core uses)

from .commands.cli import main

sys.exit(main(sys.argv[1:]))
