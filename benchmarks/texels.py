"""Texel storage: what it costs and what it buys.

    .venv/bin/python benchmarks/texels.py [--part room|image|all] [--workers 2] [--resolution 1024] [--quick]
                                          [--json [DIR]]

room: the demo scene's floor and walls stored per texel at 1024 × 1024 (their own UV map), shadowed, order 4, to a
1 % target error (256 samples, up to 4096): the bake's time (goal ≤ 60 s on 2 cores), its texels baked and
interpolated per lattice, and its actual error against a reference: 1000 random covered texels per object baked
alone at 8192 samples, RMS over them of ‖T − T_ref‖ ÷ ‖T_unshadowed‖ (the bake's own measure), the reference's
noise taken out.

image: a sphere over a one-quad floor and over a 16 × 16 floor, baked with Storage Auto, Vertex and Texel (every
object, resolution from the target error), each compared with Cycles from a camera (`prt validate --image`, 160 × 120, 2 × 64 samples): the image RMS error
(goal ≤ 2 % with Auto) beside the vertex figure, to show what texels bought.

--quick is a smoke run: the room at 64 × 64 to at most 64 samples against 100 texels per object at 1024, and the
image part with Storage Auto only (its texel maps 32 × 32) on the one-quad floor, baked at 64 samples, Cycles 2 × 8
samples at 40 × 30 (the goals are for the full run).
"""

import argparse
from dataclasses import dataclass, replace
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402  (before mathutils, which the core uses)
import numpy as np  # noqa: E402

from benchmarks import results as result_files  # noqa: E402

import prt_addon  # noqa: E402
from prt_addon.blender import sample_scenes, texel_maps  # noqa: E402
from prt_addon.blender.image_validation import validate_image  # noqa: E402
from prt_addon.blender.layouts import PerTexel  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.core import bake, job, lobes  # noqa: E402

ROOM_GOAL_S = 60.0
ROOM_GOAL_ERROR = 0.01  # the room's target: the maps' actual error must meet it
IMAGE_GOAL = 0.02
ROOM_TEXELS = ("Floor", "BackWall", "LeftWall")


@dataclass(frozen=True)
class Sizes:
    resolution: int         # room: texels along each side
    room_samples: int       # room: first round of the 1 % target bake
    room_max_samples: int   # room: its ray budget per point
    reference_texels: int   # room: random texels per object in the reference
    reference_samples: int  # room: the reference's rays per texel
    floor_cuts: tuple       # image: the floors under the sphere (quads per side)
    image_samples: int      # image: bake samples
    cycles_samples: int     # image: Cycles samples per pass
    cycles_passes: int
    image_resolution: tuple
    image_texels: int       # image: texels along each side of a map stored per texel (0: from the target error)
    storages: tuple         # image: the Storage settings compared (the goal is Auto's)


FULL = Sizes(1024, 256, 4096, 1000, 8192, (1, 16), 256, 64, 2, (160, 120), 0, ("vertex", "auto", "texel"))
QUICK = Sizes(64, 32, 64, 100, 1024, (1,), 64, 8, 2, (40, 30), 32, ("auto",))


def room_scene(sizes: Sizes) -> bake.BakeSettings:
    """A fresh file with the demo scene, its floor and walls stored per texel at the sizes' resolution; the room's
    bake settings (order 4, shadowed, to a 1 % target)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sample_scenes.build_demo_scene()
    for name in ROOM_TEXELS:
        ob = bpy.data.objects[name]
        ob.prt_storage, ob.prt_resolution, ob.prt_uv_map = "texel", sizes.resolution, sample_scenes.UV_MAP
    return bake.BakeSettings(order=4, samples=sizes.room_samples, target_error=0.01,
                             max_samples=sizes.room_max_samples)


def room(sizes: Sizes, workers, goals: list) -> dict:
    """The room's figures; its time goal appended to `goals`."""
    settings = room_scene(sizes)
    resolution = sizes.resolution
    start = time.perf_counter()
    scene_bake = SceneBake(bpy.context, settings, workers=workers)
    summary = scene_bake.run()
    seconds = time.perf_counter() - start
    print(summary.line())
    print(f"texel lattices: {scene_bake.results.lattices}")
    texels = sum(len(s.layout.texels) for s in scene_bake.results.layouts if isinstance(s, PerTexel))
    goals.append(result_files.goal(f"texel room at {resolution}², {workers} workers, wall time", seconds, "<=",
                                   ROOM_GOAL_S, "s"))
    print(f"room: floor and walls at {resolution} × {resolution} ({texels:,} covered texels) + torus per vertex, "
          f"1 % target, {workers} workers: {seconds:.1f} s (gathering and checks included)   goal <= "
          f"{ROOM_GOAL_S:.0f} s   {goals[-1]['verdict']}")
    actual, reference_noise = actual_error(scene_bake, settings, workers, sizes)
    estimates = [summary.per_object[name]["est_rms_rel_error"] for name in ROOM_TEXELS]
    goals.append(result_files.goal("texel room, the maps' actual RMS rel. error", actual, "<=", ROOM_GOAL_ERROR))
    print(f"room: actual RMS rel. error of the texel maps against the reference ({sizes.reference_texels} texels per "
          f"object at {sizes.reference_samples} samples, its own noise {reference_noise:.4f} taken out): {actual:.4f}; the bake "
          f"estimated {math.sqrt(np.mean(np.square(estimates))):.4f} for them (RMS of the objects' estimates)   "
          f"goal <= {ROOM_GOAL_ERROR:g}   {goals[-1]['verdict']}")
    return {"seconds": seconds, "texels": texels, "actual_rms_rel_error": actual, "reference_noise": reference_noise,
            "estimates": estimates}


def actual_error(scene_bake, settings, workers, sizes: Sizes):
    """(RMS over random texels of the stored map against a high-sample bake of the same points, the reference's
    own RMS noise), both relative to the unshadowed transfer's norm."""
    rng = np.random.default_rng(7)
    receivers, stored = [], []
    for ob, surface in zip(scene_bake.objects, scene_bake.results.layouts):
        if not isinstance(surface, PerTexel):
            continue
        rows = rng.choice(len(surface.layout.texels), size=min(sizes.reference_texels, len(surface.layout.texels)),
                          replace=False)
        point = surface.receiver
        receivers.append(bake.Receiver(ob.name, point.positions[rows], point.normals[rows],
                                       bake.Receiver.key_for(ob.name + " reference"), point.inward[rows]))
        planes, _ = texel_maps.read_planes(ob.data)
        stored.append(planes[:, surface.layout.texels[rows]].T)
    reference_settings = bake.BakeSettings(order=settings.order, samples=sizes.reference_samples,
                                           seed=settings.seed + 1)
    results = job.TransferJob(receivers, scene_bake.plan.occluders, reference_settings, scene_bake.executor).run()
    scale = lobes.unshadowed_norm(settings.order)
    difference = np.concatenate([np.linalg.norm(s - r.transfer, axis=1) for s, r in zip(stored, results)]) / scale
    noise = np.concatenate([r.rel_error for r in results])
    measured = math.sqrt(np.mean(difference ** 2))
    reference_noise = math.sqrt(np.mean(noise ** 2))
    return math.sqrt(max(measured ** 2 - reference_noise ** 2, 0.0)), reference_noise


def sphere_over_floor(cuts):
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=cuts, y_subdivisions=cuts, size=4)
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0, 0, 0.8))
    bpy.context.object.name = "Ball"
    bpy.context.object.data.shade_smooth()
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(camera)
    camera.location, camera.rotation_euler = (0.0, -5.0, 4.0), (0.9, 0.0, 0.0)
    bpy.context.scene.camera = camera


def image(sizes: Sizes, workers, goals: list) -> dict:
    """Each scene's image errors by Storage; Auto's goal for each appended to `goals`."""
    found = {}
    for cuts in sizes.floor_cuts:
        label = "one-quad floor" if cuts == 1 else f"{cuts} × {cuts} floor"
        errors = {}
        for storage in sizes.storages:
            sphere_over_floor(cuts)
            scene_bake = SceneBake(bpy.context, bake.BakeSettings(order=4, samples=sizes.image_samples),
                                   ["Floor", "Ball"], workers=workers,
                                   storage_options={"storage": storage, "resolution": sizes.image_texels})
            summary = scene_bake.run()
            report = validate_image(bpy.context, samples=sizes.cycles_samples, passes=sizes.cycles_passes,
                                    resolution=sizes.image_resolution)
            errors[storage] = report.comparison
            chosen = "; ".join(scene_bake.report().storage) or "every object per vertex"
            print(f"image: sphere over a {label}, Storage {storage.title()}: bake {summary.time_s:.1f} s; {chosen}")
            print(f"  {report.line()}")
        auto = errors["auto"]
        found[label] = {storage: {"rms": c.error, "p99": c.p99} for storage, c in errors.items()}
        goals.append(result_files.goal(f"image RMS with Auto, sphere over a {label}", 100 * auto.error, "<=",
                                       100 * IMAGE_GOAL, "%"))
        others = " and".join(f" {100 * errors[storage].error:.2f} % {what} (p99 {100 * errors[storage].p99:.1f} %)"
                             for storage, what in (("vertex", "per vertex"), ("texel", "with every object per texel"))
                             if storage in errors)
        print(f"image: sphere over a {label}: image RMS error {100 * auto.error:.2f} % with Auto (p99 "
              f"{100 * auto.p99:.1f} %){' against' + others if others else ''}   goal <= "
              f"{100 * IMAGE_GOAL:.0f} %   {goals[-1]['verdict']}")
    return found


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("room", "image", "all"), default="all")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--resolution", type=int, help="room: texels along each side (default 1024; --quick 64)")
    parser.add_argument("--quick", action="store_true", help="a smoke run: small sizes, the goals are for the full run")
    result_files.add_argument(parser)
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    sizes = QUICK if args.quick else FULL
    if args.resolution:
        sizes = replace(sizes, resolution=args.resolution)
    prt_addon.register()
    print(f"texel benchmark{' (quick: the goals are for the full run)' if args.quick else ''}: bpy "
          f"{bpy.app.version_string}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    figures, goals = {}, []
    try:
        if args.part in ("room", "all"):
            figures["room"] = room(sizes, args.workers, goals)
        if args.part in ("image", "all"):
            figures["image"] = image(sizes, args.workers, goals)
    finally:
        prt_addon.unregister()
    if args.json:
        result_files.write("texels", args, figures, goals, argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
