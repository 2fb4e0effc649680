"""Texel storage: what it costs and what it buys.

    .venv/bin/python benchmarks/texels.py [--part room|image|all] [--workers 2] [--resolution 1024]

room: the demo scene's floor and walls stored per texel at 1024 × 1024 (their own UV map), shadowed, order 4, to a
1 % target error (256 samples, up to 4096): the bake's time (goal ≤ 60 s on 2 cores), its texels baked and
interpolated per lattice, and its actual error against a reference: 1000 random covered texels per object baked
alone at 8192 samples, RMS over them of ‖T − T_ref‖ ÷ ‖T_unshadowed‖ (the bake's own measure), the reference's
noise taken out.

image: a sphere over a one-quad floor and over a 16 × 16 floor, baked with Storage Auto, Vertex and Texel (every
object, resolution from the target error), each compared with Cycles from a camera (`prt validate --image`, 160 × 120, 2 × 64 samples): the image RMS error
(goal ≤ 2 % with Auto) beside the vertex figure, to show what texels bought.
"""

import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402  (before mathutils, which the core uses)
import numpy as np  # noqa: E402

import prt_addon  # noqa: E402
from prt_addon.blender import sample_scenes, texel_maps  # noqa: E402
from prt_addon.blender.image_validation import validate_image  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.blender.texel_bake import TexelSurface  # noqa: E402
from prt_addon.core import bake, job, lobes  # noqa: E402

ROOM_GOAL_S = 60.0
IMAGE_GOAL = 0.02
REFERENCE_TEXELS = 1000
REFERENCE_SAMPLES = 8192
ROOM_TEXELS = ("Floor", "BackWall", "LeftWall")


def room(resolution, workers):
    bpy.ops.wm.read_homefile(use_empty=True)
    sample_scenes.build_demo_scene()
    settings = bake.BakeSettings(order=4, samples=256, target_error=0.01, max_samples=4096)
    for name in ROOM_TEXELS:
        ob = bpy.data.objects[name]
        ob.prt_storage, ob.prt_resolution, ob.prt_uv_map = "texel", resolution, sample_scenes.UV_MAP
    start = time.perf_counter()
    scene_bake = SceneBake(bpy.context, settings, workers=workers)
    summary = scene_bake.run()
    seconds = time.perf_counter() - start
    print(summary.line())
    print(f"texel lattices: {scene_bake.levels.lattice_line()}")
    texels = sum(len(s.layout.texels) for s in scene_bake.surfaces.receivers if isinstance(s, TexelSurface))
    verdict = "PASS" if seconds <= ROOM_GOAL_S else "MISS"
    print(f"room: floor and walls at {resolution} × {resolution} ({texels:,} covered texels) + torus per vertex, "
          f"1 % target, {workers} workers: {seconds:.1f} s (gathering and checks included)   goal <= "
          f"{ROOM_GOAL_S:.0f} s   {verdict}")
    actual, reference_noise = actual_error(scene_bake, settings, workers)
    estimates = [summary.per_object[name]["est_rms_rel_error"] for name in ROOM_TEXELS]
    print(f"room: actual RMS rel. error of the texel maps against the reference ({REFERENCE_TEXELS} texels per object "
          f"at {REFERENCE_SAMPLES} samples, its own noise {reference_noise:.4f} taken out): {actual:.4f}; the bake "
          f"estimated {math.sqrt(np.mean(np.square(estimates))):.4f} for them (RMS of the objects' estimates)")


def actual_error(scene_bake, settings, workers):
    """(RMS over random texels of the stored map against a high-sample bake of the same points, the reference's
    own RMS noise), both relative to the unshadowed transfer's norm."""
    rng = np.random.default_rng(7)
    receivers, stored = [], []
    for ob, surface in zip(scene_bake.objects, scene_bake.surfaces.receivers):
        if not isinstance(surface, TexelSurface):
            continue
        rows = rng.choice(len(surface.layout.texels), size=min(REFERENCE_TEXELS, len(surface.layout.texels)),
                          replace=False)
        point = surface.receiver
        receivers.append(bake.Receiver(ob.name, point.positions[rows], point.normals[rows],
                                       bake.Receiver.key_for(ob.name + " reference"), point.inward[rows]))
        planes, _ = texel_maps.read_planes(ob.data)
        stored.append(planes[:, surface.layout.texels[rows]].T)
    reference_settings = bake.BakeSettings(order=settings.order, samples=REFERENCE_SAMPLES, seed=settings.seed + 1)
    results = job.TransferJob(receivers, scene_bake.job.occluders, reference_settings, workers,
                              scene_bake.job.worker_command).run()
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


def image(workers):
    for cuts, label in ((1, "one-quad floor"), (16, "16 × 16 floor")):
        errors = {}
        for storage in ("vertex", "auto", "texel"):
            sphere_over_floor(cuts)
            scene_bake = SceneBake(bpy.context, bake.BakeSettings(order=4, samples=256), ["Floor", "Ball"],
                                   workers=workers, storage_options={"storage": storage})
            summary = scene_bake.run()
            report = validate_image(bpy.context, samples=64, passes=2, resolution=(160, 120))
            errors[storage] = report.comparison
            chosen = "; ".join(scene_bake.storage_decisions) or "every object per vertex"
            print(f"image: sphere over a {label}, Storage {storage.title()}: bake {summary.time_s:.1f} s; {chosen}")
            print(f"  {report.line()}")
        auto, vertex, texel = errors["auto"], errors["vertex"], errors["texel"]
        verdict = "PASS" if auto.error <= IMAGE_GOAL else "MISS"
        print(f"image: sphere over a {label}: image RMS error {100 * auto.error:.2f} % with Auto (p99 "
              f"{100 * auto.p99:.1f} %) against {100 * vertex.error:.2f} % per vertex (p99 {100 * vertex.p99:.1f} %)"
              f" and {100 * texel.error:.2f} % with every object per texel (p99 {100 * texel.p99:.1f} %)   goal <= "
              f"{100 * IMAGE_GOAL:.0f} %   {verdict}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("room", "image", "all"), default="all")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--resolution", type=int, default=1024, help="room: texels along each side")
    args = parser.parse_args(argv)
    prt_addon.register()
    print(f"texel benchmark: bpy {bpy.app.version_string}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.2f}")
    try:
        if args.part in ("room", "all"):
            room(args.resolution, args.workers)
        if args.part in ("image", "all"):
            image(args.workers)
    finally:
        prt_addon.unregister()
    return 0


if __name__ == "__main__":
    sys.exit(main())
