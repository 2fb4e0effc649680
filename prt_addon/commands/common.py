"""What several commands share: opening the file, names from a comma list, JSON reports, logging, and registering
the saved settings' schema and the relighting handlers for the bpy module."""

import argparse
from contextlib import contextmanager
import json
import os
import sys

import bpy

from ..core.errors import InputError


@contextmanager
def schema_registered(relighting: bool = False):
    """With the bpy module the add-on is not enabled: registers the saved settings' schema (blender.schema: the
    scene's bake settings, SH lights and display switches, each object's storage choice) for the body, and the
    relighting handlers (blender.handlers) where the command relies on them to keep the PRT display current
    (`relighting`); never a panel or an operator. Unregisters them after, also on failure: Blender 4.5's module
    hangs at exit while classes stay registered. Where the add-on is enabled (a real Blender, a test session), it
    has registered both, and they are left as they are."""
    if hasattr(bpy.types.Scene, "prt_bake"):
        yield
        return
    from ..blender import handlers, schema
    modules = (schema, handlers) if relighting else (schema,)
    for module in modules:
        module.register()
    try:
        yield
    finally:
        for module in reversed(modules):
            module.unregister()


def open_file(path, required: bool):
    """Opens `path`; without one, a real Blender's open file serves unless `required`."""
    if path:
        if not os.path.isfile(path):
            raise InputError(f"no such file: {path}")
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
    elif required or not bpy.data.filepath and not bpy.data.objects:
        raise InputError("give a .blend file to open")


def whole_number(option: str, at_least: int):
    """An argparse type: a whole number of at least `at_least`, refused by name as it is read."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = at_least - 1
        if value < at_least:
            raise argparse.ArgumentTypeError(f"{option} takes a whole number of at least {at_least}, not {text!r}")
        return value
    return parse


def check_writable(path):
    """Refuses, before any work is spent, a path that cannot be written: its nearest existing folder must be a
    writable folder (the folders below it are created when writing)."""
    folder = os.path.dirname(os.path.abspath(path))
    while not os.path.exists(folder):
        folder = os.path.dirname(folder)
    if os.path.isdir(path) or not os.path.isdir(folder) or not os.access(folder, os.W_OK):
        raise InputError(f"cannot write {path}: {folder} is not a writable folder")


def save_bake(scene_bake, output, report):
    """Saves the baked scene (over the opened file without `output`) and its JSON report."""
    output = output or bpy.data.filepath
    if not output:
        raise InputError("the scene has no file; give --output")
    os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(output))
    if report:
        write_json(report, scene_bake.report().as_dict())


def add_object_options(parser, default: str):
    """--objects A,B (names split at commas) and --object NAME (one name exactly as written, commas and all;
    repeatable): `object_names` gives what they name together. `default` says what neither names."""
    parser.add_argument("--objects", metavar="A,B", help=f"comma-separated names (default: {default})")
    parser.add_argument("--object", dest="object_names", action="append", metavar="NAME",
                        help="one name exactly as written, also one with a comma; repeat it for more (with --objects: "
                             "both)")


def object_names(args):
    """The names --objects and --object give, in order, each once; None when neither gives one."""
    split = [name.strip() for name in args.objects.split(",")] if args.objects else []
    return list(dict.fromkeys(split + (args.object_names or []))) or None


def write_json(path, data):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as handle:
        json.dump(data, handle, indent=2)


def log(line):
    print(line, flush=True)


def warn(sentences):
    for sentence in sentences:
        print(f"prt: warning: {sentence}", file=sys.stderr)
