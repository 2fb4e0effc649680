"""A mesh's arrays as numpy reads them: positions, vertex and corner normals, corner vertices, triangles. Every
reader of mesh data in the add-on goes through these (contiguous float64 / int arrays via foreach_get)."""

import numpy as np


def mesh_positions(mesh) -> np.ndarray:
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", positions)
    return positions.reshape(-1, 3)


def mesh_vertex_normals(mesh) -> np.ndarray:
    normals = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertex_normals.foreach_get("vector", normals)
    return normals.reshape(-1, 3)


def mesh_triangles(mesh, of: str = "vertices") -> np.ndarray:
    """(T, 3) the triangles' vertices, or with of="loops" their face corners."""
    mesh.calc_loop_triangles()
    triangles = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get(of, triangles)
    return triangles.reshape(-1, 3)


def mesh_corner_vertices(mesh) -> np.ndarray:
    """(C,) each face corner's vertex."""
    return _per_corner(mesh, "vertex_index")


def mesh_corner_normals(mesh) -> np.ndarray:
    """(C, 3) the normal Blender shades each face corner with (flat faces, sharp edges, custom normals)."""
    normals = np.empty(len(mesh.loops) * 3, dtype=np.float64)
    mesh.corner_normals.foreach_get("vector", normals)
    return normals.reshape(-1, 3)


def mesh_corner_edges(mesh) -> np.ndarray:
    """(C,) each face corner's edge, to its face's next corner."""
    return _per_corner(mesh, "edge_index")


def _per_corner(mesh, name: str) -> np.ndarray:
    values = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get(name, values)
    return values


def mesh_edge_vertices(mesh) -> np.ndarray:
    edge_vertices = np.empty(len(mesh.edges) * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", edge_vertices)
    return edge_vertices.reshape(-1, 2)
