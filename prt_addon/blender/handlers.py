"""Persistent handlers that keep the PRT colours and display materials current as lights change, through one
relighting engine (blender.relighting). The add-on registers them, and so does a command that shows the PRT display
(commands.common.schema_registered); the interface reads the engine's last legend and Auto window.

depsgraph_update_post refreshes only for light-relevant updates (the engine says which); frame_change_post always
refreshes, since animated and driven settings change with the frame; load_post forgets the previous file.
No bpy.ops here: handlers run inside Blender's evaluation.
"""

import bpy
from bpy.app.handlers import persistent

from . import display
from .relighting import Relighter

engine = Relighter()


@persistent
def on_depsgraph_update(scene, depsgraph):
    if not engine.busy and engine.light_relevant(scene, depsgraph):
        engine.refresh(scene, depsgraph)


@persistent
def on_frame_change(scene, depsgraph):
    engine.refresh(scene, depsgraph)


@persistent
def on_load_post(_filepath):
    engine.forget()


HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
    (bpy.app.handlers.frame_change_post, on_frame_change),
    (bpy.app.handlers.load_post, on_load_post),
)


def register():
    for handlers, function in HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in HANDLERS:
        if function in handlers:
            handlers.remove(function)
    display.restore_all()
    engine.forget()
