"""Shading points: the face corners of a mesh grouped by the normal Blender shades them with.

Blender shades each face corner with its corner normal (flat faces, sharp edges, custom normals and Smooth by
Angle give a vertex's corners different normals), and Cycles evaluates a vertex-colour bake corner by corner. A
vertex whose corners share one normal is one point; a vertex whose corners have k distinct normals is k points,
each seen from its own faces. Points 0..V-1 are the vertices themselves (with the normal of their first corner),
points V.. the further normals of split vertices, so a mesh without splits has exactly its vertices as points.

Cycles clips each corner by its own face's plane (docs/cycles_conventions.md). Around a closed
surface the faces meeting at a vertex do that for one point; at a vertex of an edge with three or more faces (a fin on
a tube) the corners sharing one averaged normal lie on faces that block each other's sky: there each face plane's
corners are a point of their own, with that plane as its `clip`.

A corner whose normal points against its face (an OBJ's `vn` line against the face's winding) Cycles shades from
behind: it negates N and Ng (`shader_setup_from_ray`, intern/cycles/kernel/geom/shader_data.h, when Ng · view < 0,
the view being N in a bake) and gathers the directions in front of both, −N's clipped by the plane of −Ng, Ng that
of the corner's own face (the first triangle holding it, where the vertex-colour bake samples it:
`bake_targets_populate_pixels_color_attributes`, source/blender/editors/object/object_bake_api.cc). Such corners are
points of their own, marked `against`, one per face plane, with −Ng as their `clip` (clip_planes); the bake measures
them with the normal −N (core.estimator).
"""

from dataclasses import dataclass

import numpy as np

from . import sampling

# Normals are compared after rounding to this many decimals: corner normals Blender computes for one smooth fan are
# the same floats, and custom normals are stored quantised, so this only absorbs float32 round-off.
NORMAL_DECIMALS = 5
# Radians within which a flat face's triangle and its mean plane are one normal: well above float32 normals' rounding
# (about 1e-7), well below a non-planar face's fold (degrees on Blender's Suzanne).
FLAT_TOLERANCE = 1e-3


@dataclass
class ShadingPoints:
    corner_points: np.ndarray  # (C,) the point of each face corner
    point_vertices: np.ndarray  # (P,) the vertex of each point; the first V are 0..V-1
    point_normals: np.ndarray   # (P, 3) the corner normal each point is shaded with
    vertex_count: int
    against: np.ndarray | None = None  # (P,) bool: the point's corners' normal points against their faces; None: none
    # (P, 3) the unit normal whose plane clips the point's sky (its face's, reversed for a point against its face),
    # zero for none
    clip: np.ndarray | None = None

    @property
    def extra_points(self) -> int:
        return len(self.point_vertices) - self.vertex_count

    @property
    def split_vertices(self) -> int:
        """How many vertices have more than one point."""
        return len(np.unique(self.point_vertices[self.vertex_count:]))


def unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first (u,), inverse (n,)): where each distinct row of `rows` (n, d) first occurs, and each row's distinct
    row. Rows are compared as bytes (-0.0 made 0.0 first), 3-5× faster than np.unique's axis=0; the distinct rows
    come in no meaningful order."""
    keys = np.ascontiguousarray(rows + 0.0)
    _, first, inverse = np.unique(keys.view(np.dtype((np.void, keys.itemsize * keys.shape[1]))).ravel(),
                                  return_index=True, return_inverse=True)
    return first, inverse.ravel()


def first_triangle_normals(positions: np.ndarray, corner_triangles: np.ndarray) -> np.ndarray:
    """(C, 3) each corner's face normal Ng, not normalised: that of the first triangle (`corner_triangles` (T, 3) of
    corner indices, their vertices' `positions` given per corner (C, 3)) that holds the corner, where Cycles'
    vertex-colour bake samples it; zero for a corner on no triangle or on a zero-area one (whose Ng Cycles finds
    not a number: docs/cycles_conventions.md, R3)."""
    count = len(positions)
    corners_ = positions[corner_triangles]
    face_normals = np.cross(corners_[:, 1] - corners_[:, 0], corners_[:, 2] - corners_[:, 0])
    first = np.full(count, len(corner_triangles))
    np.minimum.at(first, corner_triangles.ravel(), np.repeat(np.arange(len(corner_triangles)), 3))
    found = np.zeros((count, 3))
    held = first < len(corner_triangles)
    found[held] = face_normals[first[held]]
    return found


def flat_shading_normals(corner_normals: np.ndarray, face_normals: np.ndarray) -> np.ndarray:
    """(C, 3) the normals Cycles shades the corners of a mesh whose faces are all flat (no smooth face, sharp edge
    or custom normal: Blender's normals domain FACE) with: each corner's triangle's own Ng (`face_normals`, from
    first_triangle_normals), where Blender gives every corner of a face its mean plane's normal. They differ on a
    non-planar face: Blender's own Suzanne, 13.1 % RMS against Cycles with the face's normal, 5.8 % with the
    triangle's (and 5.6 % triangulated). Where they agree within FLAT_TOLERANCE (a planar face), Blender's is kept,
    so a planar face's corners stay one point with their neighbours in its plane."""
    length = np.linalg.norm(face_normals, axis=1)
    unit = np.divide(face_normals, length[:, None], out=np.zeros_like(face_normals), where=length[:, None] > 0)
    differs = (length > 0) & (np.einsum("ij,ij->i", unit, corner_normals) < np.cos(FLAT_TOLERANCE))
    return np.where(differs[:, None], unit, corner_normals)


def against_faces(corner_normals: np.ndarray, face_normals: np.ndarray) -> np.ndarray:
    """(C,) bool: each corner's normal (C, 3) points against its face, N·Ng < 0 (first_triangle_normals)."""
    return np.einsum("ij,ij->i", corner_normals, face_normals) < 0.0


def clip_planes(face_normals: np.ndarray, against: np.ndarray, fins: np.ndarray) -> np.ndarray | None:
    """(C, 3) the unit normal whose plane clips each corner's sky, zero where none does (None: none does): a corner
    against its face (C,) is shaded from behind, clipped by its own face reversed (−Ng); one of an edge with three or
    more faces (`fins` (C,)) by its own face (Ng). `face_normals` (C, 3): first_triangle_normals."""
    if not (against.any() or fins.any()):
        return None
    unit = sampling.unit_or_zero(face_normals)
    return np.where(against[:, None], -unit, np.where(fins[:, None], unit, 0.0))


def on_fins(corner_vertices: np.ndarray, corner_edges: np.ndarray, edge_vertices: np.ndarray) -> np.ndarray:
    """(C,) bool: each corner's vertex (`corner_vertices` (C,)) ends an edge that three or more faces share, from
    each corner's edge (`corner_edges` (C,), the edge to the face's next corner) and the edges' vertices (E, 2)."""
    faces_per_edge = np.bincount(corner_edges, minlength=len(edge_vertices))
    on_fin = np.zeros(max(int(corner_vertices.max(initial=-1)) + 1, int(edge_vertices.max(initial=-1)) + 1), bool)
    on_fin[edge_vertices[faces_per_edge > 2].ravel()] = True
    return on_fin[corner_vertices]


def shading_points(corner_vertices: np.ndarray, corner_normals: np.ndarray, vertex_count: int,
                   against: np.ndarray | None = None, clip: np.ndarray | None = None) -> ShadingPoints:
    """Groups corners (C,) with normals (C, 3) into points, the corners `against` their faces (C,) bool apart from
    the others (None: none is), and those of each distinct `clip` plane (C, 3) unit normals (clip_planes), zero for
    corners not clipped (None: none is); a vertex without corners keeps a zero normal."""
    rounded = np.round(np.asarray(corner_normals, dtype=np.float64), NORMAL_DECIMALS) + 0.0  # -0.0 → 0.0
    keys = [corner_vertices.astype(np.float64), rounded] + ([] if against is None else [against.astype(np.float64)])
    keys += [] if clip is None else [np.round(clip, NORMAL_DECIMALS) + 0.0]
    # The order of the groups does not matter: points are numbered below.
    first_corner, group_of_corner = unique_rows(np.column_stack(keys))
    group_vertex = np.asarray(corner_vertices, dtype=np.int64)[first_corner]
    # Each vertex's group holding its lowest corner becomes the vertex's own point; the other groups follow.
    order = np.lexsort((first_corner, group_vertex))
    primary = np.zeros(len(first_corner), dtype=bool)
    primary[order[np.r_[True, group_vertex[order][1:] != group_vertex[order][:-1]]]] = True
    point_of_group = np.empty(len(first_corner), dtype=np.int64)
    point_of_group[primary] = group_vertex[primary]
    extra = np.flatnonzero(~primary)
    extra = extra[np.argsort(first_corner[extra], kind="stable")]
    point_of_group[extra] = vertex_count + np.arange(len(extra))
    point_vertices = np.concatenate([np.arange(vertex_count), group_vertex[extra]])
    point_normals = np.zeros((len(point_vertices), 3))
    point_normals[point_of_group] = np.asarray(corner_normals, dtype=np.float64)[first_corner]
    point_against = None
    if against is not None and against.any():
        point_against = np.zeros(len(point_vertices), dtype=bool)
        point_against[point_of_group] = against[first_corner]
    point_clip = None
    if clip is not None and clip.any():
        point_clip = np.zeros((len(point_vertices), 3))
        point_clip[point_of_group] = clip[first_corner]
    return ShadingPoints(point_of_group[group_of_corner], point_vertices, point_normals, vertex_count, point_against,
                         point_clip)


def unsplit_points(corner_vertices: np.ndarray, vertex_normals: np.ndarray) -> ShadingPoints:
    """shading_points for a mesh whose corners all have their vertex's normal (no vertex splits): the vertices,
    each with its vertex normal (zero without corners), without reading or grouping the corner normals."""
    count = len(vertex_normals)
    has_corners = np.bincount(corner_vertices, minlength=count)[:count] > 0
    return ShadingPoints(np.asarray(corner_vertices, dtype=np.int64), np.arange(count),
                         np.where(has_corners[:, None], vertex_normals, 0.0), count)


# The points of a split vertex share their rays when their normals all lie within 60° of the group's mean normal n̄: one
# ray origin then lies above all their tangent planes, and the cap that covers all their hemispheres (core.ray_groups)
# keeps each point's weights below (1 − s)² ≤ 3.5. Sharper creases (a cube's corners, a thin sheet's rim) part a
# vertex's points into several groups. 60° keeps the worst point's error at its lowest for nearly the fewest rays: on
# the flat-shaded cow at 256 samples, the rays for the smooth bake's estimated RMS error, relative, and the worst
# point's estimated error are 50° 1.289 (0.065), 60° 1.269 (0.065), 70° 1.261 (0.087), 90° 1.264 (0.109). Groups
# gather about their mean normal, not one corner's, so that a vertex's odd corners do not split off one by one.
SHARE_COSINE = float(np.cos(np.radians(60.0)))


def ray_groups(point_vertices: np.ndarray, point_normals: np.ndarray, vertex_count: int) -> np.ndarray:
    """(P,) labels, each a group's lowest point (a vertex's own point where it is in the group): a vertex's points
    form one group when their normals all lie within SHARE_COSINE of their mean, else they are parted (_parted).
    Normals may be in any frame that keeps angles (world space)."""
    labels = np.arange(len(point_vertices))
    mean = np.zeros((vertex_count, 3))
    np.add.at(mean, point_vertices, point_normals)
    mean /= np.maximum(np.linalg.norm(mean, axis=1, keepdims=True), 1e-300)
    spread = np.zeros(vertex_count, dtype=bool)
    spread[point_vertices[np.einsum("ij,ij->i", point_normals, mean[point_vertices]) < SHARE_COSINE]] = True
    whole = ~spread[point_vertices]
    labels[whole] = point_vertices[whole]
    parted = np.flatnonzero(~whole)  # in order of vertex, then point
    if len(parted):
        parted = parted[np.argsort(point_vertices[parted], kind="stable")]
        starts = np.flatnonzero(np.r_[True, np.diff(point_vertices[parted]) != 0])
        counts = np.diff(np.r_[starts, len(parted)])
        by_vertex = np.full((len(starts), counts.max()), -1)  # each parted vertex's points, padded with -1
        place = np.arange(len(parted)) - np.repeat(starts, counts)
        by_vertex[np.repeat(np.arange(len(starts)), counts), place] = parted
        labels[parted] = _parted(by_vertex, point_normals)[by_vertex >= 0]
    return labels


def _parted(points, normals):
    """(V, K) labels for each vertex's points (`points` (V, K), increasing, padded with -1; `normals` of every
    point), parting them into groups within SHARE_COSINE of their mean: the point with the most others within
    SHARE_COSINE of it gathers them, and those farthest from their mean leave one by one until all are within it;
    the rest are parted alike. A group's label is its lowest point. Every vertex is parted at once: a loop over the
    vertices would take most of the ray groups' time."""
    real = points >= 0
    rows = np.where(real, points, 0)
    normals = np.where(real[..., None], normals[rows], 0.0)  # (V, K, 3)
    near = np.einsum("vid,vjd->vij", normals, normals) >= SHARE_COSINE
    near |= np.eye(points.shape[1], dtype=bool)  # a zero normal (a degenerate face's) is a group of its own
    near &= real[:, :, None] & real[:, None, :]
    left, labels, every = real.copy(), np.full(points.shape, -1), np.arange(len(points))
    while left.any():
        gathered = near & left[:, None, :]
        members = gathered[every, np.argmax(gathered.sum(2) * left, axis=1)] & left.any(1)[:, None]
        while True:  # each vertex drops its member farthest from their mean until all are within it
            mean = (members[..., None] * normals).sum(1)
            mean /= np.maximum(np.linalg.norm(mean, axis=1), 1e-300)[:, None]
            cosines = np.where(members, np.einsum("vkd,vd->vk", normals, mean), np.inf)
            dropping = np.flatnonzero((members.sum(1) > 1) & (cosines.min(1) < SHARE_COSINE))
            if not len(dropping):
                break
            members[dropping, np.argmin(cosines[dropping], axis=1)] = False
        left &= ~members
        labels = np.where(members, np.where(members, rows, np.iinfo(np.int64).max).min(1)[:, None], labels)
    return labels
