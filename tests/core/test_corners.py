"""Shading points from face corners, against meshes whose corner normals are known by construction."""

import numpy as np

from prt_addon.core.corners import (against_faces, clip_planes, first_triangle_normals, flat_shading_normals, on_fins,
                                    shading_points,
                                    unsplit_points)

# A unit cube, flat-shaded: 8 vertices, 6 quads, 24 corners; each vertex touches 3 faces with 3 normals.
CUBE_FACES = {(0, 0, -1): (0, 2, 3, 1), (0, 0, 1): (4, 5, 7, 6), (0, -1, 0): (0, 1, 5, 4),
              (0, 1, 0): (2, 6, 7, 3), (-1, 0, 0): (0, 4, 6, 2), (1, 0, 0): (1, 3, 7, 5)}


def flat_cube():
    corner_vertices = np.array([v for face in CUBE_FACES.values() for v in face])
    corner_normals = np.array([normal for normal, face in CUBE_FACES.items() for _ in face], dtype=float)
    return corner_vertices, corner_normals


def test_a_flat_cube_has_three_points_per_vertex_each_with_its_faces_normal():
    corner_vertices, corner_normals = flat_cube()
    points = shading_points(corner_vertices, corner_normals, 8)
    assert len(points.point_vertices) == 24 and points.split_vertices == 8 and points.extra_points == 16
    np.testing.assert_array_equal(points.point_vertices[:8], np.arange(8))
    np.testing.assert_array_equal(points.point_vertices[points.corner_points], corner_vertices)
    np.testing.assert_array_equal(points.point_normals[points.corner_points], corner_normals)
    assert len(np.unique(points.corner_points)) == 24  # no two faces share a point


def test_corners_with_one_normal_are_one_point_and_the_vertices_keep_their_indices():
    corner_vertices, _ = flat_cube()
    smooth = np.array([[1.0, 2.0, 3.0]])[[0] * 24] / np.sqrt(14.0)
    wobble = smooth + 1e-7 * np.random.default_rng(1).standard_normal(smooth.shape)  # float32 round-off
    points = shading_points(corner_vertices, wobble, 8)
    assert len(points.point_vertices) == 8 and points.split_vertices == 0
    np.testing.assert_array_equal(points.corner_points, corner_vertices)


def test_a_split_vertex_keeps_the_normal_of_its_first_corner_as_its_own_point():
    """Vertex 0 has corners 0 and 2 facing +z and corner 1 facing +x; vertex 1 one corner; vertex 2 none."""
    corner_vertices = np.array([0, 0, 0, 1])
    normals = np.array([[0, 0, 1], [1, 0, 0], [0, 0, 1], [0, 1, 0]], dtype=float)
    points = shading_points(corner_vertices, normals, 3)
    np.testing.assert_array_equal(points.corner_points, [0, 3, 0, 1])
    np.testing.assert_array_equal(points.point_vertices, [0, 1, 2, 0])
    np.testing.assert_array_equal(points.point_normals, [[0, 0, 1], [0, 1, 0], [0, 0, 0], [1, 0, 0]])
    assert points.split_vertices == 1


def test_unsplit_points_are_what_grouping_gives_when_every_corner_has_its_vertexs_normal():
    """Vertex 4 has no corner: a zero normal, as shading_points gives it."""
    rng = np.random.default_rng(3)
    vertex_normals = rng.standard_normal((5, 3))
    vertex_normals /= np.linalg.norm(vertex_normals, axis=1, keepdims=True)
    corner_vertices = np.array([0, 1, 2, 2, 3, 1, 0, 3, 2])
    grouped = shading_points(corner_vertices, vertex_normals[corner_vertices], 5)
    unsplit = unsplit_points(corner_vertices, vertex_normals)
    for field in ("corner_points", "point_vertices", "point_normals"):
        np.testing.assert_array_equal(getattr(unsplit, field), getattr(grouped, field))
    assert unsplit.vertex_count == 5 and unsplit.extra_points == 0 and not unsplit.point_normals[4].any()


def test_a_corner_whose_normal_points_against_its_first_triangle_is_against_its_face():
    """Two triangles of a unit square in z = 0, of corners (0, 1, 2) wound up and (3, 4, 1) wound down; corners 5
    and 6 on none. Every corner's normal is +z, except corner 4's, tilted 100° from +z: its z, -0.17, goes with the
    second triangle's -z. Corner 1 lies on both, and is sampled on the first, which it goes with."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    triangles = np.array([[0, 1, 2], [3, 4, 1]])
    normals = np.tile([0.0, 0.0, 1.0], (7, 1))
    normals[4] = [np.sin(np.radians(100.0)), 0.0, np.cos(np.radians(100.0))]
    np.testing.assert_array_equal(against_faces(normals, first_triangle_normals(positions, triangles)), [0, 0, 0, 1, 0, 0, 0])


def test_corners_against_their_faces_are_points_apart_from_the_corners_with_their_normal():
    """Vertex 0's corners 0 and 1 share a normal, corner 1 against its face; vertex 1's two corners agree: vertex 0
    becomes two points (the second marked against), vertex 1 one."""
    corner_vertices = np.array([0, 0, 1, 1])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    points = shading_points(corner_vertices, normals, 2, np.array([False, True, False, False]))
    np.testing.assert_array_equal(points.corner_points, [0, 2, 1, 1])
    np.testing.assert_array_equal(points.against, [False, False, True])
    assert shading_points(corner_vertices, normals, 2, np.zeros(4, dtype=bool)).against is None


def test_corners_at_a_vertex_of_an_edge_of_three_faces_are_points_of_their_own_face_plane():
    """Three quads share the edge of vertices 0-1 (a fin on a sheet's fold), one averaged normal at every corner:
    vertices 0 and 1 become a point per face plane, each clipped by it; the outer vertices stay unsplit, unclipped."""
    # quads (0 1 2 3), (1 0 4 5), (0 1 6 7); edges numbered as a mesh would: 0-1 is edge 0, held by all three
    faces = [(0, 1, 2, 3), (1, 0, 4, 5), (0, 1, 6, 7)]
    corner_vertices = np.array([v for face in faces for v in face])
    edges = {}
    for face in faces:
        for k in range(4):
            edges.setdefault(tuple(sorted((face[k], face[(k + 1) % 4]))), len(edges))
    corner_edges = np.array([edges[tuple(sorted((face[k], face[(k + 1) % 4])))] for face in faces for k in range(4)])
    edge_vertices = np.array(list(edges))
    fins = on_fins(corner_vertices, corner_edges, edge_vertices)
    np.testing.assert_array_equal(fins, np.isin(corner_vertices, [0, 1]))
    planes = np.repeat(np.eye(3), 4, axis=0)  # each quad's own plane, as first_triangle_normals gives it
    clip = np.where(fins[:, None], planes, 0.0)
    points = shading_points(corner_vertices, np.tile([1.0, 1.0, 1.0], (12, 1)) / np.sqrt(3), 8, None, clip)
    assert points.extra_points == 4 and points.split_vertices == 2
    np.testing.assert_array_equal(points.clip[points.corner_points], clip)
    np.testing.assert_array_equal(points.point_vertices[points.corner_points], corner_vertices)


def test_corners_against_their_faces_are_points_of_their_own_face_clipped_by_it_reversed():
    """Vertex 0's three corners share a normal (up) and are all against their faces, 170°, 120° and 180° from their
    face normals: Cycles shades each from behind, clipped by its own face reversed, so each is a point of its own
    with its unit −Ng as its clip. Vertex 1's corner, 10° from its face, on a fin, is clipped by its face as it is."""
    corner_vertices = np.array([0, 0, 0, 1])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    angles = np.radians([170.0, 120.0, 180.0, 10.0])
    unit = np.stack([np.sin(angles), np.zeros(4), np.cos(angles)], axis=1)
    faces = 2.0 * unit  # not unit, as first_triangle_normals gives them
    against = against_faces(normals, faces)
    clip = clip_planes(faces, against, np.array([False, False, False, True]))
    np.testing.assert_allclose(clip, np.concatenate([-unit[:3], unit[3:]]), atol=1e-15)
    points = shading_points(corner_vertices, normals, 2, against, clip)
    np.testing.assert_array_equal(points.corner_points, [0, 2, 3, 1])
    np.testing.assert_array_equal(points.against, [True, False, True, True])
    np.testing.assert_allclose(points.clip[points.corner_points], clip)
    assert clip_planes(faces, np.zeros(4, dtype=bool), np.zeros(4, dtype=bool)) is None



def test_a_flat_faces_corners_take_their_own_triangles_normal_where_the_face_is_not_planar():
    """A quad folded along its diagonal 0-2 (vertex 3 lifted): Blender gives its four corners the mean plane's
    normal; Cycles shades each triangle with its own. Corners 0, 1, 2 are held first by the triangle (0, 1, 2), whose
    normal is +Z; corner 3 only by (0, 2, 3), tilted towards −Y. The same quad flat keeps Blender's normals, bits
    and all."""
    folded = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.5]])
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    mean = np.tile(np.cross(folded[2] - folded[0], folded[3] - folded[1]), (4, 1))
    mean /= np.linalg.norm(mean, axis=1, keepdims=True)
    found = flat_shading_normals(mean, first_triangle_normals(folded, triangles))
    tilted = np.cross(folded[2] - folded[0], folded[3] - folded[0])
    np.testing.assert_allclose(found, [[0, 0, 1]] * 3 + [tilted / np.linalg.norm(tilted)], atol=1e-15)
    flat = folded * [1, 1, 0]
    plane = np.tile([0.0, 0.0, 1.0 - 1e-9], (4, 1))  # Blender's float normal, a hair off the triangles' exact one
    assert (flat_shading_normals(plane, first_triangle_normals(flat, triangles)) == plane).all()
