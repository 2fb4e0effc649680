"""Flat convex occluders in closed form: the transfer they block, and which rays they stop.

The long straight edges of a floor, a wall or a ground plane are where a ray estimator's error comes from. For a
convex polygon P seen from a vertex, the transfer P blocks, G_k = (1/π) ∫ over P's directions above the tangent
plane of (n·ω) Y_k(ω) dω, has a closed form (axial moments over a spherical polygon, Arvo 1995, with each SH band
written as a sum of zonal lobes, Wang & Ramamoorthi 2018), and whether a ray's direction hits P is a few dot
products. The bake then sends rays only for what P does not explain (core.estimator), so P's edges add no noise.
"""

from functools import lru_cache
import math

import numpy as np
from numpy.polynomial import legendre

from . import arrays, lobes, sh

# Detection: coplanar to this fraction of the object's size, and its triangles cover their convex hull to this
# fraction of its area (a hole or a notch would only cost accuracy, never correctness, but then gains nothing).
PLANAR_TOLERANCE = 1e-6
COVER_TOLERANCE = 1e-6
MAX_EDGES = 16
# Polygons kept per bake, the largest first.
MAX_POLYGONS = 8


def convex_polygon(vertices, triangles):
    """(m, 3) corners, counter-clockwise about the triangles' common normal, of the convex polygon that these
    triangles exactly tile; None when they are not flat, do not face one way, or do not tile a convex polygon
    of at most MAX_EDGES corners. Vertices not used by a triangle count too (a flat object with stray points
    off its plane is not taken)."""
    if len(triangles) == 0 or not np.isfinite(vertices).all():
        return None
    low, high = arrays.bounds(vertices)
    size = float((high - low).max())
    # Most objects are not flat: a plane from a few triangles rejects them before any per-triangle work.
    guess, _ = _areas(vertices, triangles[:64])
    if not np.linalg.norm(guess) > 0.0 or np.abs(arrays.one_thread_product(vertices - vertices[0], guess)).max() \
            > PLANAR_TOLERANCE * size * np.linalg.norm(guess):
        return None
    total, area = _areas(vertices, triangles)
    if not area > 0.0 or 0.5 * np.linalg.norm(total) < (1.0 - COVER_TOLERANCE) * area:
        return None  # faces turned both ways
    normal = total / np.linalg.norm(total)
    heights = arrays.one_thread_product(vertices - vertices[0], normal)
    if np.abs(heights).max() > PLANAR_TOLERANCE * size:
        return None
    tangent = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    tangent /= np.linalg.norm(tangent)
    flat = arrays.one_thread_product(vertices - vertices[0], np.stack([tangent, np.cross(normal, tangent)], 1))
    hull = _convex_hull_2d(flat, tolerance=PLANAR_TOLERANCE * size)
    if not 3 <= len(hull) <= MAX_EDGES:
        return None
    x, y = flat[hull, 0], flat[hull, 1]
    hull_area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if abs(hull_area - area) > COVER_TOLERANCE * area:
        return None  # a hole, a notch or overlapping faces
    return vertices[hull] - np.outer(heights[hull], normal)  # exactly in one plane


def largest(candidates, count):
    """The `count` polygons of largest area: each costs a few dot products per ray."""
    return sorted(candidates, key=lambda polygon: -np.linalg.norm(_vector_area(polygon)))[:count]


def _areas(vertices, triangles):
    """(twice the vector area, the area) of triangles, in blocks to bound memory."""
    total, area = np.zeros(3), 0.0
    for part in np.array_split(triangles, max(1, len(triangles) >> 16)):
        a, b, c = (vertices[part[:, i]] for i in range(3))
        crosses = np.cross(b - a, c - a)
        total += crosses.sum(0)
        area += 0.5 * float(np.linalg.norm(crosses, axis=1).sum())
    return total, area


def _vector_area(polygon):
    """Twice the vector area of a flat polygon (m, 3): along its normal, counter-clockwise."""
    return _cross(polygon, np.roll(polygon, -1, axis=0)).sum(0)


def _convex_hull_2d(points, tolerance):
    """Indices of the convex hull's corners, counter-clockwise (Andrew's monotone chain), without the corners
    that stand less than `tolerance` off the line through their neighbours, so a tiled rectangle has four."""
    candidates = _outside_octagon(points)
    order = candidates[np.lexsort((points[candidates, 1], points[candidates, 0]))].tolist()
    chains = []
    for sequence in (order, order[::-1]):
        chain = []
        for i in sequence:
            while len(chain) >= 2 and _turn(points[chain[-2]], points[chain[-1]], points[i]) <= 0.0:
                chain.pop()
            chain.append(i)
        chains.append(chain[:-1])
    hull = chains[0] + chains[1]
    while len(hull) > 3:
        offsets = [_turn(points[hull[n - 1]], points[hull[n]], points[hull[(n + 1) % len(hull)]])
                   / math.dist(points[hull[n - 1]], points[hull[(n + 1) % len(hull)]]) for n in range(len(hull))]
        flattest = int(np.argmin(offsets))
        if offsets[flattest] >= tolerance:
            break
        del hull[flattest]
    return np.array(hull, dtype=np.int64)


def _outside_octagon(points):
    """Indices of the points not strictly inside the polygon of the extreme points in eight directions (Akl and
    Toussaint): only these can be hull corners, a few boundary points of a big flat grid instead of all."""
    angles = np.arange(8) * (np.pi / 4)
    extremes = np.argmax(points @ np.stack([np.cos(angles), np.sin(angles)]), axis=0)
    corners = points[extremes[np.sort(np.unique(extremes, return_index=True)[1])]]
    if len(corners) < 3:
        return np.arange(len(points))
    a, b = corners, np.roll(corners, -1, axis=0)
    turns = (b[:, 0] - a[:, 0]) * (points[:, 1, None] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (points[:, 0, None] - a[:, 0])
    return np.flatnonzero((turns <= 0.0).any(axis=1))


def _turn(a, b, c):
    """Twice the signed area of triangle abc: positive when it turns counter-clockwise."""
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def hits(directions, planes):
    """directions (c, k, 3), cone planes (c, P, m, 3) from cones_and_blocked_transfer → (c, k) int8: how many
    polygons each ray hits. Each polygon's sides are one batched matrix product with the directions (read as
    (c, 3, k): contiguous rows for component-major directions, as the bake makes them)."""
    count = np.zeros(directions.shape[:2], dtype=np.int8)
    across = directions.transpose(0, 2, 1)
    for polygon in range(planes.shape[1]):
        sides = np.matmul(planes[:, polygon], across)  # (c, m, k)
        inside = (sides >= 0.0).all(axis=1) & np.any(planes[:, polygon] != 0.0, axis=(1, 2))[:, None]
        count += inside
    return count


def cones_and_blocked_transfer(order, apexes, normals, polygons):
    """For apexes (c, 3) with unit normals (c, 3) and polygons (a list of (m, 3) corners):

    - (c, P, m, 3) cone planes: normals of the planes through each apex and each edge of each polygon, oriented
      so that a direction d points at the polygon exactly when d·plane ≥ 0 for all its edges; all zero where the
      apex lies in the polygon's plane (nothing points at it);
    - (c, order²) blocked transfer: G_k = (1/π) ∫ (n·ω)₊ Y_k(ω) dω over the directions from each apex that hit a
      polygon, summed over the polygons, all (vertex, polygon) pairs in one pass."""
    relative, side = _seen_from(apexes, polygons)
    planes = _cross(relative, np.roll(relative, -1, axis=2)) * side[..., None, None]
    return planes, _blocked_transfer(order, normals, relative, side)


def lune_transfer(order, normals, planes):
    """(c, order²): (1/π) ∫ (n·ω) Y_k(ω) dω over the directions in front of both each unit normal n (c, 3) and
    its plane's unit normal m (c, 3): the part of n's unshadowed transfer that a plane through the point leaves open, a
    lune of cosine-weighted share (1 + n·m)/2. Its corners, counter-clockwise from the centre, start at the middle
    of its edge on m's plane, then its tip −e, the middle of its edge on n's horizon, its tip e: so no edge spans
    half a circle, and the fan that measures its solid angle (_solid_angle) has no flat triangle."""
    normals, planes = np.asarray(normals, dtype=np.float64), np.asarray(planes, dtype=np.float64)
    tips = _cross(normals, planes)
    sines = np.linalg.norm(tips, axis=1)
    dots = np.einsum("ij,ij->i", normals, planes)
    # Else the plane is the tangent plane: the whole hemisphere in front of it, or none. A lune of dihedral angle δ
    # differs from those by O(δ²) in every band, so below 1e-6 rad (the float rounding of a normal taken twice from a
    # mesh, or of one exactly reversed) they are exact within 1e-10: black where Cycles reads 0.000 (R2).
    lune = sines > 1e-6
    out = lobes.cosine_transfer(order, normals) * (~lune & (dots > 0.0))[:, None]
    if lune.any():
        n, m, e = normals[lune], planes[lune], tips[lune] / sines[lune, None]
        # The middle of the edge on m's plane, on n's side (m × (n × m) = n − (n·m)m), and that of the edge on n's
        # horizon, on m's side: as cross products with e, which lose nothing where n and m nearly agree (a normal and
        # its own face's plane, each unit only to float32's rounding, whose difference n − (n·m)m is mostly that).
        across_m = _cross(m, e)
        across_n = _cross(e, n)
        out[lune] = _cosine_sh_integrals(order, np.stack([across_m, -e, across_n, e], axis=1), n) / np.pi
    return out


def _blocked_transfer(order, normals, relative, side):
    blocked = np.zeros((len(normals), order * order))
    seen = (side != 0) & (np.einsum("cpmj,cj->cpm", relative, normals) > 0.0).any(2)
    vertex, polygon = np.nonzero(seen)
    if not len(vertex):
        return blocked
    rows = relative[vertex, polygon]
    rows = np.where(side[vertex, polygon, None, None] < 0, rows[:, ::-1], rows)  # counter-clockwise from the apex
    clipped = _clip_to_half_space(rows, normals[vertex])
    length = np.linalg.norm(clipped, axis=-1, keepdims=True)
    unit = np.divide(clipped, length, out=np.zeros_like(clipped), where=length > 0)
    np.add.at(blocked, vertex, _cosine_sh_integrals(order, unit, normals[vertex]) / np.pi)
    return blocked


def _seen_from(apexes, polygons):
    """Corners relative to each apex (c, P, m, 3), padded to the most corners, and (c, P) the side each apex sees:
    +1 the polygon's back (its corners run counter-clockwise from the apex), −1 its front, 0 edge-on."""
    relative = _padded(polygons)[None] - apexes[:, None, None, :]
    facing = np.stack([_vector_area(polygon) for polygon in polygons])
    return relative, np.sign(np.einsum("cpj,pj->cp", relative[:, :, 0], facing))


def _padded(polygons):
    """(P, m, 3): every polygon with its last corner repeated up to the most corners (zero-length edges)."""
    most = max(len(polygon) for polygon in polygons)
    return np.stack([np.concatenate([polygon, np.repeat(polygon[-1:], most - len(polygon), axis=0)])
                     for polygon in polygons])


def _clip_to_half_space(points, normals):
    """Sutherland-Hodgman: each convex polygon (c, m, 3) cut to n·x ≥ 0, as (c, m + 1, 3) corners in order (one
    cut adds at most one corner), the last kept corner repeated in the slots left over (zero-length edges); all
    zero when nothing is left."""
    height = np.einsum("cmj,cj->cm", points, normals)
    following, following_height = np.roll(points, -1, axis=1), np.roll(height, -1, axis=1)
    inside, crosses = height >= 0.0, (height >= 0.0) != (following_height >= 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(crosses, height / (height - following_height), 0.0)
    cut = points + t[..., None] * (following - points)
    slots = np.stack([points, cut], axis=2).reshape(len(points), -1, 3)  # each corner, then its edge's cut
    keep = np.stack([inside, crosses], axis=2).reshape(len(points), -1)
    first = np.argsort(~keep, axis=1, kind="stable")[:, :points.shape[1] + 1]  # kept slots first, in order
    count = keep.sum(1)
    first = np.where(np.arange(first.shape[1]) < count[:, None], first,
                     np.take_along_axis(first, np.maximum(count - 1, 0)[:, None], axis=1))
    return np.take_along_axis(slots, first[..., None], axis=1) * (count > 0)[:, None, None]


def _cosine_sh_integrals(order, unit, normals):
    """(c, order²): ∫ (n·ω) Y_k(ω) dω over spherical polygons (c, m, 3), corners counter-clockwise seen from the
    centre, repeated corners allowed, each with its own n (c, 3). Band l is a combination of 2l + 1 zonal lobes
    P_l(w·ω) (addition theorem), each a polynomial in w·ω, so its integral is a sum of double-axis moments."""
    directions, lobes_to_sh, powers = _zonal_tables(order)
    moments = _cosine_moments(unit, normals, directions, order - 1)  # (c, D, order)
    out = np.empty((len(unit), order * order))
    start = 0
    for l in range(order):
        span = slice(start, start + 2 * l + 1)
        lobes = np.einsum("cdp,p->cd", moments[:, span], powers[l])  # ∫ (n·ω) P_l(w_j·ω) dω, (c, 2l + 1)
        out[:, l * l:(l + 1) * (l + 1)] = lobes @ lobes_to_sh[l]
        start += 2 * l + 1
    return out


def _cosine_moments(unit, normals, axes, degree):
    """(c, D, degree + 1): μ_p(w) = ∫ (n·ω)(w·ω)^p dω over each spherical polygon (c, m, 3) with its own n (c, 3),
    for axes w (D, 3).

    Arvo's recurrences over the edges, with n_i the unit normal of edge i's great circle (towards the inside) and
    F_i^j = ∫ (w·ω)^j along edge i (which has a recurrence of its own):
    axial moments τ_k = ∫ (w·ω)^k dω = ((k − 1) τ_{k−2} + Σ_i (w·n_i) F_i^{k−1}) / (k + 1), and
    double-axis moments μ_p = (p (n·w) τ_{p−1} + Σ_i (n·n_i) F_i^p) / (p + 2)."""
    start, end = unit, np.roll(unit, -1, axis=1)
    cross = _cross(start, end)
    sine = np.sqrt(np.sum(cross * cross, axis=-1))
    angle = np.arctan2(sine, np.sum(start * end, axis=-1))  # (c, m): F^0, the same for every axis
    edge_normal = np.divide(cross, sine[..., None], out=np.zeros_like(cross), where=sine[..., None] > 0)
    normal_along_axes = normals @ axes.T  # (c, D)
    normal_along_edges = np.einsum("cmj,cj->cm", edge_normal, normals)
    moments = np.empty(unit.shape[:1] + (len(axes), degree + 1))
    moments[..., 0] = 0.5 * np.einsum("cm,cm->c", normal_along_edges, angle)[:, None]
    if degree == 0:
        return moments
    # Along an edge w·ω = a cos φ + b sin φ, b the tangent leaving `start`; at its end, a_end and b_end. One
    # matrix product over all edges (a broadcast matmul would run one tiny product per edge).
    frames = np.stack([start, _cross(edge_normal, start), end, _cross(edge_normal, end), edge_normal])
    a, b, a_end, b_end, c = (frames.reshape(-1, 3) @ axes.T).reshape(frames.shape[:-1] + (len(axes),))
    sin_angle, cos_angle = np.sin(angle)[..., None], np.cos(angle)[..., None]
    edge = [None, a * sin_angle + b * (1.0 - cos_angle)]  # F^1; F^0 is `angle`
    radius_squared = a * a + b * b
    power, power_end = a, a_end  # a^(j−1), a_end^(j−1)
    for j in range(2, degree + 1):
        term = radius_squared * (angle[..., None] if j == 2 else edge[j - 2])
        term *= j - 1
        term -= power_end * b_end
        term += power * b
        term /= j
        edge.append(term)
        if j < degree:
            power, power_end = power * a, power_end * a_end
    axial = [_solid_angle(unit)[:, None], np.einsum("cmd,cm->cd", c, angle) / 2.0]  # τ_0, τ_1
    for k in range(2, degree):
        axial.append(((k - 1) * axial[k - 2] + np.einsum("cmd,cmd->cd", c, edge[k - 1])) / (k + 1))
    for p in range(1, degree + 1):
        along_edges = np.einsum("cm,cmd->cd", normal_along_edges, edge[p])
        moments[..., p] = (p * normal_along_axes * axial[p - 1] + along_edges) / (p + 2)
    return moments


def _cross(a, b):
    """Cross products along the last axis, without np.cross's axis shuffling (these arrays are small)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _solid_angle(unit):
    """(c,) solid angle of each spherical polygon, a fan of triangles from its first corner (Van Oosterom and
    Strackee's formula: exact for triangles up to a hemisphere)."""
    first = unit[:, :1]
    here, following = unit[:, 1:-1], unit[:, 2:]
    triple = np.sum(first * _cross(here, following), axis=-1)
    dots = 1.0 + np.sum(first * here + here * following + following * first, axis=-1)
    return 2.0 * np.arctan2(triple, dots).sum(1)


@lru_cache(maxsize=None)
def _zonal_tables(order):
    """Per band l < order: 2l + 1 lobe axes, the matrix taking the lobes' integrals to band l's, and P_l's
    monomial coefficients. The axes are a Fibonacci hemisphere turned to make the lobes' matrix best
    conditioned."""
    axes, to_sh, powers = [], [], []
    for l in range(order):
        count = 2 * l + 1
        best = None
        for turn in np.linspace(0.0, 1.0, 16, endpoint=False):
            candidate = _fibonacci_hemisphere(count, turn)
            matrix = (4.0 * np.pi / count) * sh.evaluate(order, candidate)[:, l * l:(l + 1) * (l + 1)]
            condition = np.linalg.cond(matrix)
            if best is None or condition < best[0]:
                best = (condition, candidate, matrix)
        axes.append(best[1])
        to_sh.append(np.linalg.inv(best[2]).T)  # lobes = M · I_l, so I_lᵀ = lobesᵀ · M⁻ᵀ
        power = np.zeros(order)
        power[:l + 1] = legendre.leg2poly(np.eye(l + 1)[l])
        powers.append(power)
    return np.concatenate(axes), to_sh, powers


def _fibonacci_hemisphere(count, turn):
    index = np.arange(count) + 0.5
    z = 1.0 - index / count  # one hemisphere: antipodal axes give the same lobe up to sign
    azimuth = 2.0 * np.pi * (index * (math.sqrt(5.0) - 1.0) / 2.0 + turn)
    radius = np.sqrt(1.0 - z * z)
    return np.stack([radius * np.cos(azimuth), radius * np.sin(azimuth), z], axis=1)
