"""Between Blender data and the core's arrays: geometry in, transfer attributes and metadata out.

Stored layout (documented in the README; bump core.bake.CONVENTION_VERSION when it changes):
- POINT-domain FLOAT_VECTOR attributes `_prt_t00`, `_prt_t01`, ... each holding 3 consecutive SH
  coefficients (k = 3j, 3j+1, 3j+2; the last one zero-padded). The leading `_` lets glTF export them.
- POINT-domain FLOAT attribute `_prt_error`: per-vertex estimated relative standard error.
- Mesh custom property `prt` (a group): order, mode, samples, rays, convention, vertex_count,
  est_rms_rel_error, est_max_rel_error, time_s, date, bake_id, seed, target_error, skipped_vertices.
"""

from datetime import datetime, timezone
import uuid

import bpy
import numpy as np

from .core import bake

ATTRIBUTE_PREFIX = "_prt_"
ERROR_ATTRIBUTE = "_prt_error"
METADATA_KEY = "prt"


class InputError(Exception):
    """A problem with one object, told to the user by name; other objects still bake."""


def coefficient_attribute_names(order: int, channel: str = "t") -> list[str]:
    return [f"{ATTRIBUTE_PREFIX}{channel}{j:02d}" for j in range(-(-order * order // 3))]


def _mesh_triangles(mesh) -> np.ndarray:
    mesh.calc_loop_triangles()
    triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", triangles)
    return triangles.reshape(-1, 3)


def _mesh_positions(mesh) -> np.ndarray:
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", positions)
    return positions.reshape(-1, 3)


def _to_world(matrix, positions):
    m = np.array(matrix, dtype=np.float64)
    return positions @ m[:3, :3].T + m[:3, 3]


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


def check_writable(ob):
    """Reasons the bake could not be stored on this object, raised before any work is done."""
    if ob.type != "MESH":
        raise InputError(f"{ob.name!r} is a {ob.type.lower()}, not a mesh")
    if ob.data.library is not None or ob.library is not None:
        raise InputError(f"{ob.name!r} uses linked library data, which cannot be written; make it local")
    if ob.mode == "EDIT" or ob.data.is_editmode:
        raise InputError(f"{ob.name!r} is in Edit Mode; switch to Object Mode to bake")


def receiver_from_object(ob, depsgraph, notes: list) -> bake.Receiver:
    """World-space positions and normals of the evaluated mesh, validated vertex by vertex.

    Vertices without a surface (loose, or only on zero-area faces) get zero transfer and a note in `notes`."""
    check_writable(ob)
    mesh = ob.data
    if len(mesh.polygons) == 0:
        raise InputError(f"{ob.name!r} has no faces, so it has no surface to bake")
    evaluated = ob.evaluated_get(depsgraph)
    eval_mesh = evaluated.to_mesh()
    try:
        if len(eval_mesh.vertices) != len(mesh.vertices):
            raise InputError(
                f"{ob.name!r}: its modifiers change the vertex count ({len(mesh.vertices)} → "
                f"{len(eval_mesh.vertices)}); apply them or disable them in the viewport to bake")
        positions = _mesh_positions(eval_mesh)
        if not np.isfinite(positions).all():
            bad = int((~np.isfinite(positions).all(1)).sum())
            raise InputError(f"{ob.name!r} has {bad} vertices with non-finite (NaN or infinite) coordinates")
        normals = np.empty(len(eval_mesh.vertices) * 3, dtype=np.float64)
        eval_mesh.vertex_normals.foreach_get("vector", normals)
        normals = normals.reshape(-1, 3)
        used = np.zeros(len(positions), dtype=bool)
        used[_face_vertices_with_area(eval_mesh, positions)] = True
        towards_faces = _towards_faces(_mesh_triangles(eval_mesh), positions)
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(ob.matrix_world, dtype=np.float64)
    world_positions = _to_world(matrix, positions)
    normal_matrix = np.linalg.inv(matrix[:3, :3]).T
    world_normals = normals @ normal_matrix.T
    lengths = np.linalg.norm(world_normals, axis=1, keepdims=True)
    usable = used & (lengths[:, 0] > 0) & np.isfinite(lengths[:, 0])
    world_normals = np.where(usable[:, None], world_normals / np.where(lengths > 0, lengths, 1.0), 0.0)
    inward = towards_faces @ matrix[:3, :3].T
    inward -= np.einsum("ij,ij->i", inward, world_normals)[:, None] * world_normals  # tangent only
    length = np.linalg.norm(inward, axis=1, keepdims=True)
    inward = np.where(length > 1e-12 * np.linalg.norm(np.ptp(world_positions, axis=0)),
                      inward / np.where(length > 0, length, 1.0), 0.0)
    if not usable.all():
        notes.append(f"{ob.name!r}: {int((~usable).sum())} vertices are loose or only on zero-area faces; "
                     f"they get zero transfer")
    return bake.Receiver(ob.name, world_positions, world_normals, bake.Receiver.key_for(ob.name), inward)


def _towards_faces(triangles: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Per vertex: mean of its triangles' centroids minus the vertex (object space, not normalised)."""
    centroids = positions[triangles].mean(axis=1)
    total = np.zeros_like(positions)
    for corner in range(3):
        np.add.at(total, triangles[:, corner], centroids)
    count = np.bincount(triangles.ravel(), minlength=len(positions))[:, None]
    return np.where(count > 0, total / np.maximum(count, 1) - positions, 0.0)


def _face_vertices_with_area(mesh, positions) -> np.ndarray:
    """Vertices of triangles with non-zero area: the others (loose or degenerate) have no normal."""
    triangles = _mesh_triangles(mesh)
    if len(triangles) == 0:
        return np.zeros(0, dtype=np.int32)
    a, b, c = (positions[triangles[:, i]] for i in range(3))
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return np.unique(triangles[area > 0])


def occluders_from_depsgraph(depsgraph, receivers=()) -> tuple[bake.Occluders, set]:
    """Every visible mesh (modifiers applied, instances expanded) plus the receivers, in world space,
    and the names of the objects they came from."""
    vertex_blocks, triangle_blocks, count, sources = [], [], 0, set()
    meshes = {}
    receiver_names = {ob.name for ob in receivers}
    for instance in depsgraph.object_instances:
        ob = instance.object
        if ob.type != "MESH":
            continue
        owner = instance.parent.original if instance.is_instance and instance.parent else ob.original
        if not (owner.visible_get() or ob.original.name in receiver_names):
            continue
        key = ob.original.name, instance.is_instance
        if key not in meshes:
            mesh = ob.to_mesh()
            meshes[key] = (_mesh_positions(mesh), _mesh_triangles(mesh))
            ob.to_mesh_clear()
        positions, triangles = meshes[key]
        if len(triangles) == 0:
            continue
        sources.add(owner.name)
        world = _to_world(instance.matrix_world, positions)
        finite = np.isfinite(world).all(1)
        keep = finite[triangles].all(1)  # drop triangles that touch non-finite vertices
        vertex_blocks.append(np.where(finite[:, None], world, 0.0))
        triangle_blocks.append(triangles[keep] + count)
        count += len(world)
    if not vertex_blocks:
        return bake.Occluders(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), np.zeros((0, 3))), sources
    vertices = np.concatenate(vertex_blocks)
    triangles = np.concatenate(triangle_blocks)
    return bake.Occluders(vertices, triangles, convex_hull_points(vertices[np.unique(triangles)])), sources


def convex_hull_points(points: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull: the highest occluder point in any direction is one of them.

    Flat or collinear input has no 3D hull; the bounding box's corners then bound it (conservative: a
    vertex may lose its proof of being unoccluded, never gain a wrong one)."""
    centre = 0.5 * (points.min(0) + points.max(0))  # bmesh decides in float32: keep its rounding scene-relative
    candidates = _outside_polytope_of_extremes(points - centre)
    if candidates is not None:
        hull, _ = _hull(candidates)
        if len(hull) >= 4:
            return candidates[hull] + centre  # the exact points: bmesh rounds coordinates to float32
    low, high = points.min(0), points.max(0)
    return np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])


def _hull(points: np.ndarray):
    """bmesh's convex hull: (indices of the hull's vertices in `points`, face planes as (normals, offsets))."""
    import bmesh
    bm = bmesh.new()
    try:
        for p in points:
            bm.verts.new(p)
        result = bmesh.ops.convex_hull(bm, input=bm.verts, use_existing_faces=False)
        bm.verts.index_update()
        vertices = np.array([v.index for v in result["geom"] if isinstance(v, bmesh.types.BMVert)], dtype=np.int64)
        faces = [f for f in result["geom"] if isinstance(f, bmesh.types.BMFace)]
        for face in faces:
            face.normal_update()
        normals = np.array([f.normal[:] for f in faces]).reshape(-1, 3)
        offsets = np.array([f.normal.dot(f.verts[0].co) for f in faces])
    finally:
        bm.free()
    return vertices, (normals, offsets)


def _outside_polytope_of_extremes(points: np.ndarray, chunk: int = 1 << 16):
    """Akl-Toussaint: a point strictly inside the hull of some extreme points is no hull vertex, so the exact
    hull only needs the rest (for a room with objects inside, a handful of points instead of every vertex)."""
    axes = np.array([(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if (x, y, z) != (0, 0, 0)])
    extremes = points[np.unique(np.argmax(points @ axes.T, axis=0))]
    inner, (normals, offsets) = _hull(extremes)
    if len(inner) < 4 or len(normals) < 4:
        return None  # flat: no volume to test against
    outward = np.where(normals @ extremes[inner].mean(0) - offsets > 0, -1.0, 1.0)  # bmesh does not orient them
    normals, offsets = normals * outward[:, None], offsets * outward
    tolerance = 1e-5 * (np.abs(points).max() + 1.0)  # bmesh stores float32: keep points near the faces
    keep = np.concatenate([
        np.any(block @ normals.T - offsets >= -tolerance, axis=1)
        for block in np.array_split(points, max(1, len(points) // chunk))])
    return points[keep]


# -- storage --------------------------------------------------------------------------------------------
def write_transfer(ob, result, summary_fields: dict, settings: bake.BakeSettings):
    """Replaces any previous bake on the object's mesh: attributes first, metadata last."""
    mesh = ob.data
    remove_transfer(mesh)
    order = settings.order
    padded = np.zeros((len(mesh.vertices), 3 * len(coefficient_attribute_names(order))), dtype=np.float32)
    padded[:, : order * order] = result.transfer
    for j, name in enumerate(coefficient_attribute_names(order)):
        mesh.attributes.new(name, "FLOAT_VECTOR", "POINT")
        # Look the attribute up by name again: adding attributes can invalidate earlier references.
        mesh.attributes[name].data.foreach_set("vector", np.ascontiguousarray(padded[:, 3 * j: 3 * j + 3]).ravel())
    mesh.attributes.new(ERROR_ATTRIBUTE, "FLOAT", "POINT")
    mesh.attributes[ERROR_ATTRIBUTE].data.foreach_set("value", result.rel_error.astype(np.float32))
    mesh[METADATA_KEY] = {
        "order": order,
        "mode": settings.mode,
        "samples": settings.samples,
        "target_error": settings.target_error,
        "seed": settings.seed,
        "convention": bake.CONVENTION_VERSION,
        "vertex_count": len(mesh.vertices),
        "rays": int(result.rays.sum()),
        "skipped_vertices": int(result.skipped.sum()),
        "est_rms_rel_error": float(np.sqrt(np.mean(np.square(result.rel_error)))),
        "est_max_rel_error": float(result.rel_error.max(initial=0.0)),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "bake_id": uuid.uuid4().hex,  # tells two bakes apart even within the same second
        **summary_fields,
    }
    mesh.update()


def remove_transfer(mesh):
    for name in [a.name for a in mesh.attributes if a.name.startswith(ATTRIBUTE_PREFIX)]:
        mesh.attributes.remove(mesh.attributes[name])
    if METADATA_KEY in mesh:
        del mesh[METADATA_KEY]


class StaleBake(Exception):
    pass


def read_transfer(mesh) -> tuple[np.ndarray, dict]:
    """(V, n²) float32 transfer and the metadata; raises StaleBake when it no longer fits the mesh."""
    if METADATA_KEY not in mesh:
        raise StaleBake(f"mesh {mesh.name!r} has no PRT bake")
    meta = mesh[METADATA_KEY].to_dict()
    if meta.get("convention") != bake.CONVENTION_VERSION:
        raise StaleBake(f"mesh {mesh.name!r} was baked with layout version {meta.get('convention')}; rebake it")
    if meta["vertex_count"] != len(mesh.vertices):
        raise StaleBake(f"mesh {mesh.name!r} was baked with {meta['vertex_count']} vertices but now has "
                        f"{len(mesh.vertices)}; rebake it")
    order = meta["order"]
    names = coefficient_attribute_names(order)
    missing = [n for n in names if n not in mesh.attributes]
    if missing:
        raise StaleBake(f"mesh {mesh.name!r} lost its PRT attributes {', '.join(missing)}; rebake it")
    columns = np.empty((len(names), len(mesh.vertices) * 3), dtype=np.float32)
    for j, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("vector", columns[j])
    transfer = columns.reshape(len(names), -1, 3).transpose(1, 0, 2).reshape(len(mesh.vertices), -1)
    return np.ascontiguousarray(transfer[:, : order * order]), meta
