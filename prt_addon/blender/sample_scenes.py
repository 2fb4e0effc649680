"""Sample scenes for trying the bake: a torus in an open box corner, and Suzanne on a plane.

Each builder adds its objects to the current scene (`bpy.context.scene`) and returns them by role.
Geometry is made from numpy arrays or bmesh, never bpy.ops, so the builders need no UI context.
"""

import bmesh
import bpy
import numpy as np

from .compat import new_node_material

UV_MAP = "UVMap"
ALBEDO_NAME = "Albedo"
ALBEDO_SIZE = 512
CHECKER_CELLS = 8
CHECKER_BLUR_RADIUS = 6  # pixels of box blur that soften the cell borders
# Muted sRGB tones: a mid-range albedo keeps interreflections visible without washing out.
CHECKER_PALETTE = np.array([
    (0.80, 0.76, 0.68),
    (0.55, 0.66, 0.78),
    (0.80, 0.58, 0.50),
    (0.60, 0.74, 0.56),
])

TORUS_MAJOR_SEGMENTS = 120
TORUS_MINOR_SEGMENTS = 90
TORUS_MAJOR_RADIUS = 1.0
TORUS_MINOR_RADIUS = 0.35
TORUS_HEIGHT = 0.9

ROOM_SIZE = 5.0
WALL_HEIGHT = 2.5
ROOM_SEGMENTS = 36  # floor 37² + two walls 37 × 19 vertices = 2,775

SUN_ELEVATION = np.radians(55.0)
SUN_AZIMUTH = np.radians(30.0)  # from the camera's side, so shadows fall toward the walls
SUN_ANGLE = 0.1
SUN_STRENGTH = 3.0

RESOLUTION = (640, 480)


def build_demo_scene() -> dict:
    """Torus (120 × 90 vertices) floating in an open box corner, textured, lit by a sun."""
    material = _albedo_material(_albedo_image())
    objects = {
        "torus": _link_object("Torus", _torus_mesh("Torus"), location=(0.0, 0.0, TORUS_HEIGHT)),
        "floor": _grid_object("Floor", centre=(0.0, 0.0, 0.0),
                              edge_u=(ROOM_SIZE, 0.0, 0.0), edge_v=(0.0, ROOM_SIZE, 0.0)),
        # Edge order makes each wall's normal face into the room.
        "back_wall": _grid_object("BackWall", centre=(0.0, ROOM_SIZE / 2, WALL_HEIGHT / 2),
                                  edge_u=(ROOM_SIZE, 0.0, 0.0), edge_v=(0.0, 0.0, WALL_HEIGHT)),
        "left_wall": _grid_object("LeftWall", centre=(-ROOM_SIZE / 2, 0.0, WALL_HEIGHT / 2),
                                  edge_u=(0.0, ROOM_SIZE, 0.0), edge_v=(0.0, 0.0, WALL_HEIGHT)),
    }
    for ob in objects.values():
        ob.data.materials.append(material)
    objects["camera"] = _add_camera(eye=(4.6, -9.8, 5.0), target=(-0.45, 0.3, 0.75))
    objects["sun"] = _add_sun()
    _set_resolution()
    return objects


def build_suzanne_scene() -> dict:
    """Suzanne, subdivided twice and smooth, resting on a plane, lit by a sun."""
    material = _albedo_material(_albedo_image())
    objects = {
        "suzanne": suzanne_object("Suzanne"),
        "plane": _grid_object("Plane", centre=(0.0, 0.0, 0.0), edge_u=(6.0, 0.0, 0.0),
                              edge_v=(0.0, 6.0, 0.0), segments=(20, 20)),
    }
    for ob in objects.values():
        ob.data.materials.append(material)
    objects["camera"] = _add_camera(eye=(3.0, -5.8, 2.6), target=(0.0, 0.0, 0.75))
    objects["sun"] = _add_sun()
    _set_resolution()
    return objects


# Geometry

def _quad_corners(segments_u, segments_v):
    """Lattice indices (i, j) of every quad's corners, counter-clockwise in (u, v), not wrapped."""
    i, j = np.meshgrid(np.arange(segments_u), np.arange(segments_v), indexing="ij")
    i, j = i.reshape(-1, 1), j.reshape(-1, 1)
    return i + np.array([0, 1, 1, 0]), j + np.array([0, 0, 1, 1])


def _mesh_from_quads(name, positions, quads, loop_uvs):
    """A smooth-shaded quad mesh with one UV map; positions (n, 3), quads (f, 4), loop_uvs (f, 4, 2)."""
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(positions))
    mesh.vertices.foreach_set("co", positions.astype(np.float32).ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.astype(np.int32).ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.uv_layers.new(name=UV_MAP).data.foreach_set("uv", loop_uvs.astype(np.float32).ravel())
    mesh.shade_smooth()
    return mesh


def _torus_mesh(name):
    """Torus around the z axis; u runs around the major radius, v around the tube."""
    n_u, n_v = TORUS_MAJOR_SEGMENTS, TORUS_MINOR_SEGMENTS
    u = np.repeat(np.arange(n_u) * (2 * np.pi / n_u), n_v)
    v = np.tile(np.arange(n_v) * (2 * np.pi / n_v), n_u)
    ring = TORUS_MAJOR_RADIUS + TORUS_MINOR_RADIUS * np.cos(v)
    positions = np.stack([ring * np.cos(u), ring * np.sin(u), TORUS_MINOR_RADIUS * np.sin(v)], axis=1)

    corner_i, corner_j = _quad_corners(n_u, n_v)
    quads = (corner_i % n_u) * n_v + corner_j % n_v
    # UVs stay unwrapped past the seam; 2 × 0.5 repeats keep the checker cells roughly square.
    loop_uvs = np.stack([corner_i / n_u * 2.0, corner_j / n_v * 0.5], axis=2)
    return _mesh_from_quads(name, positions, quads, loop_uvs)


def _grid_object(name, centre, edge_u, edge_v, segments=None):
    """A subdivided rectangle spanning edge_u × edge_v around centre; its normal is edge_u × edge_v."""
    edge_u, edge_v = np.array(edge_u), np.array(edge_v)
    if segments is None:  # keep cells square at ROOM_SEGMENTS across ROOM_SIZE
        cell = ROOM_SIZE / ROOM_SEGMENTS
        segments = (round(np.linalg.norm(edge_u) / cell), round(np.linalg.norm(edge_v) / cell))
    n_u, n_v = segments
    a = np.repeat(np.linspace(-0.5, 0.5, n_u + 1), n_v + 1)
    b = np.tile(np.linspace(-0.5, 0.5, n_v + 1), n_u + 1)
    positions = a[:, None] * edge_u + b[:, None] * edge_v

    corner_i, corner_j = _quad_corners(n_u, n_v)
    quads = corner_i * (n_v + 1) + corner_j
    # UVs in world units over ROOM_SIZE, so every surface shows checker cells of one size.
    loop_uvs = np.stack([corner_i / n_u * np.linalg.norm(edge_u),
                         corner_j / n_v * np.linalg.norm(edge_v)], axis=2) / ROOM_SIZE
    return _link_object(name, _mesh_from_quads(name, positions, quads, loop_uvs), location=centre)


def suzanne_object(name):
    """Suzanne with two Catmull-Clark levels applied in data, her lowest point at the object origin."""
    bm = bmesh.new()
    bm.loops.layers.uv.new(UV_MAP)
    bmesh.ops.create_monkey(bm, calc_uvs=True)
    base = bpy.data.meshes.new(name + "Base")
    bm.to_mesh(base)
    bm.free()

    ob = _link_object(name, base)
    subdivision = ob.modifiers.new("Subdivision", "SUBSURF")
    subdivision.levels = subdivision.render_levels = 2
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ob.data = bpy.data.meshes.new_from_object(ob.evaluated_get(depsgraph))
    ob.data.name = name
    ob.modifiers.remove(subdivision)
    bpy.data.meshes.remove(base)

    _drop_to_origin(ob.data)
    ob.data.shade_smooth()
    return ob


def _drop_to_origin(mesh):
    """Shift vertices so the lowest is at z = 0: the object then rests on whatever sits at its origin."""
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    positions = positions.reshape(-1, 3)
    positions[:, 2] -= positions[:, 2].min()
    mesh.vertices.foreach_set("co", positions.ravel())
    mesh.update()


def _link_object(name, data, location=(0.0, 0.0, 0.0)):
    ob = bpy.data.objects.new(name, data)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    return ob


# Albedo texture

def _albedo_image():
    """A soft four-colour checker, packed so the .blend carries it."""
    image = bpy.data.images.new(ALBEDO_NAME, ALBEDO_SIZE, ALBEDO_SIZE, alpha=False)
    image.pixels.foreach_set(_soft_checker_pixels(ALBEDO_SIZE, CHECKER_CELLS))
    image.pack()
    return image


def _soft_checker_pixels(size, cells):
    """Flat RGBA float pixels of a tileable checker whose cell borders are blurred."""
    cell = np.arange(size) * cells // size
    # Stepping one cell in x or y always changes colour; cells is a multiple of 4, so it tiles.
    colour_index = (cell[None, :] + 2 * cell[:, None]) % len(CHECKER_PALETTE)
    rgb = _wrapped_box_blur(CHECKER_PALETTE[colour_index], CHECKER_BLUR_RADIUS)
    rgba = np.concatenate([rgb, np.ones((size, size, 1))], axis=2)
    return rgba.astype(np.float32).ravel()


def _wrapped_box_blur(pixels, radius):
    """Separable box blur that wraps around the edges, keeping the texture tileable."""
    width = 2 * radius + 1
    for axis in (0, 1):
        pixels = sum(np.roll(pixels, shift, axis=axis) for shift in range(-radius, radius + 1)) / width
    return pixels


def _albedo_material(image):
    """Principled BSDF whose Base Color is the image, read through the UV map."""
    material = new_node_material(ALBEDO_NAME)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = UV_MAP
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Roughness"].default_value = 0.8  # PRT transfer is diffuse; keep highlights faint
    output = nodes.new("ShaderNodeOutputMaterial")
    for x, node in zip((-800, -550, -250, 100), (uv, texture, bsdf, output)):
        node.location = (x, 0)
    links.new(uv.outputs["UV"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    return material


# Camera, light, render settings

def _aim_euler(direction):
    """XYZ Euler turning an object's -Z axis along direction, its X axis kept level (no roll)."""
    x, y, z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    return (float(np.arccos(-z)), 0.0, float(np.arctan2(-x, y)))


def _add_camera(eye, target):
    camera = _link_object("Camera", bpy.data.cameras.new("Camera"), location=eye)
    camera.rotation_euler = _aim_euler(np.subtract(target, eye))
    bpy.context.scene.camera = camera
    return camera


def _add_sun():
    light = bpy.data.lights.new("Sun", "SUN")
    light.angle = SUN_ANGLE
    light.energy = SUN_STRENGTH
    toward_sun = np.array([np.sin(SUN_AZIMUTH) * np.cos(SUN_ELEVATION),
                           -np.cos(SUN_AZIMUTH) * np.cos(SUN_ELEVATION),
                           np.sin(SUN_ELEVATION)])
    # Placed up along its own direction only so it is easy to find in the viewport.
    sun = _link_object("Sun", light, location=tuple(6.0 * toward_sun))
    sun.rotation_euler = _aim_euler(-toward_sun)
    return sun


def _set_resolution():
    render = bpy.context.scene.render
    render.resolution_x, render.resolution_y = RESOLUTION
    render.resolution_percentage = 100
