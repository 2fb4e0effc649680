"""Checks before any ray of the bake, on its plan (blender.plan): where the bake will be saved, what it will cost
(core.checks grades memory and time from the plan's sizes), and what is wrong with its objects. The bake operator,
the panel's Check button and `prt bake` all run these, so they find the same things; they write nothing and cast no
ray."""

import os
import tempfile

import bpy
import numpy as np

from ..core import checks, probe_transfer
from ..core.checks import ERROR, INFO, WARNING, Check
from . import geometry
from .execute import first_job
from .fault_checks import fault_checks

# Modifiers that move vertices (a pose, a simulation, a procedural deformation): a dynamic object follows rigid motion
# only. Geometry Nodes count, since they may deform.
DEFORMING = {"ARMATURE", "CAST", "CLOTH", "CORRECTIVE_SMOOTH", "CURVE", "DISPLACE", "EXPLODE", "HOOK",
             "LAPLACIANDEFORM", "LAPLACIANSMOOTH", "LATTICE", "MESH_CACHE", "MESH_DEFORM", "MESH_SEQUENCE_CACHE",
             "NODES", "OCEAN", "SHRINKWRAP", "SIMPLE_DEFORM", "SMOOTH", "SOFT_BODY", "SURFACE_DEFORM",
             "VOLUME_DISPLACE", "WARP", "WAVE"}


def output_check(output: str | None, required: bool) -> Check:
    """Where the bake will be saved: `output`, else the open file. On the command line saving is part of the
    bake (`required`: a problem is an error); in the interface it is the artist's next save (a warning)."""
    path = output or bpy.data.filepath
    if path:
        return checks.writable_check(path, "output", required)
    if required:
        return Check(ERROR, "output", "the scene has no file to save over; give --output")
    return Check(INFO, "output", "the file is not saved yet: the bake stays in memory until you save it")


def all_checks(context, plan, executor, output: str | None, required: bool) -> list[Check]:
    return [output_check(output, required)] + scene_checks(context, plan, executor)


def scene_checks(context, plan, executor) -> list[Check]:
    """Workers, memory, time, then each object's problems, then what the plan found (objects not baked, notes), for
    the plan (blender.plan) baked by `executor` (core.executors). The bake's first jobs are made to size it, not run;
    the time is estimated from their rays at the ray engine's typical rate (core.engines.RATES)."""
    settings = plan.settings
    sizes = bake_sizes(plan, executor)
    parallel = min(sizes[0].processes, os.cpu_count() or 1)
    seconds = sum(checks.estimated_seconds(size.rays, size.occluder_triangles, size.ray_engine,
                                           min(size.processes, os.cpu_count() or 1),
                                           executor.start_s if size.spawned else 0.0) for size in sizes)
    found = [checks.workers_check(sizes[0].processes, tempfile.gettempdir()),
             checks.memory_check(sizes, checks.available_memory()),
             checks.time_check(sum(size.rays for size in sizes), seconds, sizes[0].ray_engine, settings, parallel)]
    casts_rays = settings.mode != "unshadowed"
    receivers = [bpy.data.objects[(name, None)] for name in plan.names]
    others = ([ob for ob in geometry.visible_mesh_objects(context) if ob not in receivers] if casts_rays else [])
    for ob in receivers + others:
        found += object_checks(ob, receiver=ob in receivers, casts_rays=casts_rays)
    found += fault_checks(receivers, others)
    found += [Check(WARNING, "not baked", problem) for problem in plan.problems]
    found += [Check(INFO, "note", note) for note in plan.notes()]
    return found


def bake_sizes(plan, executor) -> list[checks.BakeSize]:
    """The plan's bake and each of its dynamic parts (blender.plan), which bake one after another, each against its
    own occluders: a dynamic object's rays against itself only."""
    sizes = []
    for part in [plan] + plan.parts:
        job = first_job(part, executor)
        sizes.append(bake_size(part, job, job.processes() > 1 and executor.spawned))
    return sizes


def bake_size(plan, job, spawned: bool) -> checks.BakeSize:
    """What the plan's bake holds, `job` its first job (blender.execute.first_job)."""
    layouts = plan.layouts()
    split = [len(layout.corner_points) for layout in layouts if layout.corner_points is not None]
    occluders, settings = job.occluders, plan.settings
    casts = occluders is not None and settings.mode != "unshadowed" and len(occluders.triangles) > 0
    channels = job.albedo[0].shape[1] if job.albedo else 1
    probes = sum(len(volume.positions) for volume in plan.request.probe_volumes)
    return checks.BakeSize(
        points=job.total_vertices,
        stored_rows=sum(layout.stored_rows() for layout in layouts),
        split_corners=sum(split),
        occluder_vertices=len(occluders.vertices) if occluders else 0,
        occluder_triangles=len(occluders.triangles) if occluders else 0,
        order=plan.settings.order,
        channels=channels,
        rays=(job.total_vertices + probes) * settings.samples if casts else 0,
        hits_per_ray=checks.HITS_PER_RAY if casts and settings.mode == "interreflected" else 0.0,
        processes=job.processes(), spawned=spawned, ray_engine=occluders.engine if occluders else "bvhtree",
        probe_values=probes * channels * probe_transfer.received_order(settings.order) ** 2 * settings.order ** 2)


def object_checks(ob, receiver: bool, casts_rays: bool) -> list[Check]:
    """A mirrored object (its faces' winding turned, which decides their front for contact and bounced light),
    and for receivers: hidden in renders, open or non-manifold edges (thin faces and the other faults of messy
    models are blender.fault_checks')."""
    found = []
    name = repr(ob.name)
    if casts_rays and ob.matrix_world.determinant() < 0:
        scale = (f"negative scale ({', '.join(f'{value:g}' for value in ob.scale)})" if min(ob.scale) < 0 else
                 "mirrored by a parent's negative scale")
        found.append(Check(WARNING, name, f"{scale}: contact and bounced light take its faces' backs for their "
                                          f"fronts; apply the scale (Object > Apply > Scale)"))
    if not receiver:
        return found
    if geometry.is_dynamic(ob):
        found += dynamic_checks(ob)
    if ob.hide_render:
        found.append(Check(WARNING, name, "hidden in renders (Disable in Renders): it is baked, but a render "
                                          "will not show it"))
    mesh = ob.data
    faces_per_edge = edge_face_counts(mesh)
    boundary, shared = int((faces_per_edge == 1).sum()), int((faces_per_edge > 2).sum())
    if boundary or shared:
        said = [f"{boundary} open boundary edges"] * bool(boundary) + [
            f"{shared} non-manifold edges (more than two faces)"] * bool(shared)
        found.append(Check(INFO, name, " and ".join(said) + ": rays may pass through the openings into the "
                                                             "inside (expected for floors, walls and cards)"))
    return found


def dynamic_checks(ob) -> list[Check]:
    """What a dynamic object's display cannot follow. Non-uniform scale (or shear) is an error: the transfer is
    baked for the unscaled shape and the display turns the light only, so it would be wrong at every angle, and
    its fingerprint leaves the transform out, so nothing would call it stale. A deforming modifier or shape keys
    are a warning: the bake holds the pose it was baked in, and a changed pose shows as stale (geometry changed)."""
    name, found = repr(ob.name), []
    axes = np.array(ob.matrix_world.to_3x3(), dtype=np.float64)
    gram = axes.T @ axes
    if np.abs(gram - np.trace(gram) / 3.0 * np.eye(3)).max() > 1e-4 * np.trace(gram) / 3.0:
        scale = ", ".join(f"{value:g}" for value in ob.matrix_world.to_scale())
        found.append(Check(ERROR, name, f"dynamic with non-uniform scale ({scale}): the display turns its light "
                                        f"but cannot stretch its shadows; apply the scale (Object > Apply > Scale) "
                                        f"or scale it uniformly"))
    deforming = [modifier.name for modifier in ob.modifiers if modifier.show_viewport and modifier.type in DEFORMING]
    deforming += ["shape keys"] * (ob.data.shape_keys is not None and len(ob.data.shape_keys.key_blocks) > 1)
    if deforming:
        found.append(Check(WARNING, name, f"dynamic and deformed ({', '.join(deforming)}): only rigid motion is "
                                          f"followed; the bake holds this pose, and another pose is stale"))
    return found


def edge_face_counts(mesh) -> np.ndarray:
    """How many faces use each edge."""
    edges = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("edge_index", edges)
    return np.bincount(edges, minlength=len(mesh.edges))
