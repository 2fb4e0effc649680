"""The sample scenes against the thesis's published demo scene and against geometry measured from the built
meshes themselves, never against the builder's own constants."""
import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from prt_addon.blender import sample_scenes as scenes

# The 2008 thesis's demo scene (SHBuilder, about 3 hours on a 2 GHz Pentium 4): "a torus of 10,800 vertices
# over surrounding planes of 2,700 vertices".
THESIS_TORUS_VERTICES = 10_800
THESIS_PLANE_VERTICES = 2_700
PLANE_ROLES = ("floor", "back_wall", "left_wall")


def build_fresh(build):
    bpy.ops.wm.read_homefile(use_empty=True)
    return build()


@pytest.fixture
def demo():
    return build_fresh(scenes.build_demo_scene)


@pytest.fixture
def suzanne_scene():
    return build_fresh(scenes.build_suzanne_scene)


def local_positions(mesh):
    positions = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", positions)
    return positions.reshape(-1, 3)


def world_positions(ob):
    matrix = np.array(ob.matrix_world)
    return local_positions(ob.data) @ matrix[:3, :3].T + matrix[:3, 3]


def corner_array(mesh, name):
    values = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get(name, values)
    return values


def fitted_torus(positions):
    """Centre, unit axis, major radius R and tube radius r of the torus through `positions`, measured from the
    points alone: the centre is their mean and the axis the direction of least spread (a torus is flat along
    its axis); in that frame (ρ − R)² + z² = r², that is ρ² + z² = 2R·ρ + (r² − R²), is linear in 2R and
    r² − R² and solved by least squares. Also returns each point's ρ and z."""
    centre = positions.mean(axis=0)
    offsets = positions - centre
    axis = np.linalg.eigh(np.cov(offsets.T))[1][:, 0]
    z = offsets @ axis
    rho = np.linalg.norm(offsets - np.outer(z, axis), axis=1)
    (twice_major, r_squared_minus), *_ = np.linalg.lstsq(np.column_stack([rho, np.ones_like(rho)]),
                                                         rho * rho + z * z, rcond=None)
    major = twice_major / 2
    return centre, axis, major, np.sqrt(r_squared_minus + major * major), rho, z


def base_color_image(material):
    """The image feeding the Principled BSDF's Base Color."""
    bsdf = next(node for node in material.node_tree.nodes if node.type == "BSDF_PRINCIPLED")
    link = bsdf.inputs["Base Color"].links[0]
    assert link.from_node.type == "TEX_IMAGE"
    return link.from_node.image


def test_torus_has_the_thesis_vertex_count_and_is_a_closed_quad_surface(demo):
    mesh = demo["torus"].data
    assert len(mesh.vertices) == THESIS_TORUS_VERTICES
    assert all(polygon.loop_total == 4 for polygon in mesh.polygons)
    # Closed and manifold: every edge between exactly two faces. Of genus one: V − E + F = 0, which for quads
    # (E = 2F) means as many faces as vertices.
    assert np.all(np.bincount(corner_array(mesh, "edge_index"), minlength=len(mesh.edges)) == 2)
    assert len(mesh.vertices) - len(mesh.edges) + len(mesh.polygons) == 0
    assert len(mesh.polygons) == len(mesh.vertices)


def test_scene_vertex_counts_match_the_thesis_demo(demo):
    """The bake's work is proportional to its vertex count, and comparing bake times with the thesis's needs
    the same work: the whole scene within 1 % of 10,800 + 2,700. The planes cannot hit 2,700 exactly (square
    cells on walls lower than the floor is wide), and the torus is exact, so they may differ by ±135 (5 %)."""
    planes = sum(len(demo[role].data.vertices) for role in PLANE_ROLES)
    meshes = sum(len(ob.data.vertices) for ob in bpy.context.scene.objects if ob.type == "MESH")
    assert meshes == len(demo["torus"].data.vertices) + planes  # no other geometry to bake
    thesis = THESIS_TORUS_VERTICES + THESIS_PLANE_VERTICES
    assert abs(meshes - thesis) <= 0.01 * thesis


def test_torus_vertices_lie_on_a_torus_whose_area_and_volume_its_faces_enclose(demo):
    mesh = demo["torus"].data
    positions = local_positions(mesh)
    centre, axis, major, minor, rho, z = fitted_torus(positions)
    assert 0.0 < minor < major  # a ring torus: it has a hole, and its tube does not cross the axis
    # Every vertex at distance r from the tube's centre circle, to float32 rounding of the coordinates.
    np.testing.assert_allclose(np.hypot(rho - major, z), minor, rtol=0, atol=1e-6 * (major + minor))
    # The faces, which the fit never saw, enclose the torus's area 4π²Rr and volume 2π²Rr². An inscribed
    # polyhedron falls short by O(step²): about 5e-4 of the area and 1.3e-3 of the volume at 3° × 4° steps.
    quads = corner_array(mesh, "vertex_index").reshape(-1, 4)
    a, b, c, d = (positions[quads[:, k]] - centre for k in range(4))
    area = 0.5 * np.linalg.norm(np.cross(c - a, d - b), axis=1).sum()
    volume = (np.einsum("ij,ij->i", a, np.cross(b, c)) + np.einsum("ij,ij->i", a, np.cross(c, d))).sum() / 6
    assert -2e-3 < area / (4 * np.pi**2 * major * minor) - 1 < 0
    assert -2e-3 < volume / (2 * np.pi**2 * major * minor**2) - 1 < 0  # > 0: faces wound outward


def test_torus_normals_are_the_fitted_torus_normals(demo):
    mesh = demo["torus"].data
    positions = local_positions(mesh)
    normals = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("normal", normals)
    centre, axis, major, minor, rho, z = fitted_torus(positions)
    # The exact normal points from the nearest point of the tube's centre circle to the vertex.
    offsets = positions - centre
    ring_points = centre + (offsets - np.outer(z, axis)) * (major / rho)[:, None]
    exact = (positions - ring_points) / minor
    # Vertex normals average the normals of faces 3° × 4° across: off by second order in the step, < 5e-3.
    np.testing.assert_allclose(normals.reshape(-1, 3), exact, rtol=0, atol=5e-3)


def test_planes_are_flat_and_face_the_torus_they_surround(demo):
    """Each plane is flat, and the whole torus lies on its front side (where its face normals point), clear of
    it: the planes surround the torus without touching it."""
    bpy.context.view_layer.update()
    torus = world_positions(demo["torus"])
    for role in PLANE_ROLES:
        ob = demo[role]
        points = world_positions(ob)
        centre = points.mean(axis=0)
        normal = np.linalg.svd(points - centre)[2][-1]  # direction of least spread
        extent = np.ptp(points, axis=0).max()
        assert np.abs((points - centre) @ normal).max() < 1e-6 * extent, role
        face_normals = np.empty(len(ob.data.polygons) * 3)
        ob.data.polygons.foreach_get("normal", face_normals)
        face_normals = face_normals.reshape(-1, 3) @ np.array(ob.matrix_world)[:3, :3].T
        normal *= np.sign(face_normals[0] @ normal)
        np.testing.assert_allclose(face_normals, np.broadcast_to(normal, face_normals.shape), atol=1e-6)
        assert ((torus - centre) @ normal).min() > 0.0, role


@pytest.mark.parametrize("build", [scenes.build_demo_scene, scenes.build_suzanne_scene])
def test_every_mesh_object_has_a_uv_map(build):
    build_fresh(build)
    meshes = [ob for ob in bpy.context.scene.objects if ob.type == "MESH"]
    assert meshes
    for ob in meshes:
        assert ob.data.uv_layers.active is not None, ob.name


def test_albedo_image_is_packed_and_varies(demo):
    image = base_color_image(demo["torus"].active_material)
    assert image.packed_file is not None
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    assert np.ptp(pixels.reshape(-1, 4)[:, :3], axis=0).min() > 0.1


def test_camera_sees_the_torus(demo):
    scene = bpy.context.scene
    assert scene.camera == demo["camera"]
    bpy.context.view_layer.update()
    torus = demo["torus"]
    for corner in torus.bound_box:
        x, y, depth = world_to_camera_view(scene, scene.camera, torus.matrix_world @ Vector(corner))
        assert 0.0 <= x <= 1.0 and 0.0 <= y <= 1.0 and depth > 0.0


def test_suzanne_rests_on_the_plane(suzanne_scene):
    """Resting is touching: her lowest vertex at the plane's height, to float32 rounding."""
    bpy.context.view_layer.update()
    lowest = world_positions(suzanne_scene["suzanne"])[:, 2].min()
    plane = world_positions(suzanne_scene["plane"])[:, 2]
    assert np.ptp(plane) < 1e-6  # level
    assert abs(lowest - plane.max()) < 1e-6
