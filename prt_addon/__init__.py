"""PRT: precomputed radiance transfer for Blender. This module only registers.

Rooms: core/ (numpy maths, no bpy), blender/ (between Blender's data and the core, with the saved settings' schema
and the relighting handlers), commands/ (the command line), ui/ (operators, panels and overlays). The interface is
imported inside register() so that the core and the commands import without it; a command registers only the
schema and the handlers it needs (commands.common.schema_registered).
"""


def register():
    from . import ui
    from .blender import handlers, schema
    from .commands import cli
    schema.register()
    handlers.register()
    ui.register()
    cli.register_command()


def unregister():
    from . import ui
    from .blender import handlers, schema
    from .commands import cli
    cli.unregister_command()
    ui.unregister()
    handlers.unregister()
    schema.unregister()
