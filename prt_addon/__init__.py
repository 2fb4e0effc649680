"""PRT: precomputed radiance transfer for Blender. This module only registers.

Rooms: core/ (numpy maths, no bpy), blender/ (between Blender's data and the core), commands/ (the command line),
ui/ (operators, panels, properties, handlers and overlays). The interface is imported inside register() so that
the core and the commands import without it.
"""


def register():
    from . import ui
    from .commands import cli
    ui.register()
    cli.register_command()


def unregister():
    from . import ui
    from .commands import cli
    cli.unregister_command()
    ui.unregister()
