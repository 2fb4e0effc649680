"""`prt validate`: the baked meshes against Cycles under the same light; progress lines, a line overall and one
per object, and an optional JSON report."""

import argparse

import bpy

from ..blender.image_validation import DEFAULT_PASSES as IMAGE_PASSES, DEFAULT_RESOLUTION, validate_image
from ..blender.validation import DEFAULT_PASSES, DEFAULT_SAMPLES, REFERENCES, Validation
from ..blender.outputs import IMAGE_FORMATS
from ..core.outputs import check_suffix
from .common import add_object_options, check_outputs, log, object_names, open_file, warn, write_json

RELIGHTING = True  # --image renders the PRT display, which the relighting handlers switch on and off


def add_parser(commands):
    parser = commands.add_parser("validate", help="compare the PRT colours with Cycles under the same light")
    parser.add_argument("file", nargs="?", help="baked .blend file (in Blender: defaults to the open file)")
    add_object_options(parser, "the selected meshes when one has a bake, else every visible mesh with a bake")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES, help="Cycles samples per pass")
    parser.add_argument("--passes", type=int,
                        help=f"Cycles passes with different seeds; their spread measures Cycles' noise (≥ 2; default "
                             f"{DEFAULT_PASSES}, with --image {IMAGE_PASSES})")
    parser.add_argument("--reference", choices=REFERENCES, default=REFERENCES[0],
                        help="band-limited: Cycles under the light PRT uses (PRT's own error); light: also under the "
                             "scene's lights as they are, for the total error and what band-limiting costs")
    parser.add_argument("--report", help="write the comparison as JSON here")
    parser.add_argument("--image", action="store_true",
                        help="compare what the camera sees instead: a Cycles render against the PRT display (EEVEE), "
                             "pixel by pixel (--passes defaults to 2 here)")
    parser.add_argument("--camera", help="--image: the camera to render from (default: the scene's)")
    parser.add_argument("--resolution", type=resolution, default=DEFAULT_RESOLUTION,
                        help="--image: WIDTHxHEIGHT of both renders (default 160x120)")
    parser.add_argument("--heatmap", help="--image: write an image of each pixel's error here (.png, .jpg)")


def resolution(text: str) -> tuple[int, int]:
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must be WIDTHxHEIGHT, not {text!r}") from None
    if not (1 <= width <= 8192 and 1 <= height <= 8192):
        raise argparse.ArgumentTypeError(f"resolution must be 1-8192 on each side, not {text}")
    return width, height


def run(args, in_blender: bool) -> int:
    if args.heatmap:
        check_suffix(args.heatmap, "--heatmap", list(IMAGE_FORMATS))
    open_file(args.file, required=not in_blender)
    check_outputs([("--report", args.report), ("--heatmap", args.heatmap)])
    if args.image:
        return _run_image(args)
    validation = Validation(bpy.context, args.samples, args.passes or DEFAULT_PASSES, object_names(args),
                            args.reference)
    warn(validation.problems + validation.notes)
    comparisons = validation.run(log=log)
    log("\n".join(validation.lines(comparisons)))
    if args.report:
        write_json(args.report, validation.report(comparisons).as_dict())
    return 0


def _run_image(args) -> int:
    report = validate_image(bpy.context, args.camera, args.samples, args.passes or IMAGE_PASSES, args.resolution,
                            args.heatmap)
    warn(report.notes)
    log(report.line())
    if args.report:
        write_json(args.report, report.as_dict())
    return 0
