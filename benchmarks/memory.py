"""Peak memory of a 1 M-vertex shadowed bake, as a multiple of the transfer it stores.

    .venv/bin/python benchmarks/memory.py [--side 1000] [--samples 16] [--quick] [--json [DIR]]

(--quick: a 100 × 100 grid, a smoke run of seconds; the ratio then holds mostly Blender's fixed overhead.)

The bake streams fixed 128-vertex chunks, casting at most 65,536 rays at a time, so rays never pile up: what
it holds for the whole mesh is the receiver's positions and normals, the transfer and its error. The printed ratio is
(peak resident memory during the bake − resident memory before it) ÷ (vertices × n² × 4 bytes).
"""

import argparse
import os
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (before mathutils)
import numpy as np  # noqa: E402

from benchmarks import results as result_files  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.core.bake import BakeSettings  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402


def resident_bytes() -> int:
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


class PeakSampler(threading.Thread):
    """Samples resident memory every few milliseconds until stopped."""

    def __init__(self):
        super().__init__(daemon=True)
        self.peak = resident_bytes()
        self.running = True

    def run(self):
        while self.running:
            self.peak = max(self.peak, resident_bytes())
            time.sleep(0.005)


def build_grid(side: int):
    """A side × side vertex grid at z = 0 under a small square occluder."""
    ticks = np.linspace(-5.0, 5.0, side)
    xs, ys = np.meshgrid(ticks, ticks)
    vertices = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(side * side)]).astype(np.float32)
    rows = np.arange(side - 1)
    corner = (rows[:, None] * side + rows[None, :]).ravel()
    quads = np.column_stack([corner, corner + 1, corner + side + 1, corner + side]).astype(np.int32)
    mesh = bpy.data.meshes.new("Grid")
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", vertices.ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update()
    grid = bpy.data.objects.new("Grid", mesh)
    bpy.context.collection.objects.link(grid)
    blocker = bpy.data.meshes.new("Blocker")
    blocker.from_pydata([(-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)], [], [(0, 1, 2, 3)])
    bpy.context.collection.objects.link(bpy.data.objects.new("Blocker", blocker))
    return grid


QUICK_SIDE = 100


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, help="grid side: side² vertices (default 1000: 1 M; --quick 100)")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--order", type=int, default=4)
    parser.add_argument("--quick", action="store_true", help=f"a smoke run on a {QUICK_SIDE} × {QUICK_SIDE} grid")
    result_files.add_argument(parser)
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    args.side = args.side or (QUICK_SIDE if args.quick else 1000)
    bpy.ops.wm.read_homefile(use_empty=True)
    grid = build_grid(args.side)
    vertices = len(grid.data.vertices)
    settings = BakeSettings(order=args.order, samples=args.samples, replicates=min(8, args.samples))
    before = resident_bytes()
    sampler = PeakSampler()
    sampler.start()
    start = time.perf_counter()
    scene_bake = SceneBake(bpy.context, settings, ["Grid"])
    summary = scene_bake.run(log=lambda line: print(line, flush=True))
    elapsed = time.perf_counter() - start
    sampler.running = False
    sampler.join()
    transfer_bytes = vertices * args.order ** 2 * 4
    print(summary.line())
    print(f"vertices {vertices:,}, order {args.order}: transfer stored {transfer_bytes / 2**20:.1f} MiB (float32)")
    print(f"resident before {before / 2**20:.0f} MiB, peak during bake {sampler.peak / 2**20:.0f} MiB, "
          f"wall {elapsed:.1f} s")
    ratio = (sampler.peak - before) / transfer_bytes
    print(f"peak memory / transfer size = {ratio:.2f}")
    if args.json:  # no goal: the figure says what a bake holds beyond its transfer
        result_files.write("memory", args, {"vertices": vertices, "transfer_bytes": transfer_bytes,
                                            "resident_before_bytes": before, "peak_bytes": sampler.peak,
                                            "wall_s": elapsed, "peak_over_transfer": ratio}, [], argv)


if __name__ == "__main__":
    with schema_registered():  # each object's storage choice, which the bake reads, is a schema property
        sys.exit(main())
