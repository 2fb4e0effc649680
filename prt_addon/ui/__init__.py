"""The Blender interface: properties, operators, panels (and later handlers), registered in that order."""

from . import operators, panels, properties

modules = (properties, operators, panels)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
