"""`prt bake`: bake and save, with progress lines, the summary line and an optional JSON report."""

import argparse
import os

import bpy

from ..blender.fingerprint import stale_line, stale_receivers
from ..blender.scene_bake import SceneBake
from ..core import settings as spec
from ..core.bake import BakeSettings
from ..core.errors import InputError
from .common import log, names, open_file, warn, write_json


def add_parser(commands):
    parser = commands.add_parser("bake", help="bake SH transfer into a .blend file's meshes")
    parser.add_argument("file", nargs="?", help=".blend file to open (in Blender: defaults to the open file)")
    parser.add_argument("--objects", help="comma-separated receiver names (default: every visible mesh)")
    for setting in spec.BAKE + (spec.WORKERS,):
        add_setting(parser, setting)
    parser.add_argument("--output", help="where to save the baked file (default: over the opened file)")
    parser.add_argument("--report", help="write the bake report as JSON here")
    parser.add_argument("--stale-only", action="store_true",
                        help="rebake only the receivers whose geometry, transform, occluders, materials or settings "
                             "changed since their bake (or that have none); nothing is written when none did")


def add_setting(parser, setting: spec.Setting):
    """--name-with-dashes for a setting, its help text with its range and default from the one definition."""
    if setting.auto:
        kind, default, shown = _whole_or_auto(setting.label.lower()), None, "auto"
    else:
        kind, default, shown = type(setting.default), setting.default, setting.default
    limits = "" if setting.choices else f"{setting.range_text()}{' or auto' if setting.auto else ''}, "
    parser.add_argument("--" + setting.name.replace("_", "-"), type=kind, default=default,
                        choices=[identifier for identifier, _, _ in setting.choices] or None,
                        help=f"{setting.description}; {limits}default {shown}")


def _whole_or_auto(what: str):
    def parse(text: str):
        if text == "auto":
            return None
        try:
            return int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be a whole number or 'auto', not {text!r}") from None
    return parse


def settings_from(args) -> BakeSettings:
    return BakeSettings(**{setting.name: getattr(args, setting.name) for setting in spec.BAKE})


def run(args, in_blender: bool) -> int:
    open_file(args.file, required=not in_blender)
    settings, receivers = settings_from(args), names(args.objects)
    if args.stale_only:
        changed = stale_receivers(bpy.context, settings, receivers)
        log(stale_line(changed))
        receivers = [name for name, words in changed.items() if words]
        if not receivers:
            return 0
    scene_bake = SceneBake(bpy.context, settings, receivers, workers=args.workers)
    warn(scene_bake.problems + scene_bake.notes)
    summary = scene_bake.run(log=log)
    log(summary.line())
    output = args.output or bpy.data.filepath
    if not output:
        raise InputError("the scene has no file; give --output")
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(output))
    if args.report:
        write_json(args.report, scene_bake.report().as_dict())
    return 0
