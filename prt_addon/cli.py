"""The command line: one parser and one implementation for `python -m prt_addon ...` (bpy module) and
`blender --background [file.blend] --command prt ...` (a real Blender). Exit 0 on success, 1 with a
one-line reason on failure."""

import argparse
import json
import os
import sys

import bpy

COMMAND_ID = "prt"
_cli_handle = None


class CliError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would exit with 2; we promise 1 and one line
        raise CliError(f"{self.prog}: {message}")


def _bounces(text: str):
    if text == "auto":
        return None
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"bounces must be a whole number or 'auto', not {text!r}") from None


def build_parser() -> argparse.ArgumentParser:
    from .convergence import DEFAULT_SAMPLES as CONVERGENCE_SAMPLES
    from .validate import DEFAULT_PASSES as CYCLES_PASSES, DEFAULT_SAMPLES as CYCLES_SAMPLES
    parser = _Parser(prog="prt", description="Precomputed radiance transfer for Blender.")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    commands.required = True

    bake = commands.add_parser("bake", help="bake SH transfer into a .blend file's meshes")
    bake.add_argument("file", nargs="?", help=".blend file to open (in Blender: defaults to the open file)")
    bake.add_argument("--objects", help="comma-separated receiver names (default: every visible mesh)")
    bake.add_argument("--mode", choices=("unshadowed", "shadowed", "interreflected"), default="shadowed")
    bake.add_argument("--bounces", type=_bounces, default=None,
                      help="interreflected: a number of bounces, or 'auto' (default)")
    bake.add_argument("--bounce-tolerance", type=float, default=1e-3, help="what 'auto' bounces may leave out")
    bake.add_argument("--order", type=int, default=4, help="SH bands, 1-10 (default 4: 16 coefficients)")
    bake.add_argument("--samples", type=int, default=256, help="rays per vertex (first round with a target)")
    bake.add_argument("--target-error", type=float, default=0.0,
                      help="sample each vertex until its estimated relative error is below this")
    bake.add_argument("--max-samples", type=int, default=16384, help="ray budget per vertex with a target")
    bake.add_argument("--workers", type=int, default=1, help="worker processes casting rays")
    bake.add_argument("--seed", type=int, default=0)
    bake.add_argument("--output", help="where to save the baked file (default: over the opened file)")
    bake.add_argument("--report", help="write the bake report as JSON here")

    export = commands.add_parser("export", help="write one object's bake to a .npz for use outside Blender")
    export.add_argument("file", help=".blend file")
    export.add_argument("--object", required=True, help="object name")
    export.add_argument("--npz", required=True, help="output .npz path")

    relight = commands.add_parser("relight", help="re-render a baked .blend file under changed SH lights")
    relight.add_argument("file", help=".blend file with a bake and SH lights")
    relight.add_argument("--light", type=int, help="index of the SH light to aim (default: the active one)")
    relight.add_argument("--light-theta", type=float, metavar="DEGREES", help="angle from the zenith; a light that "
                         "follows a Sun object stops following it")
    relight.add_argument("--light-phi", type=float, metavar="DEGREES", help="azimuth, from +X towards +Y")
    relight.add_argument("--engine", choices=("EEVEE", "WORKBENCH"), default="EEVEE",
                         help="EEVEE: PRT colour × albedo texture; WORKBENCH: the PRT colour alone, faster")
    relight.add_argument("--samples", type=int, default=4, help="EEVEE render samples")
    relight.add_argument("--resolution", type=_resolution, metavar="WxH", help="default: the file's")
    relight.add_argument("--render", required=True, metavar="OUT.png", help="where to write the image")

    validate = commands.add_parser("validate", help="compare the PRT colours with Cycles under the same light")
    validate.add_argument("file", nargs="?", help="baked .blend file (in Blender: defaults to the open file)")
    validate.add_argument("--objects", help="comma-separated names (default: every visible mesh with a bake)")
    validate.add_argument("--samples", type=int, default=CYCLES_SAMPLES, help="Cycles samples per pass")
    validate.add_argument("--passes", type=int, default=CYCLES_PASSES,
                          help="Cycles passes with different seeds; their spread measures Cycles' noise (≥ 2)")
    validate.add_argument("--report", help="write the comparison as JSON here")

    convergence = commands.add_parser("convergence", help="bake at several sample counts; estimated and actual "
                                                          "error against bake time as CSV and a PNG plot")
    convergence.add_argument("file", nargs="?", help=".blend file (in Blender: defaults to the open file)")
    convergence.add_argument("--samples", type=_sample_counts, default=CONVERGENCE_SAMPLES,
                             metavar="16,32,...", help="rays per vertex of each bake (default 16,32,...,4096)")
    convergence.add_argument("--objects", help="comma-separated receiver names (default: every visible mesh)")
    convergence.add_argument("--order", type=int, default=4, help="SH bands, 1-10")
    convergence.add_argument("--reference", choices=("bake", "cycles"), default="bake",
                             help="bake: a bake at 16x the largest count, another seed (default); cycles: Cycles "
                                  "under the scene's SH lights")
    convergence.add_argument("--reference-samples", type=int, help="rays per vertex of the reference bake, or "
                             f"Cycles samples per pass (default {CYCLES_SAMPLES}, "
                             f"{CYCLES_PASSES} passes)")
    convergence.add_argument("--workers", type=int, default=1, help="worker processes casting rays")
    convergence.add_argument("--seed", type=int, default=0)
    convergence.add_argument("--csv", default="convergence.csv", help="where to write the table")
    convergence.add_argument("--plot", default="convergence.png", help="where to write the log-log plot")

    demo = commands.add_parser("demo", help="build the sample scene, bake, relight, render a PNG and a report")
    demo.add_argument("--output", default="demo_output", help="folder for the PNG, report and .blend")
    demo.add_argument("--workers", type=int, default=2)
    demo.add_argument("--samples", type=int, default=256)
    return parser


def _sample_counts(text):
    try:
        return [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, e.g. 16,64,256, got {text!r}") \
            from None


def _resolution(text):
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, e.g. 640x480, got {text!r}") from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"resolution must be positive, got {text!r}")
    return width, height


def main(argv, in_blender: bool = False) -> int:
    from . import mesh_data, relight
    try:
        args = build_parser().parse_args(argv)
        return COMMANDS[args.command](args, in_blender)
    except SystemExit as leaving:  # --help
        return int(leaving.code or 0)
    except (CliError, mesh_data.InputError, mesh_data.StaleBake, relight.RelightError) as failure:
        print(f"prt: error: {failure}", file=sys.stderr)
        return 1
    except Exception as failure:  # any other failure still gets its one line
        print(f"prt: error: {type(failure).__name__}: {failure}", file=sys.stderr)
        return 1


def _open(path, required: bool):
    if path:
        if not os.path.isfile(path):
            raise CliError(f"no such file: {path}")
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
    elif required or not bpy.data.filepath and not bpy.data.objects:
        raise CliError("give a .blend file to open")


def _write_json(path, data):
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    with open(path, "w", encoding="utf-8") as handle:
        json.dump(data, handle, indent=2)


def run_bake(args, in_blender: bool) -> int:
    from .baking import SceneBake
    from .core.bake import BakeSettings
    _open(args.file, required=not in_blender)
    settings = BakeSettings(order=args.order, mode=args.mode, samples=args.samples,
                            target_error=args.target_error, max_samples=args.max_samples, seed=args.seed,
                            bounces=args.bounces, bounce_tolerance=args.bounce_tolerance)
    scene_bake = SceneBake(bpy.context, settings, _names(args.objects), workers=args.workers)
    for problem in scene_bake.problems + scene_bake.notes:
        print(f"prt: warning: {problem}", file=sys.stderr)
    summary = scene_bake.run(log=lambda line: print(line, flush=True))
    print(summary.line(), flush=True)
    output = args.output or bpy.data.filepath
    if not output:
        raise CliError("the scene has no file; give --output")
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(output))
    if args.report:
        _write_json(args.report, scene_bake.report_dict())
    return 0


def run_export(args, in_blender: bool) -> int:
    import numpy as np
    from . import mesh_data
    _open(args.file, required=True)
    ob = bpy.data.objects.get(args.object)
    if ob is None or ob.type != "MESH":
        raise CliError(f"no mesh object named {args.object!r} in {args.file}")
    transfer, meta = mesh_data.read_transfer(ob.data)
    matrix = np.array(ob.matrix_world, dtype=np.float64)
    local = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertices.foreach_get("co", local)
    local = local.reshape(-1, 3)
    normals = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertex_normals.foreach_get("vector", normals)
    world_normals = normals.reshape(-1, 3) @ np.linalg.inv(matrix[:3, :3])
    world_normals /= np.maximum(np.linalg.norm(world_normals, axis=1, keepdims=True), 1e-30)
    np.savez(args.npz,
             positions=local @ matrix[:3, :3].T + matrix[:3, 3], normals=world_normals,
             local_positions=local, matrix_world=matrix,
             transfer=transfer.reshape(len(local), -1, transfer.shape[-1]), metadata=np.array(json.dumps(meta)))
    print(f"prt: wrote {args.npz}: {len(local)} vertices, order {meta['order']}, {meta['mode']}")
    return 0


def run_relight(args, in_blender: bool) -> int:
    from . import relight
    done = relight.relight_file(args.file, args.render, args.light, args.light_theta, args.light_phi,
                                engine=args.engine, samples=args.samples, resolution=args.resolution)
    width, height = done["resolution"]
    print(f"prt: rendered {done['path']} with {done['engine']} at {width}×{height} in {done['render_s']:.1f} s "
          f"(relit in {1000 * done['relight_s']:.0f} ms)")
    for line in done["lights"]:
        print(f"prt:   {line}")
    return 0


def _names(text):
    return [name.strip() for name in text.split(",")] if text else None


def run_validate(args, in_blender: bool) -> int:
    from . import relight, validate
    relight.ensure_registered()  # the scene's SH lights are add-on properties
    _open(args.file, required=not in_blender)
    validation = validate.Validation(bpy.context, args.samples, args.passes, _names(args.objects))
    for sentence in validation.problems + validation.notes:
        print(f"prt: warning: {sentence}", file=sys.stderr)
    comparisons = validation.run(log=lambda line: print(line, flush=True))
    print("\n".join(validation.lines(comparisons)), flush=True)
    if args.report:
        _write_json(args.report, validation.report_dict(comparisons))
    return 0


def run_convergence(args, in_blender: bool) -> int:
    from . import convergence, relight
    relight.ensure_registered()
    _open(args.file, required=not in_blender)
    study = convergence.Study(bpy.context, args.samples, _names(args.objects), args.order, args.reference,
                              args.reference_samples, args.workers, args.seed)
    rows = study.run(log=lambda line: print(line, flush=True))
    for sentence in study.notes:
        print(f"prt: warning: {sentence}", file=sys.stderr)
    convergence.write_csv(args.csv, rows)
    title = f"PRT error against bake time: {os.path.basename(bpy.data.filepath) or 'scene'}"
    convergence.write_plot(args.plot, rows, title, study.reference_text())
    print(f"prt: wrote {os.path.abspath(args.csv)} and {os.path.abspath(args.plot)}")
    return 0


def run_demo(args, in_blender: bool) -> int:
    from . import demo
    return demo.run(args.output, workers=args.workers, samples=args.samples)


COMMANDS = {"bake": run_bake, "export": run_export, "relight": run_relight, "validate": run_validate,
            "convergence": run_convergence, "demo": run_demo}


def blender_command(argv) -> int:
    return main(list(argv), in_blender=True)


def register_command():
    global _cli_handle
    _cli_handle = bpy.utils.register_cli_command(COMMAND_ID, blender_command)


def unregister_command():
    global _cli_handle
    if _cli_handle is not None:
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
