"""The Blender interface: properties, operators, panels, SH lights, validation, handlers and overlays, registered
in that order (the sidebar shows the bake's panel, then the lights', then validation)."""

from . import handlers, lights, operators, overlays, panels, properties, stale, validation

modules = (properties, operators, stale, panels, lights, validation, handlers, overlays)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
