"""PRT: precomputed radiance transfer for Blender. This module only registers.

The interface is imported inside register() so that `prt_addon.core` (numpy only) and the command line
import without touching bpy's UI.
"""


def register():
    from . import cli, ui
    ui.register()
    cli.register_command()


def unregister():
    from . import cli, ui
    cli.unregister_command()
    ui.unregister()
