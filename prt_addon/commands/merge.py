"""`prt merge FILE PARTS...`: the bake of a farm's shards (`prt bake --shard K/N --out PART.npz`), stored and saved
as one bake would be, bit for bit; parts that do not make exactly one bake of this scene are refused, naming them,
and nothing is written."""

import bpy

from ..blender.farm import merge_parts
from ..core.shards import part_paths
from .common import check_outputs, log, open_file, save_bake, saved_file, warn

RELIGHTING = True  # the relighting handlers keep the saved file's PRT colours current with its SH lights


def add_parser(commands):
    parser = commands.add_parser("merge", help="merge a farm's shard part files into one bake")
    parser.add_argument("inputs", nargs="+", metavar="FILE PART",
                        help="the .blend file the shards baked (in Blender: defaults to the open file), then every "
                             "part file (prt bake --shard K/N --out PART.npz), or the folder that holds them")
    parser.add_argument("--output", help="where to save the baked file (default: over the opened file)")
    parser.add_argument("--report", help="write the bake report as JSON here")


def run(args, in_blender: bool) -> int:
    has_file = args.inputs[0].lower().endswith(".blend")
    blend_file, parts = (args.inputs[0], args.inputs[1:]) if has_file else (None, args.inputs)
    open_file(blend_file, required=not in_blender)
    check_outputs([("--report", args.report)], [("the part file", path) for path in part_paths(parts)],
                  saved=saved_file(args.output))
    report = merge_parts(bpy.context, parts, log=log)
    warn(report.problems + report.notes)
    log(report.summary.line())
    log(report.summary.curve_line())
    save_bake(report, args.output, args.report)
    return 0
