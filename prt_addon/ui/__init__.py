"""The Blender interface: properties, operators, panels, SH lights, validation, handlers, overlays and the heatmaps'
legend, registered in that order (the sidebar shows the bake's panel, then the lights', then validation)."""

from . import handlers, heatmaps, lights, operators, overlays, panels, properties, validation

modules = (properties, operators, panels, lights, validation, handlers, overlays, heatmaps)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
