"""What several commands share: opening the file, checking and writing the outputs (core.outputs' rules), names
from a comma list, logging, and registering the saved settings' schema and the relighting handlers for the bpy
module."""

import argparse
from contextlib import contextmanager
import os
import sys

import bpy

from ..blender.outputs import save_blend, used_files
from ..core.errors import InputError
from ..core.outputs import check, same_file, write_json


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


def saved_file(output) -> tuple[str, str]:
    """(what, path) of the .blend a bake saves: --output, else the open file; refused without either."""
    if output:
        return "--output", output
    if not bpy.data.filepath:
        raise InputError("the scene has no file to save over; give --output")
    return "the bake saved over the open file", bpy.data.filepath


def check_outputs(outputs, inputs=(), saved=None):
    """Refuses, before any work and in one line, outputs that would replace an input or each other, or that cannot
    be written (core.outputs' rules). `outputs` and `inputs` are (what, path) pairs, a path None left out; the open
    .blend and every file it uses are inputs too. `saved` is the .blend the command saves (saved_file), which may
    be the open file: a bake saves over it unless given --output."""
    opened = bpy.data.filepath
    replaced = saved is not None and bool(opened) and same_file(saved[1], opened)
    inputs = [*inputs, *([("the open file", opened)] if opened and not replaced else []),
              *(("a file the open .blend uses,", path) for path in used_files())]
    check([*([saved] if saved else []), *outputs], inputs)


def save_bake(bake_report, output, report):
    """Saves the baked scene (over the opened file without `output`) and its JSON report (blender.store.BakeReport)
    at `report`, each whole or not at all."""
    save_blend(saved_file(output)[1])
    if report:
        write_json(report, bake_report.as_dict())


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


def log(line):
    print(line, flush=True)


def warn(sentences):
    for sentence in sentences:
        print(f"prt: warning: {sentence}", file=sys.stderr)
