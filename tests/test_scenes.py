import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from prt_addon.blender import sample_scenes as scenes


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


def base_color_image(material):
    """The image feeding the Principled BSDF's Base Color."""
    bsdf = next(node for node in material.node_tree.nodes if node.type == "BSDF_PRINCIPLED")
    link = bsdf.inputs["Base Color"].links[0]
    assert link.from_node.type == "TEX_IMAGE"
    return link.from_node.image


def test_torus_has_120_by_90_quads(demo):
    mesh = demo["torus"].data
    assert len(mesh.vertices) == 120 * 90
    assert len(mesh.polygons) == 120 * 90
    assert all(polygon.loop_total == 4 for polygon in mesh.polygons)


def test_room_vertex_total(demo):
    total = sum(len(demo[role].data.vertices) for role in ("floor", "back_wall", "left_wall"))
    assert 2500 <= total <= 2900


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


def test_torus_normals_point_away_from_its_core_ring(demo):
    mesh = demo["torus"].data
    positions = local_positions(mesh)
    normals = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("normal", normals)
    normals = normals.reshape(-1, 3)
    # The core ring is the major-radius circle in the torus' local xy plane.
    radial = positions[:, :2] / np.linalg.norm(positions[:, :2], axis=1, keepdims=True)
    ring_points = np.column_stack([radial * scenes.TORUS_MAJOR_RADIUS, np.zeros(len(positions))])
    assert (np.einsum("ij,ij->i", normals, positions - ring_points) > 0).all()


def test_suzanne_rests_on_the_plane(suzanne_scene):
    bpy.context.view_layer.update()
    lowest = world_positions(suzanne_scene["suzanne"])[:, 2].min()
    plane_height = world_positions(suzanne_scene["plane"])[:, 2].max()
    assert plane_height <= lowest <= plane_height + 0.05


def test_clear_scene_leaves_no_objects_or_their_data(demo):
    scenes.clear_scene()
    for collection in (bpy.data.objects, bpy.data.meshes, bpy.data.materials,
                       bpy.data.images, bpy.data.lights, bpy.data.cameras):
        assert len(collection) == 0
