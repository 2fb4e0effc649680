"""Between Blender data and the core's arrays: geometry in, transfer attributes and metadata out.

Stored layout (documented in the README; bump core.bake.CONVENTION_VERSION when it changes):
- POINT-domain FLOAT_VECTOR attributes `_prt_t00`, `_prt_t01`, ... each holding 3 consecutive SH
  coefficients (k = 3j, 3j+1, 3j+2; the last one zero-padded). The leading `_` lets glTF export them.
  Coloured (interreflected) transfer has one such set per channel: `_prt_r00`..., `_prt_g00`..., `_prt_b00`....
- POINT-domain FLOAT attribute `_prt_error`: per-vertex estimated relative standard error.
- Mesh custom property `prt` (a group): order, mode, samples, rays, convention, vertex_count,
  est_rms_rel_error, est_max_rel_error, time_s, date, bake_id, seed, target_error, skipped_vertices, channels
  (and bounces for interreflected bakes).
"""

from dataclasses import dataclass
from datetime import datetime, timezone
import uuid

import bpy
import numpy as np

from . import display
from .core import bake, polygons

ATTRIBUTE_PREFIX = "_prt_"
ERROR_ATTRIBUTE = "_prt_error"
METADATA_KEY = "prt"


class InputError(Exception):
    """A problem with one object, told to the user by name; other objects still bake."""


CHANNEL_LETTERS = {1: "t", 3: "rgb"}


def coefficient_attribute_names(order: int, channel: str = "t") -> list[str]:
    return [f"{ATTRIBUTE_PREFIX}{channel}{j:02d}" for j in range(-(-order * order // 3))]


def _channel_planes(transfer: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(letter, (V, n²)) per stored channel: 't' for grey transfer, 'r', 'g', 'b' for coloured."""
    if transfer.ndim == 2:
        return [("t", transfer)]
    return list(zip(CHANNEL_LETTERS[transfer.shape[1]], transfer.transpose(1, 0, 2)))


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


@dataclass
class Surface:
    """A mesh object's evaluated surface in world space, as the bake sees it."""
    receiver: bake.Receiver
    triangles: np.ndarray        # (T, 3) indices into the receiver's vertices
    albedo: np.ndarray | None    # (V, 3) linear base colour per vertex, when asked for


def surface_from_object(ob, depsgraph, notes: list, for_storage: bool = True, albedo: bool = False) -> Surface:
    """World-space positions and normals of the evaluated mesh, validated vertex by vertex.

    for_storage: the result will be written to this object's mesh, so it must be writable and keep its
    vertex count through its modifiers. Vertices without a surface (loose, or only on zero-area faces) get zero
    transfer and a note in `notes`."""
    mesh = ob.data
    if for_storage:
        check_writable(ob)
    if len(mesh.polygons) == 0:
        raise InputError(f"{ob.name!r} has no faces, so it has no surface to bake")
    evaluated = ob.evaluated_get(depsgraph)
    eval_mesh = evaluated.to_mesh()
    try:
        if for_storage and len(eval_mesh.vertices) != len(mesh.vertices):
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
        triangles = _mesh_triangles(eval_mesh)
        used = np.zeros(len(positions), dtype=bool)
        used[_face_vertices_with_area(triangles, positions)] = True
        towards_faces = _towards_faces(triangles, positions)
        colours = vertex_albedo(ob, eval_mesh, notes) if albedo else None
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
    receiver = bake.Receiver(ob.name, world_positions, world_normals, bake.Receiver.key_for(ob.name), inward)
    return Surface(receiver, triangles, colours)


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


def occluders_from_depsgraph(depsgraph, surfaces=()) -> tuple[bake.Occluders, set]:
    """The surfaces being baked first, in order (so a hit triangle's corners index their vertices), then every
    other visible mesh (modifiers applied, instances expanded), in world space; and the names of the objects
    they came from."""
    vertex_blocks = [s.receiver.positions for s in surfaces]
    offsets = np.cumsum([0] + [len(block) for block in vertex_blocks])
    triangle_blocks = [s.triangles + offset for s, offset in zip(surfaces, offsets)]
    count, sources, meshes = int(offsets[-1]), set(), {}
    flat = [polygons.convex_polygon(s.receiver.positions, s.triangles) for s in surfaces]
    baked = {s.receiver.name for s in surfaces}
    for instance in depsgraph.object_instances:
        ob = instance.object
        if ob.type != "MESH" or (not instance.is_instance and ob.original.name in baked):
            continue
        owner = instance.parent.original if instance.is_instance and instance.parent else ob.original
        if not owner.visible_get():
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
        flat.append(polygons.convex_polygon(world, triangles) if keep.all() else None)
        count += len(world)
    sources |= baked
    if not count:
        return bake.Occluders(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), np.zeros((0, 3))), sources
    vertices = np.concatenate(vertex_blocks)
    triangles = np.concatenate(triangle_blocks)
    if not len(triangles):
        return bake.Occluders(vertices, triangles, np.zeros((0, 3))), sources
    found = polygons.largest([polygon for polygon in flat if polygon is not None], polygons.MAX_POLYGONS)
    return bake.Occluders(vertices, triangles, convex_hull_points(vertices[np.unique(triangles)]), found), sources


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


# -- albedo ---------------------------------------------------------------------------------------------
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)  # Blender's default base colour


def vertex_albedo(ob, mesh, notes: list) -> np.ndarray:
    """(V, 3) linear albedo per vertex of `mesh` (the object's evaluated mesh): each face corner's base colour
    (a Principled or Diffuse BSDF's colour value, an image texture at the corner's UV, or a colour attribute),
    averaged over the corners of each vertex."""
    corner_vertex = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", corner_vertex)
    face_material = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("material_index", face_material)
    face_sizes = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_total", face_sizes)
    corner_material = np.repeat(face_material, face_sizes)
    corner_colour = np.tile(np.array(DEFAULT_ALBEDO), (len(corner_vertex), 1))
    # The object's own materials, also while the PRT display's materials stand in for them.
    for slot_index, material in enumerate(display.original_materials(ob)):
        corners = corner_material == slot_index
        if material is not None and corners.any():
            corner_colour[corners] = _material_colours(ob, mesh, material, notes)[corners]
    total = np.zeros((len(mesh.vertices), 3))
    for channel in range(3):
        total[:, channel] = np.bincount(corner_vertex, corner_colour[:, channel], minlength=len(mesh.vertices))
    count = np.bincount(corner_vertex, minlength=len(mesh.vertices))[:, None]
    return np.where(count > 0, total / np.maximum(count, 1), np.array(DEFAULT_ALBEDO))


def _material_colours(ob, mesh, material, notes) -> np.ndarray:
    """(corners, 3) base colour of `material` at every face corner of the mesh."""
    colour_input = _base_colour_input(material)
    if colour_input is None:
        return np.tile(np.array(material.diffuse_color[:3]), (len(mesh.loops), 1))
    flat = np.tile(np.array(colour_input.default_value[:3]), (len(mesh.loops), 1))
    if not colour_input.is_linked:
        return flat
    source = colour_input.links[0].from_node
    if source.type == "TEX_IMAGE" and source.image is not None:
        uv_name = _uv_map_of(source)
        layer = mesh.uv_layers.get(uv_name) if uv_name else mesh.uv_layers.active
        if layer is None:
            notes.append(f"{ob.name!r}: material {material.name!r} uses an image texture but the mesh has no UV "
                         f"map; its base colour value is used as albedo instead")
            return flat
        uv = np.empty(len(mesh.loops) * 2, dtype=np.float64)
        layer.data.foreach_get("uv", uv)
        return _sample_image(source.image, uv.reshape(-1, 2), ob, notes, flat)
    if source.type == "VERTEX_COLOR":
        attribute = mesh.color_attributes.get(source.layer_name) if source.layer_name else \
            mesh.color_attributes.active_color
        if attribute is not None:
            return _corner_colours(mesh, attribute)
    notes.append(f"{ob.name!r}: material {material.name!r}'s base colour comes from a {source.type.lower()} "
                 f"node, which the bake cannot read; its colour value is used as albedo")
    return flat


def subsurface_material(ob):
    """(weight, mean free path RGB, albedo RGB, IOR) of the object's first Principled BSDF with Subsurface
    Weight > 0, or None. The mean free path is Subsurface Radius × Subsurface Scale, in scene units."""
    for material in display.original_materials(ob):
        tree = material.node_tree if material else None
        for node in tree.nodes if tree else ():
            if node.type == "BSDF_PRINCIPLED" and node.inputs["Subsurface Weight"].default_value > 0:
                inputs = node.inputs
                return (float(inputs["Subsurface Weight"].default_value),
                        np.array(inputs["Subsurface Radius"].default_value[:3]) * inputs["Subsurface Scale"].default_value,
                        np.array(inputs["Base Color"].default_value[:3]), float(inputs["IOR"].default_value))
    return None


def _base_colour_input(material):
    if material.node_tree is None:
        return None
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            return node.inputs["Base Color"]
        if node.type == "BSDF_DIFFUSE":
            return node.inputs["Color"]
    return None


def _uv_map_of(image_node):
    vector = image_node.inputs["Vector"]
    if vector.is_linked and vector.links[0].from_node.type == "UVMAP":
        return vector.links[0].from_node.uv_map
    return None


def _sample_image(image, uv, ob, notes, fallback) -> np.ndarray:
    """Nearest texel at each UV (repeating), in linear colour."""
    width, height = image.size
    if width == 0 or height == 0:
        notes.append(f"{ob.name!r}: image {image.name!r} cannot be read; its material's colour value is used")
        return fallback
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(height, width, image.channels)
    repeat = np.mod(uv, 1.0)
    repeat[(repeat == 0.0) & (uv > 0.0)] = 1.0  # u = 1 is the image's right edge, not its left
    column = np.minimum((repeat[:, 0] * width).astype(np.int64), width - 1)
    row = np.minimum((repeat[:, 1] * height).astype(np.int64), height - 1)
    colours = pixels[row, column, :3].astype(np.float64)
    if colours.shape[1] == 1:
        colours = np.repeat(colours, 3, axis=1)
    if image.colorspace_settings.name == "sRGB" and not image.is_float:
        colours = _srgb_to_linear(colours)  # byte images hold display-encoded values
    return colours


def _srgb_to_linear(values):
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)


def _corner_colours(mesh, attribute) -> np.ndarray:
    values = np.empty(len(attribute.data) * 4, dtype=np.float32)
    attribute.data.foreach_get("color", values)  # linear, for byte and float attributes alike
    values = values.reshape(-1, 4)[:, :3].astype(np.float64)
    if attribute.domain == "CORNER":
        return values
    corner_vertex = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", corner_vertex)
    return values[corner_vertex]


# -- storage --------------------------------------------------------------------------------------------
def write_transfer(ob, result, summary_fields: dict, settings: bake.BakeSettings):
    """Replaces any previous bake on the object's mesh: attributes first, metadata last."""
    mesh = ob.data
    remove_transfer(mesh)
    order = settings.order
    planes = _channel_planes(result.transfer)
    for letter, plane in planes:
        names = coefficient_attribute_names(order, letter)
        padded = np.zeros((len(mesh.vertices), 3 * len(names)), dtype=np.float32)
        padded[:, : order * order] = plane
        for j, name in enumerate(names):
            mesh.attributes.new(name, "FLOAT_VECTOR", "POINT")
            # Look the attribute up by name again: adding attributes can invalidate earlier references.
            mesh.attributes[name].data.foreach_set("vector", np.ascontiguousarray(padded[:, 3 * j: 3 * j + 3]).ravel())
    mesh.attributes.new(ERROR_ATTRIBUTE, "FLOAT", "POINT")
    mesh.attributes[ERROR_ATTRIBUTE].data.foreach_set("value", result.rel_error.astype(np.float32))
    mesh[METADATA_KEY] = {
        "order": order,
        "mode": settings.mode,
        "channels": len(planes),
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
    """(V, n²) grey or (V, 3, n²) coloured float32 transfer and the metadata; raises StaleBake when it no
    longer fits the mesh."""
    if METADATA_KEY not in mesh:
        raise StaleBake(f"mesh {mesh.name!r} has no PRT bake")
    meta = mesh[METADATA_KEY].to_dict()
    if meta.get("convention") != bake.CONVENTION_VERSION:
        raise StaleBake(f"mesh {mesh.name!r} was baked with layout version {meta.get('convention')}; rebake it")
    if meta["vertex_count"] != len(mesh.vertices):
        raise StaleBake(f"mesh {mesh.name!r} was baked with {meta['vertex_count']} vertices but now has "
                        f"{len(mesh.vertices)}; rebake it")
    order, letters = meta["order"], CHANNEL_LETTERS[meta.get("channels", 1)]
    planes = [_read_plane(mesh, order, letter) for letter in letters]
    return (planes[0] if len(planes) == 1 else np.ascontiguousarray(np.stack(planes, axis=1))), meta


def _read_plane(mesh, order, letter) -> np.ndarray:
    names = coefficient_attribute_names(order, letter)
    missing = [n for n in names if n not in mesh.attributes]
    if missing:
        raise StaleBake(f"mesh {mesh.name!r} lost its PRT attributes {', '.join(missing)}; rebake it")
    columns = np.empty((len(names), len(mesh.vertices) * 3), dtype=np.float32)
    for j, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("vector", columns[j])
    transfer = columns.reshape(len(names), -1, 3).transpose(1, 0, 2).reshape(len(mesh.vertices), -1)
    return np.ascontiguousarray(transfer[:, : order * order])
