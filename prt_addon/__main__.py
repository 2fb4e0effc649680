"""`python -m prt_addon <command> ...` with the bpy module."""

import sys

import bpy  # noqa: F401  (must come before mathutils, which the core uses)

from .commands.cli import main

if __name__ == "__main__":  # not when a spawned process (Dask's LocalCluster workers) imports it as __mp_main__
    sys.exit(main(sys.argv[1:]))
