"""PRT probe volumes: a dynamic object moved through the demo room against Cycles, and the live cost of relighting it.

    .venv/bin/python benchmarks/probes.py [--quick] [--only accuracy|live] [--mode shadowed|interreflected]
                                          [--samples 64] [--passes 4] [--steps 30] [--json [DIR]]

Accuracy: the demo room (blender.sample_scenes.build_demo_scene, with `prt demo`'s sun and sky as SH lights) with a
probe volume over it and a dynamic Suzanne (scaled to 0.25, lit per vertex) moved and turned to PLACEMENTS: in the
open, in the torus's shadow, across its edge, beside the back wall, in the corner. At each, Cycles renders the whole
scene under the same band-limited light (blender.validation, as `prt validate` does: shadowed bakes, so direct light;
with --mode interreflected, bakes with bounces against Cycles' indirect diffuse light too, the probes then holding
the light the room's surfaces reflect)
and PRT's colours (self-transfer × the probes' light at each vertex) are compared vertex by vertex, Cycles' noise
taken out. Beside them, the same Suzanne baked statically at the first placement and then moved (its bake stale),
compared with the same Cycles passes. The probe spacing is swept over RESOLUTIONS (probes over the room's
5 × 5 × 2.5): the error at every placement and the probes' bake time for each, so a user can choose.
Goal: ≤ 5 % RMS at every placement (at the finest spacing).

Live: LIVE_PROBES (16³) probes over a floor and a dynamic UV sphere of about 100 k vertices. Each update changes a
light's θ and moves and turns the sphere (a frame of an animation), runs `view_layer.update()` and times until the
relighting handler has written the sphere's colours: one product per probe for the new light, then every vertex's
own blend of probes. 1 light and 8 lights (one moving) alternate update by update; the median time with 1 light
and the median ratio of neighbouring updates. The goals are judged on the CPU time of Blender's main thread, which
runs the handler: on the shared machines we use, the wall time also holds the time other processes had the cores
(it is printed beside). Goals: ≤ 33 ms per update, 8 lights ÷ 1 ≤ 1.1. Then the parts of one update, timed apart:
the probes' product, the per-vertex shading, the colour write.

--quick is a smoke run of seconds: coarse probes, 2 Cycles passes of 4 samples, small live objects, few updates.
"""

import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402  (before mathutils, which the core uses)

import prt_addon  # noqa: E402
from benchmarks import results as result_files  # noqa: E402
from benchmarks.relight import set_light_count, timed_update  # noqa: E402
from prt_addon.blender import display, layouts, probe_volumes, sample_scenes, storage, validation  # noqa: E402
from prt_addon.blender.relighting import dynamic_radiance  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.commands.demo import add_lights  # noqa: E402
from prt_addon.core import bake, probe_grid  # noqa: E402
from prt_addon.core.statistics import compare  # noqa: E402

ORDER = 4
SAMPLES = 1024  # rays per probe (and per floor vertex, baked with them)
SUZANNE_SCALE = 0.25  # 0.66 m from ear to ear, 0.48 m tall: she fits under the torus's tube in its shadow
SUZANNE_MIDDLE = 0.96  # her middle's height above her lowest point, unscaled
# (name, location, Euler turn): the room's floor is z = 0, its walls x = −2.5 and y = 2.5; "shadow" and "edge" are
# placed from the sun's direction at run time (shadow_placements).
PLACEMENTS = [("open", (1.5, -1.6, 0.1), (0.0, 0.0, 0.4)),
              ("back wall", (0.6, 2.05, 0.1), (0.0, 0.0, 2.6)),
              ("corner", (-2.0, 1.9, 0.1), (0.3, 0.0, -2.3))]
RESOLUTIONS = [(5, 5, 3), (10, 10, 5), (20, 20, 10), (40, 40, 20)]
QUICK_RESOLUTIONS = [(2, 2, 1), (4, 4, 2)]
GOAL_RMS = 0.05
LIVE_PROBES, QUICK_LIVE_PROBES = (16, 16, 16), (4, 4, 4)
LIVE_SPHERE, QUICK_LIVE_SPHERE = (448, 224), (32, 16)  # segments, rings: 99,906 and 482 vertices
LIGHTS = 8
GOAL_MS = 33.0
GOAL_RATIO = 1.1


def log(line):
    pass


def shadow_placements(sun) -> list:
    """Suzanne on the floor where the torus's tube hides the sun from her middle, on the side of the torus away from
    the sun (so that she stands clear of the tube), and further out across the shadow's edge, half in it."""
    towards_sun = np.array(sun.matrix_world.to_3x3())[:, 2]  # a Sun shines along its −Z
    outward = -towards_sun * (1.0, 1.0, 0.0) / np.hypot(*towards_sun[:2])
    tube = outward * sample_scenes.TORUS_MAJOR_RADIUS + (0.0, 0.0, sample_scenes.TORUS_HEIGHT)
    middle = SUZANNE_SCALE * SUZANNE_MIDDLE
    shadow = tube - towards_sun * (tube[2] - middle) / towards_sun[2]
    edge = shadow + outward * sample_scenes.TORUS_MINOR_RADIUS * 1.2
    face = math.atan2(outward[1], outward[0]) + math.pi / 2  # her depth, not her ears, along the shadow's width
    return [("torus shadow", (shadow[0], shadow[1], 0.02), (0.0, 0.0, face + 0.3)),
            ("shadow edge", (edge[0], edge[1], 0.02), (0.0, 0.0, face - 0.5))]


def demo_room(resolution):
    """The demo room, its SH lights, a probe volume over it and a dynamic Suzanne; (Suzanne, the volume)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    objects = sample_scenes.build_demo_scene()
    add_lights(bpy.context.scene, objects["sun"])
    suzanne = sample_scenes.suzanne_object("Suzanne")
    suzanne.scale = (SUZANNE_SCALE,) * 3
    suzanne.data.materials.append(objects["floor"].data.materials[0])
    suzanne.prt_dynamic = True
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    half = sample_scenes.ROOM_SIZE / 2
    volume.location = (0.0, 0.0, sample_scenes.WALL_HEIGHT / 2)
    volume.scale = (half, half, sample_scenes.WALL_HEIGHT / 2)
    volume.empty_display_size = 1.0
    volume.prt_probe_resolution = resolution
    placements = PLACEMENTS[:1] + shadow_placements(objects["sun"]) + PLACEMENTS[1:]
    return suzanne, volume, placements


def place(ob, placement):
    _, location, turn = placement
    ob.location, ob.rotation_euler = location, turn
    bpy.context.view_layer.update()


def bake_probes(volume, resolution, settings):
    """Bakes the probes (with the floor, the cheapest static receiver); seconds of the probes' phase."""
    volume.prt_probe_resolution = resolution
    job = SceneBake(bpy.context, settings, ["Floor"])
    job.run(log=log)
    return job.summary.phases_s["probe_volumes_s"]


def stale_copy(suzanne, volume, settings):
    """Suzanne copied, static, baked where she stands with the scene (the probes hidden, so not rebaked with her),
    then hidden: her stored transfer is the stale bake that moving a static object leaves."""
    copy = suzanne.copy()
    copy.data = suzanne.data.copy()
    copy.name = copy.data.name = "Suzanne static"
    copy.prt_dynamic = False
    bpy.context.collection.objects.link(copy)
    volume.hide_set(True)
    SceneBake(bpy.context, settings, [copy.name]).run(log=log)
    volume.hide_set(False)
    copy.hide_set(True)
    copy.hide_render = True
    return copy


def accuracy(args):
    resolutions = QUICK_RESOLUTIONS if args.quick else RESOLUTIONS
    samples = 64 if args.quick else SAMPLES
    suzanne, volume, placements = demo_room(resolutions[0])
    settings = bake.BakeSettings(order=args.order, mode=args.mode, samples=samples)
    SceneBake(bpy.context, settings, [suzanne.name]).run(log=log)  # her self-transfer, in her frame, once
    place(suzanne, placements[0])
    copy = stale_copy(suzanne, volume, settings)
    bake_s = {resolutions[0]: bake_probes(volume, resolutions[0], settings)}  # Cycles sees a lit volume
    checks, stale = [], []
    start = time.perf_counter()
    for placement in placements:
        place(suzanne, placement)
        check = validation.Validation(bpy.context, args.samples, args.passes, [suzanne.name])
        check.run(log=log)
        checks.append(check)
        transfer, _ = storage.read_transfer(copy.data)
        colours = validation.prt_colours(transfer, check.lights[args.order], check.albedos[suzanne])
        stale.append(compare("stale", colours, np.stack(check.cycles.radiance[suzanne.name])))
    cycles_s = time.perf_counter() - start
    rows = {}
    for resolution in resolutions:
        if resolution not in bake_s:
            bake_s[resolution] = bake_probes(volume, resolution, settings)
        errors = []
        for placement, check in zip(placements, checks):
            place(suzanne, placement)
            errors.append(check.comparisons()[0])
        rows[resolution] = (bake_s[resolution], errors)
    vertices = len(suzanne.data.vertices)
    print(f"Suzanne ({vertices:,} vertices, dynamic, lit per vertex) in the demo room, order {args.order}, "
          f"{args.mode}; Cycles {args.passes} × {args.samples} samples per placement ({cycles_s:.0f} s for all); "
          f"% RMS against Cycles, its noise taken out")
    names = [name for name, _, _ in placements]
    print(f"{'probes':>14} {'spacing':>8} {'bake':>7} " + " ".join(f"{name:>13}" for name in names) + f" {'worst':>7}")
    for resolution, (bake_s, errors) in rows.items():
        spacing = sample_scenes.ROOM_SIZE / resolution[0]
        cells = " ".join(f"{100 * c.error:>12.2f}%" for c in errors)
        print(f"{'×'.join(map(str, resolution)):>9} {math.prod(resolution):>4} {spacing:>7.2f}m {bake_s:>6.1f}s "
              f"{cells} {100 * max(c.error for c in errors):>6.2f}%")
    print(f"{'baked static at ' + names[0] + ', moved (stale)':>39} "
          + " ".join(f"{100 * c.error:>12.2f}%" for c in stale))
    finest = max(c.error for c in rows[resolutions[-1]][1])
    judged = (f"goal <= {100 * GOAL_RMS:.0f} %   {result_files.verdict(finest, '<=', GOAL_RMS)}"
              if args.mode == "shadowed" else "(the goal is judged on shadowed bakes: see goals())")
    print(f"worst placement at the finest spacing: {100 * finest:.2f} % RMS   {judged}")
    return {"vertices": vertices, "mode": args.mode, "placements": names, "finest_worst": finest,
            "stale": [c.error for c in stale],
            "by_resolution": {"x".join(map(str, r)): {"bake_s": b, "errors": [c.error for c in e]}
                              for r, (b, e) in rows.items()}}


class RadianceClock:
    """Wraps the per-vertex colour write the handler calls, noting when it returns, and the main thread's CPU time
    then (the handler runs on it)."""

    def __init__(self):
        self.written_at = self.written_cpu = None
        self._write = display.write_radiance

    def __enter__(self):
        def timed_write(*args):
            self._write(*args)
            self.written_at, self.written_cpu = time.perf_counter(), time.thread_time()
        display.write_radiance = timed_write
        return self

    def __exit__(self, *exc):
        display.write_radiance = self._write


def live_scene(probes, sphere, order):
    """A floor, a probe volume of `probes` over it, baked, and a dynamic UV sphere baked (unshadowed: the timing does
    not depend on the transfer's values); the sphere."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_plane_add(size=8.0)
    bpy.ops.prt.add_probe_volume()
    volume = bpy.context.object
    volume.location, volume.scale, volume.prt_probe_resolution = (0.0, 0.0, 2.0), (4.0, 4.0, 2.0), probes
    bpy.ops.mesh.primitive_uv_sphere_add(segments=sphere[0], ring_count=sphere[1], radius=0.8, location=(0, 0, 1))
    ob = bpy.context.object
    bpy.ops.object.shade_smooth()  # one shading point per vertex (flat, every face corner would be one)
    ob.prt_dynamic = True
    SceneBake(bpy.context, bake.BakeSettings(order=order, mode="shadowed", samples=64), ["Plane"]).run(log=log)
    SceneBake(bpy.context, bake.BakeSettings(order=order, mode="unshadowed"), [ob.name]).run(log=log)
    bpy.context.scene.prt_display.show_prt = True
    return ob, volume


def live(args):
    ob, volume = live_scene(QUICK_LIVE_PROBES if args.quick else LIVE_PROBES,
                            QUICK_LIVE_SPHERE if args.quick else LIVE_SPHERE, args.order)
    scene = bpy.context.scene
    samples = {"one": [], "eight": [], "full": [], "one_cpu": [], "eight_cpu": []}
    with RadianceClock() as clock:
        for step in range(args.steps):
            theta = 0.2 + 1.2 * ((step * 0.37) % 1.0)
            for count, name in ((1, "one"), (LIGHTS, "eight")):
                set_light_count(scene, count)
                ob.location = (2.5 * math.cos(0.3 * step), 2.5 * math.sin(0.3 * step), 1.0 + 0.4 * math.sin(step))
                ob.rotation_euler = (0.2 * step, 0.0, 0.5 * step)
                start_cpu = time.thread_time()
                written, full = timed_update(scene.prt_lights[:1], theta + 0.1 * len(name), clock)
                samples[name].append(written)
                samples[name + "_cpu"].append(clock.written_cpu - start_cpu)
                if count == 1:
                    samples["full"].append(full)
    ms = {name: 1000 * statistics.median(values) for name, values in samples.items()}
    one, full, cpu = ms["one"], ms["full"], ms["one_cpu"]
    ratio = statistics.median(e / o for e, o in zip(samples["eight_cpu"], samples["one_cpu"]))
    wall_ratio = statistics.median(e / o for e, o in zip(samples["eight"], samples["one"]))
    parts = update_parts(ob, volume, args.steps, args.order)
    probes = math.prod(QUICK_LIVE_PROBES if args.quick else LIVE_PROBES)
    print(f"live: {probes:,} probes, a dynamic sphere of {len(ob.data.vertices):,} vertices moving and turning every "
          f"update, order {args.order}, median of {args.steps} updates")
    print(f"  light change + move to colours written, main thread's CPU time: 1 light {cpu:.1f} ms, 8 lights (one "
          f"moving) {ms['eight_cpu']:.1f} ms; wall time {one:.1f} ms and {ms['eight']:.1f} ms (ratio "
          f"{wall_ratio:.2f}), whole view_layer.update() {full:.1f} ms, at load average {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores")
    print(f"  parts (CPU time): the probes' product {parts['probes']:.1f} ms, per-vertex shading {parts['shade']:.1f} "
          f"ms, colour write {parts['write']:.1f} ms")
    print(f"per update at {len(ob.data.vertices):,} vertices and {probes:,} probes: {cpu:.1f} ms   goal <= "
          f"{GOAL_MS:.0f} ms   {result_files.verdict(cpu, '<=', GOAL_MS)}")
    print(f"8 lights ÷ 1 light (one moving): {ratio:.2f}   goal <= {GOAL_RATIO}   "
          f"{result_files.verdict(ratio, '<=', GOAL_RATIO)}")
    return {"vertices": len(ob.data.vertices), "probes": probes, "cpu_ms": cpu, "wall_ms": one, "ratio": ratio,
            "wall_ratio": wall_ratio, "full_ms": full, "parts_cpu_ms": parts}


def update_parts(ob, volume, steps, order) -> dict:
    """Median CPU ms of the parts of an update, timed apart: the probes' lights for a new light, the per-vertex shading
    from them, and the colour write."""
    stored = probe_volumes.read(volume)
    baked = layouts.stored(ob.data).read(ob.data)
    points = baked.layout.points(ob.data, baked)
    found = {"probes": [], "shade": [], "write": []}
    for step in range(steps):
        light = np.random.default_rng(step).standard_normal((3, order * order))
        start = time.thread_time()
        probe_volumes.lights(stored, light)
        found["probes"].append(time.thread_time() - start)
        start = time.thread_time()
        radiance = dynamic_radiance(ob, ob, baked, points, light, [stored])
        found["shade"].append(time.thread_time() - start)
        start = time.thread_time()
        display.write_radiance(ob.data, radiance, baked.corner_points)
        found["write"].append(time.thread_time() - start)
    return {name: 1000 * statistics.median(values) for name, values in found.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, help="Cycles samples per pass (default 64; --quick 4)")
    parser.add_argument("--passes", type=int, help="Cycles passes (default 4; --quick 2)")
    parser.add_argument("--steps", type=int, help="timed live updates per configuration (default 30; --quick 3)")
    result_files.add_argument(parser)
    parser.add_argument("--only", choices=("accuracy", "live"), help="run one part alone")
    parser.add_argument("--order", type=int, default=ORDER, help=f"SH order of every bake (default {ORDER})")
    parser.add_argument("--mode", choices=("shadowed", "interreflected"), default="shadowed",
                        help="the accuracy part's bakes: direct light (default), or with bounces")
    parser.add_argument("--quick", action="store_true", help="a smoke run on coarse probes and small objects")
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    args.samples = args.samples or (4 if args.quick else 64)
    args.passes = args.passes or (2 if args.quick else 4)
    args.steps = args.steps or (3 if args.quick else 30)
    prt_addon.register()
    print(f"probes benchmark: bpy {bpy.app.version_string}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f}")
    results = {part: run(args) for part, run in (("accuracy", accuracy), ("live", live))
               if args.only in (None, part)}
    prt_addon.unregister()
    if args.json:
        result_files.write("probes", args, results, goals(results), argv)
    return 0


def goals(results: dict) -> list:
    """The goals of the parts this run measured, as benchmarks/results.py records them."""
    found = []
    # Interreflected, a dynamic object near a surface gets its bounce without its own shadow on it (it casts none
    # on the static scene): its figures are recorded, and judged apart.
    if results.get("accuracy", {}).get("mode") == "shadowed":
        found.append(result_files.goal("worst placement at the finest probe spacing, RMS against Cycles",
                                       100 * results["accuracy"]["finest_worst"], "<=", 100 * GOAL_RMS, "%"))
    if "live" in results:
        live = results["live"]
        found.append(result_files.goal(f"light change to colours, {live['probes']:,} probes, {live['vertices']:,} "
                                       "vertices moving (CPU)", live["cpu_ms"], "<=", GOAL_MS, "ms"))
        found.append(result_files.goal("8 lights ÷ 1 light, probes", live["ratio"], "<=", GOAL_RATIO))
    return found


if __name__ == "__main__":
    sys.exit(main())
