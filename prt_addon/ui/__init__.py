"""The Blender interface: properties, operators, panels, SH lights, handlers and overlays, registered in that
order (the lights' panel comes after the bake's in the sidebar)."""

from . import handlers, lights, operators, overlays, panels, properties

modules = (properties, operators, panels, lights, handlers, overlays)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
