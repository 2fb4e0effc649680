"""Mesh objects as the bake sees them: which objects, whether they can be written, and their evaluated surface
(world-space positions, normals, triangles) as numpy arrays. The one object-to-world rule lives here."""

from dataclasses import dataclass

import bpy
import numpy as np

from ..core import arrays, bake, corners, sampling
from ..core import settings as spec
from ..core.errors import InputError
from . import materials
from .mesh_arrays import (mesh_corner_edges, mesh_corner_normals, mesh_corner_vertices, mesh_edge_vertices,
                          mesh_positions, mesh_triangles, mesh_vertex_normals)


# -- shading points and transforms ---------------------------------------------------------------------------
def mesh_shading_points(mesh, positions=None, corner_triangles=None) -> corners.ShadingPoints:
    """The mesh's shading points (core.corners), from its vertex `positions` and its triangles' corners when the
    caller has read them already."""
    corner_vertices = mesh_corner_vertices(mesh)
    positions = mesh_positions(mesh) if positions is None else positions
    corner_triangles = mesh_triangles(mesh, of="loops") if corner_triangles is None else corner_triangles
    point_domain = mesh.normals_domain == "POINT"  # smooth, no sharp edges or custom normals: every corner has its
    normals = mesh_vertex_normals(mesh) if point_domain else mesh_corner_normals(mesh)  # vertex's normal
    corner_normals = normals[corner_vertices] if point_domain else normals
    face_normals = corners.first_triangle_normals(positions[corner_vertices], corner_triangles)
    if mesh.normals_domain == "FACE":
        corner_normals = corners.flat_shading_normals(corner_normals, face_normals)
    against = corners.against_faces(corner_normals, face_normals)
    fins = corners.on_fins(corner_vertices, mesh_corner_edges(mesh), mesh_edge_vertices(mesh))
    clip = corners.clip_planes(face_normals, against, fins)
    if point_domain and clip is None:  # (skipping the grouping saves a third of the gathering)
        return corners.unsplit_points(corner_vertices, normals)
    return corners.shading_points(corner_vertices, corner_normals, len(mesh.vertices), against, clip)


def points_to_world(matrix, points: np.ndarray) -> np.ndarray:
    """Object-space points (N, 3) through a 4 × 4 matrix_world."""
    m = np.asarray(matrix, dtype=np.float64)
    return arrays.one_thread_product(points, m[:3, :3].T) + m[:3, 3]


def directions_to_world(matrix, normals: np.ndarray) -> np.ndarray:
    """Object-space normals (N, 3) to unit world-space normals through the inverse transpose of matrix_world;
    zero rows stay zero."""
    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    # The inverse's rows from the columns' cross products, divided by the determinant: np.linalg.inv runs OpenBLAS's
    # threaded solver even for 3 × 3 (see arrays.SINGLE_THREAD_PRODUCT).
    cofactors = np.cross(m[:, [1, 2, 0]].T, m[:, [2, 0, 1]].T)
    determinant = float(m[:, 0] @ cofactors[0])
    if determinant == 0.0:
        raise np.linalg.LinAlgError("Singular matrix")
    return sampling.unit_or_zero(arrays.one_thread_product(normals, cofactors / determinant))


# -- which objects --------------------------------------------------------------------------------------------
def visible_mesh_objects(context):
    return [ob for ob in context.view_layer.objects if ob.type == "MESH" and ob.visible_get()]


def receivers_from_selection(context, names=None):
    """Named objects, else the selected meshes, else every visible mesh."""
    if names:
        found, missing = [], []
        for name in names:
            ob = bpy.data.objects.get(name)
            (found if ob is not None else missing).append(ob if ob is not None else name)
        if missing:
            raise InputError(f"no object named {', '.join(map(repr, missing))}")
        return found
    selected = [ob for ob in context.selected_objects if ob.type == "MESH"]
    return selected or visible_mesh_objects(context)


def is_dynamic(ob) -> bool:
    """Whether the object is baked in its own frame against itself alone (core.settings.DYNAMIC): it may move and
    turn after its bake, so it casts no shadow on the other objects and they cast none on it."""
    return bool(getattr(ob, "prt_" + spec.DYNAMIC.name, False))


def check_writable(ob):
    """Reasons the bake could not be stored on this object, raised before any work is done."""
    if ob.type != "MESH":
        raise InputError(f"{ob.name!r} is a {ob.type.lower()}, not a mesh")
    if ob.data.library is not None or ob.library is not None:
        raise InputError(f"{ob.name!r} uses linked library data, which cannot be written; make it local")
    if ob.mode == "EDIT" or ob.data.is_editmode:
        raise InputError(f"{ob.name!r} is in Edit Mode; switch to Object Mode to bake")


# -- surfaces -------------------------------------------------------------------------------------------------
@dataclass
class Surface:
    """A mesh object's evaluated surface in world space, as the bake sees it: one receiver row per shading point
    (core.corners: the vertices, then the further corner normals of split vertices)."""
    receiver: bake.Receiver
    triangles: np.ndarray        # (T, 3) indices into the receiver's points
    albedo: np.ndarray | None    # (P, 3) linear base colour per point, when asked for
    corner_points: np.ndarray | None = None  # (C,) each face corner's point; None: the points are the vertices
    split_vertices: int = 0
    extra_points: int = 0  # the last rows: split vertices' further points, each at its vertex's position

    @property
    def vertex_positions(self) -> np.ndarray:
        """(V, 3) each vertex's position once."""
        return self.receiver.positions[:len(self.receiver.positions) - self.extra_points]


def surface_from_object(ob, depsgraph, notes: list, for_storage: bool = True, albedo: bool = False,
                        own_frame: bool = False) -> Surface:
    """World-space positions and normals of the evaluated mesh's shading points, validated point by point; with
    `own_frame`, in the object's own space (a dynamic object's transfer turns with it).

    Each point is shaded with its corner normal, as Blender shades it; a vertex whose corners share one normal
    is one point (with exactly the vertex normal where they agree, so smooth meshes bake as they always did).
    for_storage: the result will be written to this object's mesh, so it must be writable and keep its
    vertex and corner counts through its modifiers. Vertices without a surface (loose, or only on zero-area
    faces) get zero transfer and a note in `notes`."""
    mesh = ob.data
    if for_storage:
        check_writable(ob)
    if len(mesh.polygons) == 0:
        raise InputError(f"{ob.name!r} has no faces, so it has no surface to bake")
    evaluated = ob.evaluated_get(depsgraph)
    eval_mesh = evaluated.to_mesh()
    try:
        if for_storage and (len(eval_mesh.vertices), len(eval_mesh.loops)) != (len(mesh.vertices), len(mesh.loops)):
            raise InputError(
                f"{ob.name!r}: its modifiers change the vertex or face corner count ({len(mesh.vertices)} → "
                f"{len(eval_mesh.vertices)} vertices, {len(mesh.loops)} → {len(eval_mesh.loops)} corners); "
                f"apply them or disable them in the viewport to bake")
        positions = mesh_positions(eval_mesh)
        if not np.isfinite(positions).all():
            bad = int((~np.isfinite(positions).all(1)).sum())
            raise InputError(f"{ob.name!r} has {bad} vertices with non-finite (NaN or infinite) coordinates")
        corner_triangles = mesh_triangles(eval_mesh, of="loops")
        points = mesh_shading_points(eval_mesh, positions, corner_triangles)
        split = points.extra_points > 0
        vertex_normals = mesh_vertex_normals(eval_mesh)
        normals = points.point_normals
        own = normals[: len(vertex_normals)]  # the vertices' own points: the vertex normal where it is theirs
        same = np.all(np.abs(own - vertex_normals) <= 10.0 ** -corners.NORMAL_DECIMALS, axis=1)
        own[same] = vertex_normals[same]
        positions = positions[points.point_vertices]
        triangles = points.corner_points[corner_triangles].astype(np.int32)
        used = np.zeros(len(positions), dtype=bool)
        used[_face_vertices_with_area(triangles, positions)] = True
        towards_faces = _towards_faces(triangles, positions)
        colours = (materials.vertex_albedo(ob, eval_mesh, notes, points.corner_points, len(positions))
                   if albedo else None)
    finally:
        evaluated.to_mesh_clear()
    matrix = np.eye(4) if own_frame else np.array(ob.matrix_world, dtype=np.float64)
    world_positions = points_to_world(matrix, positions)
    world_normals = directions_to_world(matrix, normals)
    usable = used & (np.linalg.norm(world_normals, axis=1) > 0)
    world_normals[~usable] = 0.0
    along_faces = arrays.one_thread_product(towards_faces, matrix[:3, :3].T)
    tangent = along_faces - np.einsum("ij,ij->i", along_faces, world_normals)[:, None] * world_normals
    lowest, highest = arrays.bounds(world_positions)
    scale = np.linalg.norm(highest - lowest)
    inward, surface_step = (sampling.unit_or_zero(step, 1e-12 * scale) for step in (tangent, along_faces))
    if not usable.all():
        notes.append(f"{ob.name!r}: {int((~usable).sum())} vertices are loose or only on zero-area faces; "
                     f"they get zero transfer")
    groups = corners.ray_groups(points.point_vertices, world_normals, len(vertex_normals)) if split else None
    clip = None if points.clip is None else directions_to_world(matrix, points.clip)
    receiver = bake.Receiver(ob.name, world_positions, world_normals, bake.Receiver.key_for(ob.name), inward, groups,
                             surface_step, points.against, clip)
    return Surface(receiver, triangles, colours, points.corner_points if split else None, points.split_vertices,
                   points.extra_points)


def _towards_faces(triangles: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Per vertex: mean of its triangles' centroids minus the vertex (object space, not normalised)."""
    centroids = positions[triangles].mean(axis=1)
    total = np.zeros_like(positions)
    for corner in range(3):
        np.add.at(total, triangles[:, corner], centroids)
    count = np.bincount(triangles.ravel(), minlength=len(positions))[:, None]
    return np.where(count > 0, total / np.maximum(count, 1) - positions, 0.0)


def _face_vertices_with_area(triangles, positions) -> np.ndarray:
    """Vertices of triangles with non-zero area: the others (loose or degenerate) have no normal."""
    if len(triangles) == 0:
        return np.zeros(0, dtype=np.int32)
    a, b, c = (positions[triangles[:, i]] for i in range(3))
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return np.unique(triangles[area > 0])
