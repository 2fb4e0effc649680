"""The Blender interface: properties, the checklist before a bake, presets, operators, panels, SH lights, validation,
handlers and overlays, registered in that order (the sidebar shows the bake's panel, then the lights', then validation)."""

from . import checks, handlers, lights, operators, overlays, panels, presets, properties, validation

modules = (properties, checks, presets, operators, panels, lights, validation, handlers, overlays)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
