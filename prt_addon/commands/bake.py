"""`prt bake`: bake and save, with progress lines, the summary line and an optional JSON report."""

import argparse
from dataclasses import replace

import bpy

from ..blender import checks as scene_checks
from ..blender.execute import execute, local_executor
from ..blender.farm import bake_share, bake_shard, build_ray_tree, farm_plan, merge_parts
from ..blender.fingerprint import stale_line, stale_receivers, stale_volumes
from ..blender.geometry import receivers_from_selection
from ..blender.plan import plan_bake
from ..blender.request import read_request
from ..blender.store import store
from ..core import checks, engines, presets, settings as spec
from ..core.bake import BakeSettings
from ..core.errors import InputError
from ..core.shards import Stopwatch, shard_of
from . import farm_dask, light_options
from .common import (add_object_options, check_outputs, log, object_names, open_file, save_bake, saved_file,
                     warn)

RELIGHTING = True  # the relighting handlers keep the saved file's PRT colours current with its SH lights


def add_parser(commands):
    parser = commands.add_parser("bake", help="bake SH transfer into a .blend file's meshes")
    parser.add_argument("file", nargs="?", help=".blend file to open (in Blender: defaults to the open file)")
    add_object_options(parser, "the file's selected meshes, else every visible mesh")
    parser.add_argument("--preset", type=str.lower, choices=list(presets.PRESETS),
                        help="start from a preset's settings (the manual's settings reference lists them); options given override it")
    for setting in spec.BAKE + (spec.WORKERS,) + spec.TEXEL:
        add_setting(parser, setting)
    parser.add_argument("--uv-map", help="texel storage: the UV map the texels follow (default: PRT's own)")
    parser.add_argument("--no-new-uv-map", action="store_true",
                        help="texel storage: never add PRT's own lightmap UV map; a mesh with no usable UV map "
                             "of its own is then not baked")
    parser.add_argument("--dynamic", action=argparse.BooleanOptionalAction, default=None,
                        help="set every receiver's Dynamic (saved with the file): baked in its own frame against "
                             "itself only, so it may move and turn; --no-dynamic: static (default: each object's own)")
    parser.add_argument("--output", help="where to save the baked file (default: over the opened file)")
    parser.add_argument("--report", help="write the bake report as JSON here")
    parser.add_argument("--stale-only", action="store_true",
                        help="rebake only the receivers whose geometry, transform, occluders, materials or settings "
                             "changed since their bake (or that have none), and the visible probe volumes moved, "
                             "resized or seeing a changed static scene since theirs; nothing is written when none did")
    light_options.add_arguments(parser)
    farm = parser.add_argument_group("farm", "one bake spread over a render farm (the manual's Farms page)")
    farm.add_argument("--shard", metavar="K/N", help="bake only shard K of N (K from 1 to N) into the part file "
                      "--out, saving nothing else; `prt merge` makes the bake from all N parts")
    farm.add_argument("--out", metavar="PART.npz", help="the shard's part file (written atomically)")
    farm.add_argument("--dask", metavar="SCHEDULER", help="bake one shard per worker thread of this Dask scheduler "
                      "(an address, or local:N for a LocalCluster of N workers) and merge them here; needs the "
                      "distributed package")


def add_setting(parser, setting: spec.Setting):
    """--name-with-dashes for a setting, range-checked as it is read, its help text with its range and default from
    the one definition. An option not given is left out of the arguments, so a preset's value can stand."""
    shown = "auto" if setting.auto else setting.default
    limits = "" if setting.choices else f"{setting.range_text()}{' or auto' if setting.auto else ''}, "
    parser.add_argument("--" + setting.name.replace("_", "-"), type=_in_range(setting), default=argparse.SUPPRESS,
                        choices=[identifier for identifier, _, _ in setting.choices] or None,
                        help=f"{setting.description}; {limits}default {shown}")


def _in_range(setting: spec.Setting):
    kind = type(setting.default)
    what = setting.label.lower()
    number = ("a whole number" if kind is int else "a number") + (" or 'auto'" if setting.auto else "")

    def parse(text: str):
        if setting.auto and text == "auto":
            return None
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be {number}, not {text!r}") from None
        if not setting.contains(value):
            raise argparse.ArgumentTypeError(f"{what} must be {setting.range_text()}, not {text}")
        return value
    return parse


def settings_from(args) -> BakeSettings:
    """The preset's settings (if any), overridden by the options given; the definitions' defaults for the rest."""
    chosen = presets.preset_values(args.preset) if args.preset else {}
    chosen.update({setting.name: getattr(args, setting.name) for setting in spec.BAKE if hasattr(args, setting.name)})
    return BakeSettings(**chosen)


def storage_options(args) -> dict:
    """The texel options given, for every receiver (blender.texel_bake.TexelOptions); the rest are each object's."""
    given = {setting.name: getattr(args, setting.name) for setting in spec.TEXEL if hasattr(args, setting.name)}
    if args.uv_map:
        given["uv_map"] = args.uv_map
    if args.no_new_uv_map:
        given["new_uv_map"] = False
    return given


def run(args, in_blender: bool) -> int:
    stopwatch = Stopwatch()  # a shard's part counts its seconds from here: its file opened, gathered, baked, written
    settings = settings_from(args)
    shard = _farm_options(args)
    open_file(args.file, required=not in_blender)
    check_outputs([("--out", args.out)] if shard else [("--report", args.report)], [("--env", args.env)],
                  saved=None if shard else saved_file(args.output))
    workers = getattr(args, "workers", spec.WORKERS.default)
    receivers = object_names(args)
    if args.dynamic is not None:
        for ob in receivers_from_selection(bpy.context, receivers):
            ob.prt_dynamic = args.dynamic
    if shard:
        info = bake_shard(bpy.context, settings, receivers, shard, args.out, stopwatch, workers, log=log)
        log(f"PRT shard {args.shard}: {info.rays} rays in {info.time_s:.2f} s; wrote {args.out}")
        return 0
    found = [scene_checks.output_check(args.output or bpy.data.filepath, required=True)]
    checks.stop_on_errors(found)  # before the scene is gathered: a wrong --output fails at once
    light_options.add_lights(bpy.context.scene, args)
    volumes = None  # every visible probe volume
    if args.stale_only:
        changed, probes = stale_receivers(bpy.context, settings, receivers), stale_volumes(bpy.context, settings)
        log(stale_line(changed, probes))
        receivers = [name for name, words in changed.items() if words]
        volumes = [name for name, words in probes.items() if words]
        if args.dask and volumes:
            warn([f"probe volumes bake on one machine: --dask leaves {', '.join(map(repr, volumes))} stale"])
            volumes = []
        if not receivers and not volumes:
            return 0
    if args.dask:
        # The engine is chosen here, once: every shard, on whatever machine, casts with it.
        engine, note = engines.choose(settings.ray_engine)
        settings = replace(settings, ray_engine=engine)
        warn([note] if note else [])
        with farm_dask.dask_bake(args.dask, bpy.data.filepath, settings, receivers, log) as cluster:
            # Planned once, while the cluster starts: local shards are forks that bake their share of it (with its
            # ray tree, built before they fork), and the merge stores the parts into it.
            plan = farm_plan(bpy.context, settings, receivers)
            if cluster.forks_shards:
                build_ray_tree(plan)
            parts = cluster.parts(lambda shard, part: bake_share(plan, shard, part, Stopwatch()))
            report = merge_parts(bpy.context, parts, log=log, plan=plan)
        warn(report.problems + report.notes)
    else:
        plan = plan_bake(read_request(bpy.context, settings, receivers, storage_options(args), volume_names=volumes))
        executor = local_executor(spec.worker_count(workers))
        found += scene_checks.scene_checks(bpy.context, plan, executor)
        log("prt: checks before any ray:")
        for check in found:
            log(f"prt:   {check.line()}")
        checks.stop_on_errors(found)
        report = store(plan, execute(plan, executor).run(log=log))
    log(report.summary.line())
    log(report.summary.curve_line())
    save_bake(report, args.output, args.report)
    return 0


def _farm_options(args) -> tuple[int, int] | None:
    """Checks how the farm options combine; the shard (K, N) to bake, or None."""
    if (args.shard is None) != (args.out is None):
        raise InputError("--shard K/N and --out PART.npz go together")
    texel_options = storage_options(args)
    if texel_options and (args.shard or args.dask):
        # Shards and the merge read each object's own storage choice, so that they plan the same bake.
        raise InputError(f"farm bakes store per vertex, as each object's own Storage says: "
                         f"{', '.join('--' + name.replace('_', '-') for name in texel_options)} does not apply")
    if args.shard is None:
        return None
    others = [option for option, given in (("--stale-only", args.stale_only), ("--dask", args.dask),
                                           ("--output", args.output), ("--report", args.report)) if given]
    if others:
        raise InputError(f"a shard only writes its part file (--out): {', '.join(others)} does not apply")
    return shard_of(args.shard)
