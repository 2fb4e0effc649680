"""Rays known blocked without a cast: a shared ray group's rays that surely cross a triangle of its vertex's ring
(the occluder triangles that meet the vertex, core.contact) count as blocked. A shadowed bake needs no hit but
whether there is one: 8.6 % of the flat-shaded cow's rays are known so."""

import numpy as np

from . import arrays

RING_MARGIN = 1e-4  # radians: a ray this near a ring triangle's edge or plane is cast, not predicted (ring_planes)


def ring_planes(caster, origins, ring):
    """(c, 4F, 3) float32 planes through each origin (c, 3) that tell which of its rays surely cross a triangle
    of its `ring` (c, F; −1 for none): a ray ω does where ω·P < −1 for all four of the triangle's planes P. Three
    are the planes through the origin and each edge, the fourth the triangle's own, each facing so that a ray
    crossing it from the origin's side lies below it, and scaled so that −1 leaves a margin of RING_MARGIN
    radians: rays that nearly graze an edge or the triangle are cast. The origins are taken in float32 as the
    engine casts from them, and the corners as it holds them (`caster`'s single_vertices). A triangle with the
    origin on its plane (or a padding one) has zero planes, which no ray passes."""
    corners_ = caster.single_vertices[caster.triangles[np.maximum(ring, 0)]].astype(np.float64)
    # coordinate-major (3, c, F, corner): the cross products by hand are several times faster than np.cross
    to_corners = np.moveaxis(corners_ - origins.astype(np.float32).astype(np.float64)[:, None, None], -1, 0)
    planes = np.empty((3,) + ring.shape + (4,))
    planes[..., :3] = _cross(to_corners, to_corners[..., [1, 2, 0]])
    planes[..., 3] = _cross(to_corners[..., 1] - to_corners[..., 0], to_corners[..., 2] - to_corners[..., 0])
    height = -(planes[..., 3] * to_corners[..., 0]).sum(axis=0)  # the origin over the triangle's plane
    side = np.where((ring >= 0) & (np.abs(height) > 0.0), np.sign(height), 0.0)
    size = np.sqrt((planes * planes).sum(axis=0))
    planes *= side[..., None] / np.maximum(RING_MARGIN * size, 1e-300)
    return np.moveaxis(planes, 0, -1).reshape(len(ring), -1, 3).astype(np.float32)


def _cross(a, b):
    """Cross products of coordinate-major vectors (3, ...)."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def by_ring_size(sets, ring_sizes):
    """`sets` with each set of shared groups in order of its groups' ring sizes (triangles per row (c,)): a round
    tests a group's rays against as many triangles as the widest ring in its batch, so batches pad less. Each
    group's estimate is its own: the order changes none."""
    return [members[np.argsort(ring_sizes[members[:, 0]], kind="stable")] if members.shape[1] > 1 else members
            for members in sets]


def shared_ring_planes(caster, sets, origins, ring, ring_sizes):
    """The ring planes (ring_planes) of each shared ray group (k > 1), at its first row: (planes (c, 4F, 3), zero
    elsewhere; its ring's triangles (c,), from `ring_sizes`, zero elsewhere). None without a shared group with a
    ring."""
    heads = [members[:, 0] for members in sets if members.shape[1] > 1]
    if not heads or not ring.size:
        return None
    heads = np.concatenate(heads)
    planes = np.zeros((len(ring), 4 * ring.shape[1], 3), dtype=np.float32)
    planes[heads] = ring_planes(caster, origins[heads], ring[heads])
    triangles = np.zeros(len(ring), dtype=np.int64)
    triangles[heads] = ring_sizes[heads]
    return planes, triangles


def group_ring_planes(rings, heads):
    """The ring planes of the groups whose first rows are `heads` (from `rings`, shared_ring_planes'), as wide as
    their widest ring; None if none has one (or `rings` is None)."""
    if rings is None:
        return None
    planes, triangles = rings
    width = triangles[heads].max()
    return planes[heads, :4 * width] if width else None


def surely_hit(planes, coordinates):
    """(g, n) bool: which rays of g groups (coordinates (g, 3, n)) surely hit a triangle that meets their origin's
    vertex (`planes` (g, 4F, 3) of ring_planes), in products small enough for one thread."""
    groups, faces, count = len(planes), planes.shape[1] // 4, coordinates.shape[2]
    hit = np.zeros((groups, count), dtype=bool)
    step = max(1, arrays.SINGLE_THREAD_PRODUCT // max(1, 3 * planes.shape[1]))
    for first in range(0, count, step):
        part = slice(first, first + step)
        below = (np.matmul(planes, coordinates[:, :, part]) < -1.0).reshape(groups, faces, 4, -1)
        hit[:, part] = (below[:, :, 0] & below[:, :, 1] & below[:, :, 2] & below[:, :, 3]).any(axis=1)
    return hit
