"""The Blender interface: properties, the checklist before a bake, presets, operators, stale-only rebakes, panels,
SH lights, validation, handlers, overlays, the heatmaps' legend and Drive Lights, registered in that order (the
sidebar shows the bake's panel, then the lights', then validation)."""

from . import (checks, drive, handlers, heatmaps, lights, operators, overlays, panels, presets, properties, stale,
               validation)

modules = (properties, checks, presets, operators, stale, panels, lights, validation, handlers, overlays, heatmaps,
           drive)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
