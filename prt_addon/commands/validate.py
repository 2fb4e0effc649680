"""`prt validate`: the baked meshes against Cycles under the same light; progress lines, a line overall and one
per object, and an optional JSON report."""

import bpy

from ..blender.validation import DEFAULT_PASSES, DEFAULT_SAMPLES, REFERENCES, Validation
from .common import log, names, open_file, warn, write_json


def add_parser(commands):
    parser = commands.add_parser("validate", help="compare the PRT colours with Cycles under the same light")
    parser.add_argument("file", nargs="?", help="baked .blend file (in Blender: defaults to the open file)")
    parser.add_argument("--objects", help="comma-separated names (default: every visible mesh with a bake)")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES, help="Cycles samples per pass")
    parser.add_argument("--passes", type=int, default=DEFAULT_PASSES,
                        help="Cycles passes with different seeds; their spread measures Cycles' noise (≥ 2)")
    parser.add_argument("--reference", choices=REFERENCES, default=REFERENCES[0],
                        help="band-limited: Cycles under the light PRT uses (PRT's own error); light: also under the "
                             "scene's lights as they are, for the total error and what band-limiting costs")
    parser.add_argument("--report", help="write the comparison as JSON here")


def run(args, in_blender: bool) -> int:
    open_file(args.file, required=not in_blender)
    validation = Validation(bpy.context, args.samples, args.passes, names(args.objects), args.reference)
    warn(validation.problems + validation.notes)
    comparisons = validation.run(log=log)
    log("\n".join(validation.lines(comparisons)))
    if args.report:
        write_json(args.report, validation.report(comparisons).as_dict())
    return 0
