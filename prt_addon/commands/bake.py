"""`prt bake`: bake and save, with progress lines, the summary line and an optional JSON report."""

import argparse

import bpy

from ..blender.farm import bake_shard, merge_parts
from ..blender.fingerprint import stale_line, stale_receivers
from ..blender.scene_bake import SceneBake
from ..core import settings as spec
from ..core.bake import BakeSettings
from ..core.errors import InputError
from ..core.shards import shard_of
from . import farm_dask
from .common import check_writable, log, names, open_file, save_bake, warn


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
    farm = parser.add_argument_group("farm", "one bake spread over a render farm (README: Baking on a farm)")
    farm.add_argument("--shard", metavar="K/N", help="bake only shard K of N (K from 1 to N) into the part file "
                      "--out, saving nothing else; `prt merge` makes the bake from all N parts")
    farm.add_argument("--out", metavar="PART.npz", help="the shard's part file (written atomically)")
    farm.add_argument("--dask", metavar="SCHEDULER", help="bake one shard per worker thread of this Dask scheduler "
                      "(an address, or local:N for a LocalCluster of N workers) and merge them here; needs the "
                      "distributed package")


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
    shard = _farm_options(args)
    for path in (args.out, args.output, args.report):
        if path:
            check_writable(path)
    open_file(args.file, required=not in_blender)
    settings, receivers = settings_from(args), names(args.objects)
    if shard:
        info = bake_shard(bpy.context, settings, receivers, shard, args.out, args.workers, log=log)
        log(f"PRT shard {args.shard}: {info.rays} rays in {info.time_s:.2f} s; wrote {args.out}")
        return 0
    if args.stale_only:
        changed = stale_receivers(bpy.context, settings, receivers)
        log(stale_line(changed))
        receivers = [name for name, words in changed.items() if words]
        if not receivers:
            return 0
    if args.dask:
        with farm_dask.parts_baked_on_dask(args.dask, bpy.data.filepath, settings, receivers, log) as parts:
            scene_bake = merge_parts(bpy.context, parts, log=log)
        warn(scene_bake.problems + scene_bake.notes)
    else:
        scene_bake = SceneBake(bpy.context, settings, receivers, workers=args.workers)
        warn(scene_bake.problems + scene_bake.notes)
        scene_bake.run(log=log)
    log(scene_bake.summary.line())
    save_bake(scene_bake, args.output, args.report)
    return 0


def _farm_options(args) -> tuple[int, int] | None:
    """Checks how the farm options combine; the shard (K, N) to bake, or None."""
    if (args.shard is None) != (args.out is None):
        raise InputError("--shard K/N and --out PART.npz go together")
    if args.shard is None:
        return None
    others = [option for option, given in (("--stale-only", args.stale_only), ("--dask", args.dask),
                                           ("--output", args.output), ("--report", args.report)) if given]
    if others:
        raise InputError(f"a shard only writes its part file (--out): {', '.join(others)} does not apply")
    return shard_of(args.shard)
