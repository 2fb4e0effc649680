"""Where a point lies against another surface: the occluder faces it touches and faces, whether it lies on one, and
the occluder triangles that meet its vertex (its ring), from the ray engine's search for faces near a point.

A point whose face touches another surface that it faces (an object resting on a floor) is in contact: Cycles'
rays from it meet that surface at once wherever they cross it. Lying on it (a little inside the point's own face
is on that surface), every ray does: the point is black. Touching it at an angle, the rays start in front of both
(core.estimator)."""

import numpy as np

from . import corners

# Faces count as facing when their normals are at least this far from perpendicular.
FACING_COSINE = -0.05
ON_SURFACE = 0.01  # of the ray offset: how far from a surface a point still lies on it
# Lying on a surface takes facing it within 8°: a face at a steeper angle touches it along an edge only, and sees
# past it (1 + n·n_s)/2 of the sky in Cycles (docs/cycles_conventions.md, R6), a sliver narrower than a step
# included: its step cannot leave the surface it stands on.
LYING_COSINE = -0.99
TOUCH_REACH = 2.0  # of the ray offset: surfaces this near a point's vertex are touched (its origins lie within it)


def touched_surfaces(caster, surface, normals: np.ndarray, steps: np.ndarray):
    """(normals (c, 3), lying (c,) bool, ring (c, F)): the normal of the occluder face that each point faces most
    among those it touches (zero where there is none), whether it lies on a face it faces, and the occluder
    triangles that meet its vertex (padded with −1), for points at `surface` (c, 3) in the frame of `caster`
    (core.ray_caster.RayCaster). A point is judged a step into its own faces, at `surface` + offset · `steps` (along
    the faces: a step tangent to a leaning normal would dip under a floor the vertex rests on). It touches a face it
    faces, with that step on the face's front side, that lies within one offset of the step (a fold of its own
    surface over it, a floor under it) or, unless the face meets the point's vertex (has a corner at its position),
    within TOUCH_REACH offsets of the vertex: a cone's apex (a sphere's pole on a floor) steps straight up, out of
    the floor's reach, and the faces meeting at a vertex are its own surface, not one it touches. It lies on a face
    within ON_SURFACE offsets of its step that it faces within 8° (LYING_COSINE). The corner points of one vertex
    share the search at the vertex, which also picks the points searched at their step (those facing some face near
    their vertex)."""
    offset = caster.offset
    stepped = surface + offset * steps
    row, face, location, face_normal, own, triangle = _near_vertices(caster, surface)
    ring = _padded_rows(row[own[face]], triangle[face[own[face]]], len(surface))
    dots = np.einsum("ij,ij->i", face_normal[face], normals[row])
    facing = dots < FACING_COSINE
    # Only a face it faces and does not meet can be touched from a point's vertex: the rest need no location.
    kept = np.flatnonzero(facing & ~own[face])
    in_front = np.einsum("ij,ij->i", stepped[row[kept]] - location[face[kept]], face_normal[face[kept]])
    kept = kept[in_front > -ON_SURFACE * offset]
    searched = np.unique(row[facing])
    near = caster.engine.nearest(stepped[searched], offset)
    at = searched[near.point]
    near_normal = near.normal if caster.against is None else np.where(
        _shaded_against(caster, near.triangle, surface[at])[:, None], -near.normal, near.normal)
    near_dots = _single_dots(near_normal, normals[at])
    # one ndarray.dot per face, whose BLAS sum rounds as no array expression here does: the same bits as always
    heights = np.array([(point - nearest).dot(normal)
                        for point, nearest, normal in zip(stepped[at], near.location, near_normal)])
    touches = (near_dots < FACING_COSINE) & (heights > -ON_SURFACE * offset)
    lying = np.zeros(len(surface), dtype=bool)
    lying[at[touches & (near.distance <= ON_SURFACE * offset) & (near_dots < LYING_COSINE)]] = True
    row = np.concatenate([row[kept], at[touches]])
    dots = np.concatenate([dots[kept], near_dots[touches]])
    normals_there = np.concatenate([face_normal[face[kept]], near_normal[touches]])
    touched = np.zeros_like(normals)
    most = np.lexsort((dots, row))  # each row's most facing face first
    first = most[np.r_[True, row[most][1:] != row[most][:-1]]] if len(row) else most
    touched[row[first]] = normals_there[first]
    return touched, lying, ring


def _near_vertices(caster, surface):
    """Every occluder face within TOUCH_REACH offsets of each row's position (c, 3), one search per distinct
    position: (row (P,), face (P,)) pairs, sorted by row, and per face found (F,): its nearest point (F, 3),
    normal (F, 3), own (F,) bool (the face has a corner at the position) and triangle (F,)."""
    # Rows at one position are one place; the order of places does not matter, since each row's faces are
    # listed in its place's search order.
    first, place_of_row = corners.unique_rows(surface)
    places = surface[first] + 0.0
    near = caster.engine.nearest(places, TOUCH_REACH * caster.offset)
    counts = np.bincount(near.point, minlength=len(places))
    face_corners = caster.vertices[caster.triangles[near.triangle]]  # (F, 3, 3)
    same = face_corners == np.repeat(places, counts, axis=0)[:, None]
    corner_there = same[..., 0] & same[..., 1] & same[..., 2]  # (a reduction over 3 is slower)
    own = corner_there[:, 0] | corner_there[:, 1] | corner_there[:, 2]
    # Each row meets its place's faces: a place's first face and count locate them.
    per_row = counts[place_of_row]
    row = np.repeat(np.arange(len(surface)), per_row)
    first_face = np.r_[0, np.cumsum(counts)[:-1]]
    face = np.repeat(first_face[place_of_row] - np.r_[0, np.cumsum(per_row)[:-1]], per_row) + np.arange(len(row))
    return row, face, near.location, near.normal, own, near.triangle


def _shaded_against(caster, triangles, vertices) -> np.ndarray:
    """(n,) bool: each of `triangles` (n,) has its corner at the point's vertex (`vertices` (n, 3)) on a point
    whose normal points against the face (caster.against): Cycles shades that corner from behind the winding, and
    its rays hit faces whatever their winding, so the face turns to a point of that vertex the side its shading
    normal gives it. Else a neighbour wound inward under an outward normal (an OBJ's) would seem to face every
    point around it, and they would seem to touch it."""
    corners_ = caster.triangles[triangles]  # (n, 3)
    same = caster.vertices[corners_] == vertices[:, None]
    return (same[..., 0] & same[..., 1] & same[..., 2] & caster.against[corners_]).any(axis=1)


def _single_dots(first, second) -> np.ndarray:
    """(n,) dot products of rows (n, 3) as the contact rule takes them at a point's step: float32 products summed
    in float64 from the last coordinate (mathutils' Vector.dot), so that a bake stays bit for bit the same."""
    products = (first.astype(np.float32) * second.astype(np.float32)).astype(np.float64)
    return (products[:, 2] + products[:, 1]) + products[:, 0]


def _padded_rows(rows, values, count):
    """(count, K) of `values` listed by their `rows` (sorted), each row's padded to the longest with −1."""
    per_row = np.bincount(rows, minlength=count)
    padded = np.full((count, per_row.max(initial=0)), -1, dtype=np.int64)
    padded[rows, np.arange(len(rows)) - np.repeat(np.cumsum(per_row) - per_row, per_row)] = values
    return padded
