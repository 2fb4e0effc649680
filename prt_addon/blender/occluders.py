"""What casts shadows: every visible mesh in world space (modifiers applied, instances expanded), the points whose
convex hull bounds it, and the flat convex polygons among it that the core integrates in closed form."""

import numpy as np

from ..core import arrays, bake, polygons
from .geometry import is_dynamic, points_to_world
from .mesh_arrays import mesh_positions, mesh_triangles

HULL_TEST_POINTS = 1 << 16  # points tested against the extremes' hull at once, so memory stays bounded


def occluders_from_depsgraph(depsgraph, surfaces=()) -> tuple[bake.Occluders, set]:
    """The solved surfaces first, in the job's order (the occluders' `solved_vertices`, so a hit triangle's corners
    index their vertices), then every other visible mesh but the dynamic ones (modifiers applied, instances
    expanded), in world space; and the names of the objects they came from. Without a depsgraph, the solved surfaces
    alone (a dynamic object's own)."""
    vertex_blocks = [s.receiver.positions for s in surfaces]
    offsets = np.cumsum([0] + [len(block) for block in vertex_blocks])
    triangle_blocks = [s.triangles + offset for s, offset in zip(surfaces, offsets)]
    solved = count = int(offsets[-1])
    sources, meshes = set(), {}
    flat = [polygons.convex_polygon(s.receiver.positions, s.triangles) for s in surfaces]
    baked = {s.receiver.name for s in surfaces}
    for instance in depsgraph.object_instances if depsgraph is not None else ():
        ob, owner = instance.object, shadow_caster(instance)
        if owner is None or (not instance.is_instance and ob.original.name in baked):
            continue
        key = ob.original.name, instance.is_instance
        if key not in meshes:
            mesh = ob.to_mesh()
            meshes[key] = (mesh_positions(mesh), mesh_triangles(mesh))
            ob.to_mesh_clear()
        positions, triangles = meshes[key]
        if len(triangles) == 0:
            continue
        sources.add(owner.name)
        world = points_to_world(instance.matrix_world, positions)
        finite = np.isfinite(world).all(1)
        keep = finite[triangles].all(1)  # drop triangles that touch non-finite vertices
        vertex_blocks.append(np.where(finite[:, None], world, 0.0))
        triangle_blocks.append(triangles[keep] + count)
        flat.append(polygons.convex_polygon(world, triangles) if keep.all() else None)
        count += len(world)
    sources |= baked
    if not count:
        return bake.Occluders(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), np.zeros((0, 3))), sources
    vertices = np.concatenate(vertex_blocks)
    triangles = np.concatenate(triangle_blocks)
    against = None
    if any(s.receiver.against is not None for s in surfaces):
        against = np.zeros(len(vertices), dtype=bool)
        for s, first in zip(surfaces, offsets):
            if s.receiver.against is not None:
                against[first:first + len(s.receiver.against)] = s.receiver.against
    if not len(triangles):
        return bake.Occluders(vertices, triangles, np.zeros((0, 3)), solved_vertices=solved, against=against), sources
    found = polygons.largest([polygon for polygon in flat if polygon is not None], polygons.MAX_POLYGONS)
    hull_rows = np.zeros(len(vertices), dtype=bool)
    hull_rows[triangles] = True
    for surface, end in zip(surfaces, offsets[1:]):  # not twice where a split vertex's points repeat its position
        hull_rows[end - surface.extra_points:end] = False
    hull = convex_hull_points(vertices[hull_rows])
    return bake.Occluders(vertices, triangles, hull, found, solved_vertices=solved, against=against), sources


def shadow_caster(instance):
    """The visible object whose mesh a depsgraph instance shows (the instancer for an instance), or None when it
    casts no shadow (not a mesh, hidden, or dynamic: it moves after the bake)."""
    if instance.object.type != "MESH":
        return None
    owner = instance.parent.original if instance.is_instance and instance.parent else instance.object.original
    return owner if owner.visible_get() and not is_dynamic(owner) else None


def convex_hull_points(points: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull: the highest occluder point in any direction is one of them.

    Flat or collinear input has no 3D hull; the bounding box's corners then bound it (conservative: a
    vertex may lose its proof of being unoccluded, never gain a wrong one)."""
    low, high = arrays.bounds(points)
    centre = 0.5 * (low + high)  # bmesh decides in float32: keep its rounding scene-relative
    candidates = _outside_polytope_of_extremes(points - centre)
    if candidates is not None:
        hull, _ = _hull(candidates)
        if len(hull) >= 4:
            return candidates[hull] + centre  # the exact points: bmesh rounds coordinates to float32
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


def _outside_polytope_of_extremes(points: np.ndarray):
    """Akl-Toussaint: a point strictly inside the hull of some extreme points is no hull vertex, so the exact
    hull only needs the rest (for a room with objects inside, a handful of points instead of every vertex)."""
    axes = np.array([(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if (x, y, z) != (0, 0, 0)])
    extremes = points[np.unique(np.argmax(arrays.one_thread_product(points, axes.T), axis=0))]
    inner, (normals, offsets) = _hull(extremes)
    if len(inner) < 4 or len(normals) < 4:
        return None  # flat: no volume to test against
    outward = np.where(normals @ extremes[inner].mean(0) - offsets > 0, -1.0, 1.0)  # bmesh does not orient them
    normals, offsets = normals * outward[:, None], offsets * outward
    tolerance = 1e-5 * (np.abs(points).max() + 1.0)  # bmesh stores float32: keep points near the faces
    keep = np.concatenate([
        np.any(arrays.one_thread_product(block, normals.T) - offsets >= -tolerance, axis=1)
        for block in np.array_split(points, max(1, len(points) // HULL_TEST_POINTS))])
    return points[keep]
