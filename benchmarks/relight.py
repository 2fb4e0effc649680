"""Relighting speed: from a light change to the colour attribute written, through the real depsgraph handler.

    .venv/bin/python benchmarks/relight.py [--steps 60] [--json [DIR]] [--texels | --texels-only] [--quick]

For grids of 10 k, 100 k and 1 M vertices baked at order 4 (unshadowed: the timing does not depend on the
transfer's values), it changes lights' θ, runs `view_layer.update()` and measures the time until the handler has
written the colours: with 1 light, with 8 lights of which one moves (the panel's case) and with 8 lights that all
move (a driver on each). The three alternate update by update, so that a busy moment of the machine hits them
alike; it prints the median times and the median over updates of the ratio 8 ÷ 1 of neighbouring updates.
"full update" is the whole `view_layer.update()` with 1 light: it adds Blender re-evaluating the written mesh,
which follows every write of mesh data and is outside the add-on's control.
Goals on this machine: ≤ 33 ms at 1 M vertices, and 8 lights ÷ 1 light ≤ 1.1.
Then, for the orders up to 16 that Order from Lights may pick: the 1 M-vertex grid baked at orders 4, 8 and 16, the
median time of a 1-light update to the colours written, and the transfer's stored size.

Texel storage (`--texels`, or `--texels-only`): a floor baked per texel at 1024 × 1024, the time from a light change
to the shaded image written (one product per texel, float32 foreach_set on its pixels), split into the shading and
the write, against the same goal of 33 ms. Beside it, the handler's cost of the alternative (the display material
forming the dot product on the GPU from the coefficient maps): setting the summed light's 3 × 16 values on its
nodes; the GPU's own per-pixel work cannot be timed without a display.

--quick is a smoke run of seconds: grids of 100, 1,000 and 10,000 vertices, a 128 × 128 texel map and 5 updates
each (the goals are for the full run).
"""

import argparse
import gc
import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402  (before mathutils, which the core uses)

from benchmarks import results as result_files  # noqa: E402

import prt_addon  # noqa: E402
from prt_addon.blender import display, texel_maps  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.core import bake  # noqa: E402

SIDES = (100, 317, 1000)  # grid side: 10 k, 100 k and 1 M vertices
QUICK_SIDES = (10, 32, 100)
QUICK_STEPS = 5
ORDERS = (4, 8, 16)  # the 1 M-vertex update at each
LIGHTS = 8
GOAL_MS = 33.0
GOAL_RATIO = 1.1


def baked_grid(side, order=4):
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=side - 1, y_subdivisions=side - 1, size=2)
    SceneBake(bpy.context, bake.BakeSettings(order=order, mode="unshadowed")).run(log=lambda line: None)
    return bpy.context.object


class WriteClock:
    """Wraps the colour write the handler calls, noting when it returns."""

    def __init__(self):
        self.written_at = None
        self._write = display.write_display_colours

    def __enter__(self):
        def timed_write(*args):
            self._write(*args)
            self.written_at = time.perf_counter()
        display.write_display_colours = timed_write
        return self

    def __exit__(self, *exc):
        display.write_display_colours = self._write


def set_light_count(scene, count):
    """Adds or removes suns, then lets the handler settle with an update that is not timed."""
    while len(scene.prt_lights) > count:
        scene.prt_lights.remove(len(scene.prt_lights) - 1)
    while len(scene.prt_lights) < count:
        bpy.ops.prt.light_add(kind="SUN")
        scene.prt_lights[-1].phi = 2 * math.pi * len(scene.prt_lights) / LIGHTS
    scene.update_tag()
    bpy.context.view_layer.update()


def timed_update(moving, theta, clock):
    """(seconds from changing θ of the `moving` lights to the colours written, seconds of the whole update)."""
    clock.written_at = None
    start = time.perf_counter()
    for k, light in enumerate(moving):
        light.theta = theta + 0.01 * k
    bpy.context.view_layer.update()
    end = time.perf_counter()
    if clock.written_at is None:
        raise RuntimeError("the handler did not write the colours")
    return clock.written_at - start, end - start


def measure(scene, steps, clock):
    """Median ms for 1 light, 8 with one moving, 8 all moving, and the whole update with 1 light.

    The configurations alternate update by update, so that a busy moment of the machine hits them alike."""
    samples = {"one": [], "eight_one": [], "eight_all": [], "full": []}
    for step in range(steps):
        theta = 0.2 + 1.2 * ((step * 0.37) % 1.0)
        set_light_count(scene, 1)
        written, full = timed_update(scene.prt_lights[:1], theta, clock)
        samples["one"].append(written)
        samples["full"].append(full)
        set_light_count(scene, LIGHTS)
        samples["eight_one"].append(timed_update(scene.prt_lights[:1], theta + 0.1, clock)[0])
        samples["eight_all"].append(timed_update(list(scene.prt_lights), theta + 0.2, clock)[0])
    medians = {name: 1000 * statistics.median(values) for name, values in samples.items()}
    # Ratios of neighbouring updates, then their median: a busy moment spoils one pair, not the ratio.
    for name, eight in (("ratio_one_moving", samples["eight_one"]), ("ratio_all_moving", samples["eight_all"])):
        medians[name] = statistics.median(e / o for e, o in zip(eight, samples["one"]))
    return medians


def order_costs(side, steps, clock):
    """{order: (median ms of a 1-light update, stored transfer MB)} on the side × side grid."""
    costs = {}
    for order in ORDERS:
        mesh = baked_grid(side, order).data
        stored = sum(a.data_type == "FLOAT_VECTOR" and a.name.startswith("_prt_t") for a in mesh.attributes)
        set_light_count(bpy.context.scene, 1)
        times = [timed_update(bpy.context.scene.prt_lights[:1], 0.2 + 1.2 * ((step * 0.37) % 1.0), clock)[0]
                 for step in range(steps)]
        costs[order] = (1000 * statistics.median(times), stored * 12 * len(mesh.vertices) / 1e6)
        gc.collect()
    return costs


TEXEL_SIDE, QUICK_TEXEL_SIDE = 1024, 128


def baked_texel_floor(side=TEXEL_SIDE):
    """A one-quad floor stored per texel at side × side (unshadowed: every texel covered, no rays)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_plane_add(size=2)
    SceneBake(bpy.context, bake.BakeSettings(order=4, mode="unshadowed"), storage_options={
        "storage": "texel", "resolution": side, "uv_map": "UVMap"}).run(log=lambda line: None)
    return bpy.context.object


class ShadeClock:
    """Wraps the texel shading the handler calls, noting when it returns and how long its write took."""

    def __init__(self):
        self.written_at = None
        self.write_s = []
        self._shade = texel_maps.write_shaded

    def __enter__(self):
        def timed_shade(mesh, transfer, light):
            image = self._shade(mesh, transfer, light)
            self.written_at = time.perf_counter()
            return image
        texel_maps.write_shaded = timed_shade
        return self

    def __exit__(self, *exc):
        texel_maps.write_shaded = self._shade


def measure_texels(steps, side=TEXEL_SIDE):
    """Median ms from a light change to the side² shaded image written, of the shading alone and the pixel write
    alone, and of setting 48 node values (the GPU alternative's handler work)."""
    floor = baked_texel_floor(side)
    scene = bpy.context.scene
    scene.prt_display.show_prt = True
    set_light_count(scene, 1)
    planes = np.ascontiguousarray(texel_maps.read_planes(floor.data)[0].T)
    image = texel_maps.shaded_image(floor.data)
    light = np.ones((3, 16), dtype=np.float32)
    rgba = np.ones((len(planes), 4), dtype=np.float32)
    material = floor.material_slots[0].material
    values = [material.node_tree.nodes.new("ShaderNodeValue") for _ in range(48)]
    samples = {"update": [], "shade": [], "write": [], "gpu_values": []}
    with ShadeClock() as clock:
        for step in range(steps):
            samples["update"].append(timed_update(scene.prt_lights[:1], 0.2 + 1.2 * ((step * 0.37) % 1.0), clock)[0])
            start = time.perf_counter()
            shaded = planes @ np.pad(light.T, ((0, 0), (0, 1)))
            samples["shade"].append(time.perf_counter() - start)
            start = time.perf_counter()
            image.pixels.foreach_set(rgba.ravel())
            image.update()
            samples["write"].append(time.perf_counter() - start)
            start = time.perf_counter()
            for k, node in enumerate(values):
                node.outputs[0].default_value = float(shaded[k, 0])
            samples["gpu_values"].append(time.perf_counter() - start)
    return {name: 1000 * statistics.median(found) for name, found in samples.items()}


def goal(goals: list, name: str, figure, bound, unit: str = "") -> str:
    """Records a goal of the form figure ≤ bound; its verdict to print."""
    goals.append(result_files.goal(name, figure, "<=", bound, unit))
    return goals[-1]["verdict"]


def finish(args, figures: dict, goals: list) -> int:
    prt_addon.unregister()
    if args.json:
        result_files.write("relight", args, figures, goals, args.argv)
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, help="timed updates per configuration (default 60; --quick 5)")
    result_files.add_argument(parser)
    parser.add_argument("--texels", action="store_true", help="also time a 1024 × 1024 texel map")
    parser.add_argument("--texels-only", action="store_true", help="time only the 1024 × 1024 texel map")
    parser.add_argument("--quick", action="store_true", help="a smoke run on small grids and a small texel map")
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    args.argv = argv
    args.steps = args.steps or (QUICK_STEPS if args.quick else 60)
    sides, texel_side = (QUICK_SIDES, QUICK_TEXEL_SIDE) if args.quick else (SIDES, TEXEL_SIDE)
    prt_addon.register()
    print(f"relight benchmark: bpy {bpy.app.version_string}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f}")
    figures, goals = {"steps": args.steps}, []
    if args.texels or args.texels_only:
        ms = figures["texels_ms"] = measure_texels(args.steps, texel_side)
        met = goal(goals, f"light change to shaded image, {texel_side}² texels", ms["update"], GOAL_MS, "ms")
        print(f"texels {texel_side} × {texel_side}, order 4, median of {args.steps} updates: light change to shaded "
              f"image {ms['update']:.1f} ms (shading {ms['shade']:.1f} ms, pixel write {ms['write']:.1f} ms)   goal <= "
              f"{GOAL_MS:.0f} ms   {met}")
        print(f"  GPU alternative's handler: 48 light values set on nodes in {ms['gpu_values']:.2f} ms")
        if args.texels_only:
            return finish(args, figures, goals)
    print(f"order 4, median of {args.steps} updates each; ms from a light change to the colours written")
    print(f"{'vertices':>10} {'1 light':>9} {'8 (1 moves)':>12} {'ratio':>6} {'8 (all move)':>13} {'ratio':>6}"
          f" {'full update':>12}")
    results = {}
    gc.disable()  # a collection in the middle of a timed update says nothing about relighting
    with WriteClock() as clock:
        for side in sides:
            vertices = len(baked_grid(side).data.vertices)
            ms = measure(bpy.context.scene, args.steps, clock)
            results[vertices] = ms
            print(f"{vertices:>10,} {ms['one']:>7.2f}ms {ms['eight_one']:>10.2f}ms {ms['ratio_one_moving']:>6.2f}"
                  f" {ms['eight_all']:>11.2f}ms {ms['ratio_all_moving']:>6.2f} {ms['full']:>10.2f}ms")
            gc.collect()
        costs = order_costs(sides[-1], max(5, args.steps // 6), clock)
    gc.enable()
    largest = max(results)
    for order, (ms, megabytes) in costs.items():
        print(f"order {order:2d} at {largest:,} vertices: {ms:.1f} ms per update (1 light), "
              f"transfer {megabytes:,.0f} MB stored")
    time_ms = results[largest]["one"]
    met = goal(goals, f"light change to colours written, {largest:,} vertices", time_ms, GOAL_MS, "ms")
    print(f"per update at {largest:,} vertices: {time_ms:.1f} ms   goal <= {GOAL_MS:.0f} ms   {met}")
    for vertices, ms in results.items():
        met = goal(goals, f"8 lights ÷ 1 light, {vertices:,} vertices", ms["ratio_one_moving"], GOAL_RATIO)
        print(f"8 lights ÷ 1 light at {vertices:,} vertices (one moving): {ms['ratio_one_moving']:.2f}   "
              f"goal <= {GOAL_RATIO}   {met}")
    figures.update(ms_by_vertices=results, order_ms_and_mb_at_largest={str(o): cost for o, cost in costs.items()})
    return finish(args, figures, goals)


if __name__ == "__main__":
    sys.exit(main())
