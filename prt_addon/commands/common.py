"""What several commands share: opening the file, names from a comma list, JSON reports, logging, and the add-on's
registration for the bpy module."""

import json
import os
import sys

import bpy

from ..core.errors import InputError


def ensure_registered():
    """With the bpy module the add-on is not enabled: register it for this process (the scene's SH lights and
    display switches are its properties, the relighting handlers its handlers)."""
    if not hasattr(bpy.types.Scene, "prt_lights"):
        from .. import register
        register()


def open_file(path, required: bool):
    """Opens `path`; without one, a real Blender's open file serves unless `required`."""
    if path:
        if not os.path.isfile(path):
            raise InputError(f"no such file: {path}")
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
    elif required or not bpy.data.filepath and not bpy.data.objects:
        raise InputError("give a .blend file to open")


def names(text):
    return [name.strip() for name in text.split(",")] if text else None


def write_json(path, data):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as handle:
        json.dump(data, handle, indent=2)


def log(line):
    print(line, flush=True)


def warn(sentences):
    for sentence in sentences:
        print(f"prt: warning: {sentence}", file=sys.stderr)
