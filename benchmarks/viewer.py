"""The original program's performance table, redone in the browser viewer: frames per second in headless Chromium
(Debian's, WebGL 2 on SwiftShader, the CPU) for the demo scene with 1 and with 8 lights.

    .venv/bin/python benchmarks/viewer.py [--frames 40] [--rounds 5] [--size 640x480] [--json [DIR]] [--quick]

The demo scene (torus room, 13,575 vertices) is baked (order 4, shadowed, 64 rays a vertex) and exported with the
web profile; two pages load it, one keeping the export's first light, one with 8 (suns added as keys 1-8 add them).
Each measurement turns the active light every frame (the CPU sums and turns every light's SH and uploads them),
draws, and reads one pixel back so the frame is finished before the next one. The two pages alternate round by
round, so a busy moment of the shared machine hits both alike; it prints each side's median fps and the median
over rounds of the ratio 8 ÷ 1 lights. Goal: ≥ 0.9 (the shader's cost is one dot product per coefficient whatever
the number of lights; SHDemo lost 25-70 % of its frame rate with 8). Absolute fps on software GL is no goal.
--quick is a smoke run: a 16-ray bake, 2 rounds of 4 frames at 160 × 120 (options given override it; the goal is
for the full run).
"""

import argparse
import os
import statistics
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests")]

import bpy  # noqa: E402  (before mathutils, which the core uses)

from benchmarks import results as result_files  # noqa: E402
from browser import chromium, open_viewer  # noqa: E402
from prt_addon.blender import gltf, sample_scenes  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402
from prt_addon.commands.view import VIEWER, address, start_server, stop_server  # noqa: E402
from prt_addon.core import bake  # noqa: E402

GOAL = 0.9
FULL = {"frames": 40, "rounds": 5, "size": "640x480", "samples": 64}
QUICK = {"frames": 4, "rounds": 2, "size": "160x120", "samples": 16}


def export_demo(path, samples):
    """The demo scene baked and exported; without SH lights the export carries the default light (a sun, a sky)."""
    with schema_registered():
        bpy.ops.wm.read_homefile(use_empty=True)
        sample_scenes.build_demo_scene()
        SceneBake(bpy.context, bake.BakeSettings(order=4, mode="shadowed", samples=samples)).run(
            log=lambda line: None)
        gltf.export(bpy.context.scene, path, "web")


def measure(frames, rounds, size, samples) -> dict:
    with tempfile.TemporaryDirectory(prefix="prt_viewer_bench_") as folder:
        path = os.path.join(folder, "demo.glb")
        export_demo(path, samples)
        server = start_server(VIEWER, path)
        try:
            with chromium() as browser:
                pages = {count: open_viewer(browser, f"{address(server)}?lights={count}", size) for count in (1, 8)}
                for page in pages.values():  # warm up: shaders compiled, buffers uploaded
                    page.evaluate(f"window.prtViewer.benchmark({max(2, frames // 4)})")
                fps = {1: [], 8: []}
                for _ in range(rounds):
                    for count, page in pages.items():
                        fps[count].append(page.evaluate(f"window.prtViewer.benchmark({frames})"))
                vertices = pages[1].evaluate("window.prtViewer.state().vertices")
        finally:
            stop_server(server)
    ratios = [eight / one for one, eight in zip(fps[1], fps[8])]
    return {"size": list(size), "frames": frames, "rounds": rounds, "vertices": vertices,
            "fps_1_light": statistics.median(fps[1]), "fps_8_lights": statistics.median(fps[8]),
            "ratio_8_to_1": statistics.median(ratios), "ratios": ratios}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, help=f"frames per measurement (default {FULL['frames']})")
    parser.add_argument("--rounds", type=int, help=f"alternating measurements per side (default {FULL['rounds']})")
    parser.add_argument("--size", help=f"the page's size, WxH (default {FULL['size']})")
    parser.add_argument("--samples", type=int, help=f"the bake's rays per vertex (default {FULL['samples']})")
    result_files.add_argument(parser)
    parser.add_argument("--quick", action="store_true", help="a smoke run: " + ", ".join(
        f"{name} {value}" for name, value in QUICK.items()))
    args = parser.parse_args()
    result_files.check_folder(parser, args)
    for name, value in (QUICK if args.quick else FULL).items():
        if getattr(args, name) is None:
            setattr(args, name, value)
    size = tuple(int(part) for part in args.size.lower().split("x"))
    result = measure(args.frames, args.rounds, size, args.samples)
    goal = result_files.goal("frame rate, 8 lights ÷ 1 light", result["ratio_8_to_1"], ">=", GOAL)
    print(f"viewer, demo scene ({result['vertices']} glTF vertices) at {size[0]}×{size[1]} in headless Chromium "
          f"(SwiftShader), {args.rounds} rounds of {args.frames} frames:")
    print(f"  1 light:  {result['fps_1_light']:.1f} fps")
    print(f"  8 lights: {result['fps_8_lights']:.1f} fps")
    print(f"  8 ÷ 1 lights: {result['ratio_8_to_1']:.3f} (rounds: "
          f"{', '.join(f'{r:.3f}' for r in result['ratios'])}); goal ≥ {GOAL}: {goal['verdict']}")
    if args.json:
        result_files.write("viewer", args, result, [goal])


if __name__ == "__main__":
    main()
