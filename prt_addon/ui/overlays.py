"""Viewport overlays, the original program's N and L: vertex normals of baked meshes and a line towards each sun.

A SpaceView3D draw handler draws them with the gpu module. It is added only when Blender has a display: in
background mode the overlays are simply absent. The line geometry is plain numpy, so it is testable anywhere.
"""

import math

import bpy
import numpy as np

from ..blender import geometry, lights, mesh_arrays, storage

MAX_NORMALS_PER_OBJECT = 20_000  # beyond this every k-th vertex: the overlay stays interactive on big meshes
NORMAL_LENGTH = 0.03  # of the object's bounding-box diagonal
LIGHT_LINE_LENGTH = 3.0  # scene units, from the 3D cursor
NORMAL_COLOUR = (0.35, 0.65, 1.0, 1.0)

_handle = None
_normals = {}  # object name → (matrix and vertex count, segments): meshes do not move while you turn a light


def normal_segments(ob) -> np.ndarray:
    """(2k, 3) float32 world-space line ends: each drawn shading point's vertex, then that plus its scaled normal:
    the corner normals Blender shades with, one line per distinct normal of a vertex (core.corners)."""
    mesh = ob.data
    points = geometry.mesh_shading_points(mesh)
    step = math.ceil(len(points.point_vertices) / MAX_NORMALS_PER_OBJECT)
    matrix = np.array(ob.matrix_world, dtype=np.float64)
    starts = geometry.points_to_world(matrix, mesh_arrays.mesh_positions(mesh)[points.point_vertices[::step]])
    directions = geometry.directions_to_world(matrix, points.point_normals[::step])
    length = NORMAL_LENGTH * np.linalg.norm(np.ptp(starts, axis=0)) if len(starts) else 0.0
    return np.stack([starts, starts + length * directions], axis=1).reshape(-1, 3).astype(np.float32)


def light_segments(scene, origin) -> tuple[np.ndarray, np.ndarray]:
    """Line ends (2k, 3) from `origin` towards each enabled sun, and their colours (2k, 4)."""
    suns = [light for light in scene.prt_lights if light.use and light.kind == "SUN"]
    positions = np.zeros((2 * len(suns), 3), dtype=np.float32)
    colours = np.ones((2 * len(suns), 4), dtype=np.float32)
    for i, light in enumerate(suns):
        positions[2 * i] = origin
        positions[2 * i + 1] = np.asarray(origin) + LIGHT_LINE_LENGTH * np.asarray(lights.sun_direction(light))
        colours[2 * i: 2 * i + 2, :3] = light.colour
    return positions, colours


def _cached_normal_segments(ob):
    key = (tuple(map(tuple, ob.matrix_world)), len(ob.data.vertices))
    cached = _normals.get(ob.name_full)
    if cached is None or cached[0] != key:
        cached = _normals[ob.name_full] = (key, normal_segments(ob))
    return cached[1]


def _draw():
    import gpu
    from gpu_extras.batch import batch_for_shader

    context = bpy.context
    settings = context.scene.prt_display
    positions, colours = [], []
    if settings.show_normals:
        for ob in context.visible_objects:
            if ob.type == "MESH" and storage.METADATA_KEY in ob.data:
                segments = _cached_normal_segments(ob)
                positions.append(segments)
                colours.append(np.tile(np.float32(NORMAL_COLOUR), (len(segments), 1)))
    if settings.show_light_directions:
        lines, line_colours = light_segments(context.scene, tuple(context.scene.cursor.location))
        positions.append(lines)
        colours.append(line_colours)
    if not positions:
        return
    shader = gpu.shader.from_builtin("FLAT_COLOR")
    batch = batch_for_shader(shader, "LINES", {"pos": np.concatenate(positions), "color": np.concatenate(colours)})
    gpu.state.depth_test_set("LESS_EQUAL")
    batch.draw(shader)
    gpu.state.depth_test_set("NONE")


def register():
    global _handle
    if not bpy.app.background:
        _handle = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_VIEW")


def unregister():
    global _handle
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        _handle = None
    _normals.clear()
