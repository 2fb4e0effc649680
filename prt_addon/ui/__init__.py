"""The Blender interface: the running job's status, the checklist before a bake, presets, operators, stale-only
rebakes, panels, SH lights, validation, overlays, the heatmaps' legend and Drive Lights, registered in that order
(the sidebar shows the bake's panel, then the lights', then validation). The settings they show are the saved
settings' schema (blender.schema), registered before them."""

from . import checks, drive, heatmaps, lights, operators, overlays, panels, presets, stale, status, validation

modules = (status, checks, presets, operators, stale, panels, lights, validation, overlays, heatmaps, drive)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
