"""What vertex storage loses between vertices (issue 14, item 1): the bake's estimate `est_interp_rms_rel_error`
against the loss measured independently, by dense quadrature over every triangle."""

import bpy
import numpy as np

from prt_addon.blender import geometry, storage
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, interpolation, job, lobes
from prt_addon.core.bake import BakeSettings


def triangle_quadrature(resolution=12):
    """Barycentric points of a regular grid inside a triangle (equal weights)."""
    points = [(i, j) for i in range(resolution) for j in range(resolution - i)]
    u, v = (np.array(c, dtype=float) for c in zip(*points))
    u, v = (u + 1 / 3) / resolution, (v + 1 / 3) / resolution
    return np.stack([1 - u - v, u, v], axis=1)


def measured_loss(surface, transfer_at, transfer, scale):
    """Area-weighted RMS over the surface of |T(x) − Σ w T(corners)| ÷ scale, at grid points in every triangle."""
    weights = triangle_quadrature()
    squared, areas = [], []
    positions, normals = surface.receiver.positions, surface.receiver.normals
    for triangle in surface.triangles:
        corners = positions[triangle]
        area = 0.5 * np.linalg.norm(np.cross(corners[1] - corners[0], corners[2] - corners[0]))
        if area == 0:
            continue
        points, blended = weights @ corners, weights @ normals[triangle]
        blended /= np.linalg.norm(blended, axis=1, keepdims=True)
        difference = transfer_at(points, blended) - weights @ transfer[triangle]
        squared.append(np.mean(np.sum(difference ** 2, axis=1)))
        areas.append(area)
    return float(np.sqrt(np.average(squared, weights=areas))) / scale


def test_an_unshadowed_coarse_sphere_reports_the_loss_quadrature_measures(empty_scene):
    """Unshadowed transfer is exact in closed form at any point, so the only loss is interpolation: the cosine lobe
    of the interpolated normal against the interpolation of the corners' lobes. The probes' estimate (64 random
    points) agrees with a 78-point-per-triangle quadrature within 25 %."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=4)
    sphere = bpy.context.active_object
    sphere.data.shade_smooth()
    scene_bake = SceneBake(bpy.context, BakeSettings(mode="unshadowed", order=4), ["Sphere"])
    summary = scene_bake.run()
    surface = geometry.surface_from_object(sphere, bpy.context.evaluated_depsgraph_get(), [])
    transfer, meta = storage.read_transfer(sphere.data)
    truth = measured_loss(surface, lambda points, normals: lobes.unshadowed_transfer(4, normals), transfer,
                          lobes.unshadowed_norm(4))
    assert truth > 0.02  # teeth: the coarse sphere loses far more than the tolerance below
    assert abs(summary.est_interp_rms_rel_error - truth) <= 0.25 * truth, (summary.est_interp_rms_rel_error, truth)
    assert summary.interp_points == interpolation.FEWEST_PROBES and summary.interp_rays == 0
    assert meta["est_interp_rms_rel_error"] == summary.per_object["Sphere"]["est_interp_rms_rel_error"]
    assert "between vertices est. RMS" in summary.line()


def test_a_one_quad_floor_under_a_box_reports_the_shadow_its_vertices_miss(empty_scene):
    """A floor of one quad under a box: its four corners see the sky, so stored per vertex it shows no shadow at
    all, while the noise estimate at the vertices is about 1 %. The interpolation estimate must report the loss, and
    agree within 1.5 × with the loss measured by baking the quadrature points themselves (256 rays each)."""
    bpy.ops.mesh.primitive_plane_add(size=4)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 1.0))
    bpy.ops.object.select_all(action="DESELECT")
    scene_bake = SceneBake(bpy.context, BakeSettings(order=3, samples=256), ["Plane"])
    summary = scene_bake.run()
    floor = bpy.data.objects["Plane"]
    surface = geometry.surface_from_object(floor, bpy.context.evaluated_depsgraph_get(), [])
    transfer, _ = storage.read_transfer(floor.data)
    occluders = scene_bake.plan.occluders

    def baked_at(points, normals):
        receiver = bake.Receiver("quadrature", points, normals, 5)
        return job.TransferJob([receiver], occluders, BakeSettings(order=3, samples=256)).run()[0].transfer

    truth = measured_loss(surface, baked_at, transfer, lobes.unshadowed_norm(3))
    assert summary.est_rms_rel_error < 0.02 and truth > 0.1  # the vertices are right; between them, the shadow
    assert 1 / 1.5 <= summary.est_interp_rms_rel_error / truth <= 1.5, (summary.est_interp_rms_rel_error, truth)
