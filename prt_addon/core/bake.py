"""Diffuse SH transfer per vertex: the exact unshadowed transfer and the shadowed estimator.

Transfer convention: T_k = (1/π) ∫ V(ω) max(n·ω, 0) Y_k(ω) dω, so radiance = albedo · Σ_k L_k T_k.

Shadowed estimator (what makes it cheap compared with the original program's uniform-sphere Monte Carlo):
- the unshadowed transfer is exact (closed form) and serves as a control variate:
  T ≈ β·T_unshadowed + mean over cosine-distributed rays of (V − β)·Y, β the vertex's visible fraction, so a
  vertex that sees the whole sky or none of it adds no noise, and one that provably sees the sky casts no ray;
- directions are a rank-1 lattice, Cranley-Patterson rotated per vertex and replicate, so R independent
  replicates give an honest standard error;
- with a target error, rounds double the rays per replicate until each vertex meets the target.
"""

from dataclasses import dataclass, field
from itertools import chain, repeat
from operator import is_not, itemgetter
import zlib

import numpy as np

from . import arrays, corners, interreflect, lobes, polygons, sampling, settings as spec, sh

MAX_REPLICATES = 16
# Random streams per vertex (rounds × replicates): MAX_ROUNDS rounds of at most 40 lattice sizes each.
STREAMS_PER_VERTEX = 4096
MAX_ROUNDS = 6
# Target-error schedule: this estimator's error falls about as rays^-0.79 (benchmarks/estimator_study.py), and a
# round is sized for the target ÷ 1.15 so most vertices finish in one extra round.
CONVERGENCE_RATE = 0.79
TARGET_MARGIN = 1.15
# Fixed chunk size: any split of chunks over workers does exactly the same arithmetic per chunk. 128 vertices
# spread each chunk's fixed numpy work over 32 k rays at 256 samples.
CHUNK_VERTICES = 128
# A chunk of shared ray groups takes this many times the groups: it runs a round per group size (about 3.4 on the
# flat-shaded cow, against 1 for vertices), each with the same fixed numpy work, and its rows are several per group.
# The flat cow's bake at 2: 0.95-1.00× (the medians of 24 pairs in one process, three runs on a noisy machine); at
# 256 groups for every chunk, the smooth cow's bake did not change (0.99×).
SHARED_CHUNK_FACTOR = 2
WEIGHT_BYTES_PER_BATCH = 1 << 20
# Basis values that _weighted_means evaluates at once: 4M values = 32 MB in float64 (16 MB for a shared group's
# float32, weight_dtype), whatever the order and rays.
REPLICATE_VALUES_AT_ONCE = 1 << 22
# Ray origins sit this fraction of the scene's diagonal above the surface: scale-free, and far above
# float32 rounding because the geometry is recentred on the scene's bounding box before the BVH is built.
OFFSET_FRACTION = 1e-5
# Version of the stored layout and conventions; bump when either changes (2: ray origins also move towards
# the inside of each vertex's faces, so a vertex on a seam is seen from its own side; 3: a vertex split by its
# corner normals is baked once per normal and stored per face corner, see blender/storage.py).
CONVENTION_VERSION = 3
# A point whose face touches another surface that it faces (an object resting on a floor) is in contact: Cycles'
# rays from it meet that surface at once wherever they cross it. Lying on it (a little inside the point's own
# face is on that surface), every ray does: the point is black. Touching it at an angle, the rays start in front
# of both. Faces count as facing when their normals are at least this far from perpendicular.
FACING_COSINE = -0.05
ON_SURFACE = 0.01  # of the ray offset: how far from a surface a point still lies on it
TOUCH_REACH = 2.0  # of the ray offset: surfaces this near a point's vertex are touched (its origins lie within it)
RING_MARGIN = 1e-4  # radians: a ray this near a ring triangle's edge or plane is cast, not predicted (ring_planes)


@dataclass
class BakeSettings:
    """What a bake computes; defaults and ranges are core.settings'."""
    order: int = spec.ORDER.default
    mode: str = spec.MODE.default
    samples: int = spec.SAMPLES.default
    target_error: float = spec.TARGET_ERROR.default
    max_samples: int = spec.MAX_SAMPLES.default
    # 4 replicates: error 1.4x smaller than 8 at 256 rays (each replicate's lattice is denser) and still an
    # honest estimate (benchmarks/bake.py); 2 under-reports.
    replicates: int = 4
    seed: int = spec.SEED.default
    bounces: int | None = None  # interreflected: a count, or None for 'auto' (until the tail < tolerance)
    bounce_tolerance: float = spec.BOUNCE_TOLERANCE.default

    def problems(self) -> list[str]:
        """Every reason these settings cannot bake, as sentences for the user."""
        found = [f"{setting.label.lower()} must be {setting.range_text()}{' or auto' if setting.auto else ''}, "
                 f"not {getattr(self, setting.name)!r}"
                 for setting in spec.BAKE if not setting.contains(getattr(self, setting.name))]
        if self.max_samples < self.samples:
            found.append(f"max samples ({self.max_samples}) must be at least samples ({self.samples})")
        most_replicates = min(MAX_REPLICATES, max(self.samples, spec.FEWEST_SAMPLES))  # each needs a ray
        if not 2 <= self.replicates <= most_replicates:
            found.append(f"replicates must be 2-{most_replicates}, not {self.replicates}")
        return found

    @property
    def points_per_replicate(self) -> int:
        return max(1, self.samples // self.replicates)


@dataclass
class Receiver:
    """One object's vertices in world space; `key` makes its random streams independent of other objects."""
    name: str
    positions: np.ndarray  # (V, 3) float64
    normals: np.ndarray    # (V, 3) float64, unit; zero rows are vertices without a surface
    key: int
    # (V, 3) unit tangents from each vertex towards the inside of its faces, zero where there is no inside:
    # a vertex on a seam where another surface stands is baked as seen from its own faces' side.
    inward: np.ndarray | None = None
    # (V,) rows with the same label share their rays (core.corners.ray_groups: the corner points of one vertex
    # whose hemispheres overlap); None: every row casts its own.
    ray_groups: np.ndarray | None = None
    # (V, 3) unit steps from each vertex into its faces along the surface itself (not tangent to the normal), zero
    # where there is none: where a point lies against another surface is judged a step along them. None: `inward`.
    surface_step: np.ndarray | None = None

    @staticmethod
    def key_for(name: str) -> int:
        return zlib.crc32(name.encode("utf-8"))


@dataclass
class Occluders:
    """Triangles that cast shadows, in world space, the points whose hull bounds them, and flat convex polygons
    among them whose shadows are integrated in closed form.

    The first `solved_vertices` vertices are those of the surfaces whose transfer the job solves, in the job's
    order: interreflection reads a hit triangle's corners as solved vertices, so it needs exactly that."""
    vertices: np.ndarray   # (P, 3) float64
    triangles: np.ndarray  # (T, 3) int
    hull: np.ndarray       # (H, 3) float64: any superset of the convex hull's vertices
    polygons: list = field(default_factory=list)  # (m, 3) float64 corners each; see polygons.py
    solved_vertices: int = 0
    _caster: "RayCaster | None" = field(default=None, init=False, repr=False, compare=False)

    def ray_caster(self) -> "RayCaster":
        """Their ray tree, built on the first call and kept: a bake's jobs share it, and so do processes forked
        afterwards."""
        if self._caster is None:
            self._caster = RayCaster(self)
        return self._caster

    @property
    def center(self) -> np.ndarray:
        if len(self.vertices) == 0:
            return np.zeros(3)
        low, high = arrays.bounds(self.vertices)
        return 0.5 * (low + high)

    @property
    def diagonal(self) -> float:
        if len(self.vertices) == 0:
            return 1.0
        low, high = arrays.bounds(self.vertices)
        return float(np.linalg.norm(high - low)) or 1.0


@dataclass
class ChunkResult:
    transfer: np.ndarray   # (c, n²) float64
    std_error: np.ndarray  # (c,) norm of the coefficients' standard error
    rays: np.ndarray       # (c,) rays cast from each vertex (its estimate also uses its ray group's)
    skipped: np.ndarray    # (c,) bool: exact without rays (provably unoccluded, or in contact)
    records: interreflect.HitRecords | None = None  # interreflected mode: blocked rays' hits (chunk-local rows)


def unshadowed_transfer(order: int, normals: np.ndarray) -> np.ndarray:
    """Exact, noise-free: the clamped cosine rotated to each normal; zero where the normal is zero."""
    return lobes.cosine_transfer(order, normals) * (np.abs(normals).sum(-1, keepdims=True) > 0)


def unshadowed_norm(order: int) -> float:
    """‖T_unshadowed‖, the same for every unit normal (addition theorem: Σ_m Y_lm(n)² = (2l+1)/4π):
    the scale of each vertex's relative error."""
    return float(np.linalg.norm(lobes.clamped_cosine_zonal(order)) / np.pi)


def provably_unoccluded(positions, normals, hull, offset) -> np.ndarray:
    """True where every occluder lies below the ray origins' plane, so no ray into the hemisphere can hit.

    The origin is `offset` above the tangent plane and every ray climbs away from it; the highest occluder
    point in the normal's direction is attained at a vertex of the occluders' convex hull.
    """
    if len(hull) == 0:
        return np.ones(len(positions), dtype=bool)
    # A chunk of corner points (1,500 rows × the cow's 145 hull points) is a product OpenBLAS would thread.
    highest = np.max(arrays.one_thread_product(normals, hull.T), axis=1)
    return highest - np.einsum("ij,ij->i", normals, positions) < 0.5 * offset


def _tree_normals(corners) -> np.ndarray:
    """(F, 3) the unit normals the ray tree gives for triangles (F, 3, 3), bit for bit: its float32 arithmetic
    (Blender's normal_tri_v3 on the float32 corners), which costs less than reading them from its results."""
    a, b, c = (corners[:, i].astype(np.float32) for i in range(3))
    first, second = a - b, b - c
    normal = np.stack([first[:, 1] * second[:, 2] - first[:, 2] * second[:, 1],
                       first[:, 2] * second[:, 0] - first[:, 0] * second[:, 2],
                       first[:, 0] * second[:, 1] - first[:, 1] * second[:, 0]], axis=1)
    length = np.sqrt((normal[:, 0] * normal[:, 0] + normal[:, 1] * normal[:, 1]) + normal[:, 2] * normal[:, 2])
    normal *= np.divide(np.float32(1.0), length, out=np.zeros_like(length), where=length > 1e-35 ** 0.5)[:, None]
    return normal.astype(np.float64)


def _vectors(vectors, count) -> np.ndarray:
    """(count, 3) float64 from an iterable of mathutils Vectors (float32: exact in float64)."""
    return np.fromiter(chain.from_iterable(vectors), dtype=np.float64, count=3 * count).reshape(count, 3)


class RayCaster:
    """A BVHTree over the occluders, recentred so float32 precision does not depend on where the scene is."""

    def __init__(self, occluders: Occluders):
        from mathutils import Vector  # with the BVH tree, the only non-numpy dependencies of the core
        from mathutils.bvhtree import BVHTree
        self._vector = Vector
        self.center, diagonal = occluders.center, occluders.diagonal  # each takes the vertices' bounds
        self.offset = OFFSET_FRACTION * diagonal
        self.max_distance = 2.0 * diagonal
        self.hull = occluders.hull - self.center
        self.vertices = occluders.vertices - self.center
        self.tree_vertices = self.vertices.astype(np.float32)  # as the tree holds them
        self.triangles = occluders.triangles
        self.polygons = [polygon - self.center for polygon in occluders.polygons]
        self.tree = BVHTree.FromPolygons(self.vertices.tolist(), self.triangles.tolist(), all_triangles=True)

    def occluded(self, origins: np.ndarray, directions: np.ndarray, hits: bool = False, live=None):
        """origins (c, 3), directions (c, k, 3) → (c, k) bool: did the ray hit anything; with `hits`, also the
        hit triangles (−1 for none) and distances (NaN for none). Given `live` (c, k) bool, only those rays are
        cast; the others count as missed."""
        c, k = directions.shape[:2]
        coordinates = directions.reshape(-1, 3).T  # (3, c·k): rows contiguous for component-major directions
        if live is None:
            per_origin = repeat(k)
        else:  # row by row: a boolean index on the second axis of the (3, c·k) view is 5× slower
            mask = live.ravel()
            coordinates = [row[mask] for row in coordinates]
            per_origin = np.count_nonzero(live, axis=1).tolist()
        casts = self._casts(origins, coordinates, per_origin)
        if not hits:  # a miss returns (None, None, None, None); bytes() collects the flags fastest
            found = np.frombuffer(bytes(map(is_not, map(itemgetter(3), casts), repeat(None))), dtype=bool)
            return _scattered(found, live, False).reshape(c, k)
        found = np.array(list(map(itemgetter(2, 3), casts)), dtype=np.float64).reshape(-1, 2)
        triangle = np.nan_to_num(found[:, 0], nan=-1.0).astype(np.int64)  # both NaN on a miss
        distance = _scattered(found[:, 1], live, np.nan).reshape(c, k)
        return ~np.isnan(distance), _scattered(triangle, live, -1).reshape(c, k), distance

    def _casts(self, origins, coordinates, per_origin):
        """ray_cast results of directions given by their coordinates (3 arrays of n), `per_origin` of them (counts)
        from each of the origins (c, 3) in turn, lazily, looped in C by map(). Directions are read one coordinate at
        a time through memoryviews, which make each float as the loop reaches it: 4 % of a bake's time less than
        building lists of them first. Each origin is a Vector, which ray_cast reads with a copy where a tuple is
        parsed float by float for every ray: 1.5 % of a ray's cost, and the same float32 values."""
        xs, ys, zs = map(memoryview, map(np.ascontiguousarray, coordinates))
        per_ray_origins = chain.from_iterable(map(repeat, map(self._vector, origins.tolist()), per_origin))
        return map(self.tree.ray_cast, per_ray_origins, zip(xs, ys, zs), repeat(self.max_distance))

    def touched_surfaces(self, surface, normals: np.ndarray, steps: np.ndarray):
        """(normals (c, 3), lying (c,) bool, ring (c, F)): the normal of the occluder face that each point faces most
        among those it touches (zero where there is none), whether it lies on a face it faces, and the occluder
        triangles that meet its vertex (padded with −1). A point is judged a step into its own faces, at `surface`
        (c, 3) + offset · `steps` (along the faces: a step tangent to a leaning normal would dip under a floor the
        vertex rests on). It touches a face it faces, with that step on the face's
        front side, that lies within one offset of the step (a fold of its own surface over it, a floor under it)
        or, unless the face meets the point's vertex (has a corner at its position), within TOUCH_REACH offsets of
        the vertex: a cone's apex (a sphere's pole on a floor) steps straight up, out of the floor's reach, and the
        faces meeting at a vertex are its own surface, not one it touches. It lies on a face within ON_SURFACE
        offsets of its step. The corner points of one vertex share the search at the vertex, which also picks the
        points searched at their step (those facing some face near their vertex)."""
        stepped = surface + self.offset * steps
        row, face, location, face_normal, own, triangle = self._near_vertices(surface)
        ring = _padded_rows(row[own[face]], triangle[face[own[face]]], len(surface))
        dots = np.einsum("ij,ij->i", face_normal[face], normals[row])
        facing = dots < FACING_COSINE
        # Only a face it faces and does not meet can be touched from a point's vertex: the rest need no location.
        kept = np.flatnonzero(facing & ~own[face])
        in_front = np.einsum("ij,ij->i", stepped[row[kept]] - location[face[kept]], face_normal[face[kept]])
        kept = kept[in_front > -ON_SURFACE * self.offset]
        rows, most_dots, normals_there = [row[kept]], [dots[kept]], [face_normal[face[kept]]]
        lying = np.zeros(len(surface), dtype=bool)
        for r in np.unique(row[facing]).tolist():
            point, normal = stepped[r], normals[r].tolist()  # Vector.dot reads a list fastest
            for nearest, normal_there, _, distance in self.tree.find_nearest_range(tuple(point), self.offset):
                dot = normal_there.dot(normal)
                if dot < FACING_COSINE and (point - np.asarray(nearest)).dot(normal_there) > -ON_SURFACE * self.offset:
                    rows.append([r])
                    most_dots.append([dot])
                    normals_there.append([normal_there])
                    lying[r] |= distance <= ON_SURFACE * self.offset
        row, dots = np.concatenate(rows), np.concatenate(most_dots)
        touched = np.zeros_like(normals)
        most = np.lexsort((dots, row))  # each row's most facing face first
        first = most[np.r_[True, row[most][1:] != row[most][:-1]]] if len(row) else most
        touched[row[first]] = np.concatenate(normals_there, dtype=np.float64).reshape(-1, 3)[first]
        return touched, lying, ring

    def _near_vertices(self, surface):
        """Every occluder face within TOUCH_REACH offsets of each row's position (c, 3), one search per distinct
        position: (row (P,), face (P,)) pairs, sorted by row, and per face found (F,): its nearest point (F, 3),
        normal (F, 3), own (F,) bool (the face has a corner at the position) and triangle (F,). Nearest points are
        read only for faces not own (zero for the own faces, which nothing measures from): most faces found are a
        vertex's own, and each value read from a search costs a Python object."""
        # Rows at one position are one place; the order of places does not matter, since each row's faces are
        # listed in its place's search order.
        first, place_of_row = corners.unique_rows(surface)
        places = surface[first] + 0.0
        near = list(map(self.tree.find_nearest_range, map(tuple, places.tolist()),
                        repeat(TOUCH_REACH * self.offset)))
        counts = np.fromiter(map(len, near), dtype=np.int64, count=len(near))
        found = list(chain.from_iterable(near))  # (location, normal, index, distance) per face, in place order
        index = np.fromiter(map(itemgetter(2), found), dtype=np.int64, count=len(found))
        face_corners = self.vertices[self.triangles[index]]  # (F, 3, 3)
        same = face_corners == np.repeat(places, counts, axis=0)[:, None]
        corner_there = same[..., 0] & same[..., 1] & same[..., 2]  # (a reduction over 3 is slower)
        own = corner_there[:, 0] | corner_there[:, 1] | corner_there[:, 2]
        normal = _tree_normals(face_corners)
        other = np.flatnonzero(~own)
        location = np.zeros_like(normal)
        location[other] = _vectors(map(itemgetter(0), map(found.__getitem__, other.tolist())), len(other))
        # Each row meets its place's faces: a place's first face and count locate them.
        per_row = counts[place_of_row]
        row = np.repeat(np.arange(len(surface)), per_row)
        first_face = np.r_[0, np.cumsum(counts)[:-1]]
        face = np.repeat(first_face[place_of_row] - np.r_[0, np.cumsum(per_row)[:-1]], per_row) + np.arange(len(row))
        return row, face, location, normal, own, index

    def ring_planes(self, origins, ring):
        """(c, 4F, 3) float32 planes through each origin (c, 3) that tell which of its rays surely cross a triangle
        of its `ring` (c, F; −1 for none): a ray ω does where ω·P < −1 for all four of the triangle's planes P. Three
        are the planes through the origin and each edge, the fourth the triangle's own, each facing so that a ray
        crossing it from the origin's side lies below it, and scaled so that −1 leaves a margin of RING_MARGIN
        radians: rays that nearly graze an edge or the triangle are cast. The origins are taken in float32 as the
        ray caster casts from them, and the corners as its tree holds them. A triangle with the origin on its plane
        (or a padding one) has zero planes, which no ray passes."""
        corners_ = self.tree_vertices[self.triangles[np.maximum(ring, 0)]].astype(np.float64)
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

    def front_hits(self, origins, directions, triangle, distance):
        """(barycentric (H, 3), front (H,) bool) for hits: the light leaving a surface is known on its front."""
        corners = self.vertices[self.triangles[triangle]]
        points = origins + distance[:, None] * directions
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        return interreflect.barycentric(points, corners), np.einsum("ij,ij->i", normals, directions) < 0


def _cross(a, b):
    """Cross products of coordinate-major vectors (3, ...)."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _padded_rows(rows, values, count):
    """(count, K) of `values` listed by their `rows` (sorted), each row's padded to the longest with −1."""
    per_row = np.bincount(rows, minlength=count)
    padded = np.full((count, per_row.max(initial=0)), -1, dtype=np.int64)
    padded[rows, np.arange(len(rows)) - np.repeat(np.cumsum(per_row) - per_row, per_row)] = values
    return padded


def _by_ring_size(sets, ring_sizes):
    """`sets` with each set of shared groups in order of its groups' ring sizes (triangles per row (c,)): a round
    tests a group's rays against as many triangles as the widest ring in its batch, so batches pad less. Each
    group's estimate is its own: the order changes none."""
    return [members[np.argsort(ring_sizes[members[:, 0]], kind="stable")] if members.shape[1] > 1 else members
            for members in sets]


def _shared_ring_planes(caster, sets, origins, ring, ring_sizes):
    """The ring planes (RayCaster.ring_planes) of each shared ray group (k > 1), at its first row: (planes (c, 4F,
    3), zero elsewhere; its ring's triangles (c,), from `ring_sizes`, zero elsewhere). None without a shared group
    with a ring."""
    heads = [members[:, 0] for members in sets if members.shape[1] > 1]
    if not heads or not ring.size:
        return None
    heads = np.concatenate(heads)
    planes = np.zeros((len(ring), 4 * ring.shape[1], 3), dtype=np.float32)
    planes[heads] = caster.ring_planes(origins[heads], ring[heads])
    triangles = np.zeros(len(ring), dtype=np.int64)
    triangles[heads] = ring_sizes[heads]
    return planes, triangles


def _group_ring_planes(rings, heads):
    """The ring planes of the groups whose first rows are `heads` (from `rings`, _shared_ring_planes'), as wide as
    their widest ring; None if none has one (or `rings` is None)."""
    if rings is None:
        return None
    planes, triangles = rings
    width = triangles[heads].max()
    return planes[heads, :4 * width] if width else None


def _surely_hit(planes, coordinates):
    """(g, n) bool: which rays of g groups (coordinates (g, 3, n)) surely hit a triangle that meets their origin's
    vertex (`planes` (g, 4F, 3) of RayCaster.ring_planes), in products small enough for one thread."""
    groups, faces, count = len(planes), planes.shape[1] // 4, coordinates.shape[2]
    hit = np.zeros((groups, count), dtype=bool)
    step = max(1, arrays.SINGLE_THREAD_PRODUCT // max(1, 3 * planes.shape[1]))
    for first in range(0, count, step):
        part = slice(first, first + step)
        below = (np.matmul(planes, coordinates[:, :, part]) < -1.0).reshape(groups, faces, 4, -1)
        hit[:, part] = (below[:, :, 0] & below[:, :, 1] & below[:, :, 2] & below[:, :, 3]).any(axis=1)
    return hit


def _scattered(values, live, missing):
    """`values` of the live rays (n,) as the values of every ray (`live`'s size), `missing` for the others; `values`
    itself without a mask."""
    if live is None:
        return values
    every = np.full(live.size, missing, dtype=values.dtype)
    every[live.ravel()] = values
    return every


def shadowed_chunk(caster: RayCaster, positions, normals, inward, keys, settings: BakeSettings, labels=None,
                   surface_steps=None):
    """Generator: bakes one chunk, yielding the rays cast after each round; returns a ChunkResult. Rows with
    the same `labels` entry share their rays (None: each row casts its own); contact is judged a step along
    `surface_steps` (None: `inward`)."""
    order, replicates = settings.order, settings.replicates
    positions = positions - caster.center
    count = len(positions)
    unshadowed = unshadowed_transfer(order, normals)
    has_surface = np.abs(normals).sum(-1) > 0
    # Lying on a surface is judged a little inside the point's own faces, so that a surface merely touching the
    # vertex does not make it black.
    steps = inward if surface_steps is None else surface_steps
    touched, lying, ring = caster.touched_surfaces(positions, normals, steps)
    facing = np.einsum("ij,ij->i", touched, normals) < 0
    contact = has_surface & lying
    # The hull test assumes rays start an offset along the normal; a point touching a surface starts them elsewhere
    # (below), and a surface it faces squarely at its own tangent plane (a sphere's pole on a floor) passes the test.
    open_sky = provably_unoccluded(positions, normals, caster.hull, caster.offset) & ~facing
    skipped = has_surface & (open_sky | contact)
    rays = np.zeros(count, dtype=np.int64)  # cast from each row
    used = np.zeros(count, dtype=np.int64)  # each row's estimate rests on: its group's
    # A point touching a surface at an angle starts its rays in front of both (along the bisector of the two
    # normals, a step along its faces), so rays that cross that surface are blocked there and the others leave as
    # from its own face.
    lifted = normals + touched
    lifted /= np.maximum(np.linalg.norm(lifted, axis=1, keepdims=True), 1e-12)
    origins = positions + caster.offset * np.where(facing[:, None], lifted + steps, normals + inward)
    baked = np.flatnonzero(has_surface & ~skipped)
    if labels is not None:
        labels = _alone_unless_lifting(labels.copy(), baked, normals, touched)
    # A shadowed bake needs no hit but whether there is one: the rays of a shared group that surely cross a face
    # meeting at its vertex are known blocked without a cast, 8.6 % of the flat-shaded cow's rays. Not those of a
    # row casting alone: 1.3 % of the smooth cow's, which cost less to cast than to test. The interreflected bake
    # casts them, as it records where each ray hits.
    predicting = settings.mode != "interreflected"
    ring_sizes = np.count_nonzero(ring >= 0, axis=1)
    sets = _by_ring_size(ray_sets(labels, baked), ring_sizes) if predicting else ray_sets(labels, baked)
    # per set: each group's lattice frames (g, 3, 3) and the floor of its cap (g,), None: a hemisphere
    caps = iter(_share_rays(sets, positions, normals, touched, origins, caster.offset))
    lattices = [(_frames(normals[members[:, 0]]), None) if members.shape[1] == 1 else next(caps) for members in sets]
    cones, flat_blocked = _flat_shadows(caster, origins, normals, order)
    rings = _shared_ring_planes(caster, sets, origins, ring, ring_sizes) if predicting else None
    rounds = []  # (rows, rays per row, transfer mean, transfer variance), combined below
    hits = [] if settings.mode == "interreflected" else None  # (chunk row, triangle, barycentric, weight)
    plan = [(settings.points_per_replicate, members, lattice) for members, lattice in zip(sets, lattices)]
    for round_index in range(MAX_ROUNDS):
        if not plan:  # every row exact without rays, or every row at its target
            break
        # Every group's lattice shifts for the round from one hash (each value depends on its key alone)
        heads = np.concatenate([members[:, 0] for _, members, _ in plan])
        stream = keys[heads, None] * STREAMS_PER_VERTEX + round_index * replicates + np.arange(replicates)
        round_shifts = np.split(sampling.hash_uniform(settings.seed, stream.ravel(), 2).reshape(-1, replicates, 2),
                                np.cumsum([len(members) for _, members, _ in plan])[:-1])
        for (per_replicate, members, (lattice_frames, floor)), shifts in zip(plan, round_shifts):
            group_rays = replicates * per_replicate
            points = sampling.fibonacci_lattice(per_replicate)
            # A round weighs at most WEIGHT_BYTES_PER_BATCH of weights (rays × rows) at a time (a row of a shared
            # group weighs all of its group's rays): bounded memory, arrays near cache size, and progress (and Esc)
            # between batches. Every group keeps its own random streams, so batching never changes a result. The
            # flat-shaded cow's CPU besides the rays in float64, relative to 2^19 bytes: 2^18 1.07, 2^20 0.95, 2^21
            # 1.04 at 256 samples; 2^20 0.88 at 1024 samples (the smooth cow's: 1.00).
            size = members.shape[1]
            batch = max(1, WEIGHT_BYTES_PER_BATCH // (group_rays * size * np.dtype(weight_dtype(size)).itemsize))
            for first in range(0, len(members), batch):
                part = slice(first, first + batch)
                groups = members[part]  # (g, k) rows
                lattice = lattice_frames[part], None if floor is None else floor[part], points, shifts[part]
                flat = None if cones is None else (cones[groups[:, 0]], flat_blocked[groups])
                mean, variance, round_hits, cast = _blocked_round(
                    caster, origins[groups[:, 0]], normals[groups], lattice, unshadowed[groups], flat,
                    _group_ring_planes(rings, groups[:, 0]), settings)
                rows = groups.ravel()
                if hits is not None:
                    hits.append((rows[round_hits[0]], *round_hits[1:]))
                rounds.append((rows, group_rays, mean.reshape(len(rows), -1), variance.reshape(len(rows), -1)))
                used[rows] += group_rays
                rays[groups[:, 0]] += cast  # a group's rays are counted at its first row
                yield int(cast.sum())
        if settings.target_error <= 0.0:
            break
        _, error = _combine(rounds, used, count, order)
        plan = [(size, members[chosen], (frames[chosen], None if floor is None else floor[chosen]))
                for members, (frames, floor) in zip(sets, lattices)
                for size, chosen in _next_rounds(error[members].max(1), used[members[:, 0]], settings)]
    transfer, error = _combine(rounds, used, count, order)
    transfer[used == 0] = unshadowed[used == 0]  # exact: provably unoccluded, or no surface (zero)
    transfer[contact] = 0.0  # exact: every direction is blocked by the surface it rests on
    return ChunkResult(transfer, error, rays, skipped, _records(hits, used))


def ray_sets(labels, rows) -> list[np.ndarray]:
    """The ray groups among `rows`: one (g, k) array of rows per group size k (every row alone without labels)."""
    if not len(rows):  # every row exact without rays (a lone convex object): no group, not one of size 0
        return []
    if labels is None:
        return [rows[:, None]]
    ordered = rows[np.argsort(labels[rows], kind="stable")]
    group_labels = labels[ordered]
    starts = np.flatnonzero(np.r_[True, group_labels[1:] != group_labels[:-1]])
    sizes = np.diff(np.r_[starts, len(ordered)])
    return [ordered[starts[sizes == size][:, None] + np.arange(size)] for size in np.unique(sizes)]


def _flat_shadows(caster, origins, normals, order):
    """The closed-form part of a chunk: the cone planes (c, P, m, 3) of the flat polygons some vertex has above
    its tangent plane (None if there are none), and the transfer (c, order²) they block, seen from the ray
    origins."""
    seen = [polygon for polygon in caster.polygons
            if (normals @ polygon.T > np.einsum("ij,ij->i", normals, origins)[:, None]).any()]
    if not seen:
        return None, np.zeros((len(origins), order * order))
    return polygons.cones_and_blocked_transfer(order, origins, normals, seen)


def _records(hits, used):
    """A ray's weight in a row's estimate, rounds included: its balance weight ÷ the rays the row's estimate uses."""
    if hits is None:
        return None
    if not hits:
        return interreflect.HitRecords.empty()
    row, triangle, barycentric, weight, replicate = (np.concatenate(part) for part in zip(*hits))
    return interreflect.HitRecords(row, triangle, barycentric, weight / used[row], replicate)


def _next_rounds(error, rays, settings: BakeSettings):
    """(points per replicate, vertices) for vertices still above the target: each gets one round sized so that
    its predicted combined error meets the target (error ∝ rays^-0.79, measured for this estimator), from a
    √2-spaced ladder of lattice sizes, capped by the ray budget. Doubling instead overshot by about 1.5×."""
    target = settings.target_error * unshadowed_norm(settings.order) / TARGET_MARGIN
    budget = settings.max_samples - rays
    missing = np.flatnonzero((error > target) & (budget >= settings.replicates))
    if not len(missing):
        return []
    base = settings.points_per_replicate
    ladder = np.unique(np.round(base * 2.0 ** (np.arange(1, 2 * 20) / 2)).astype(np.int64))
    now_rays, now_error = rays[missing][:, None], error[missing][:, None]
    new_rays = settings.replicates * ladder[None, :]
    new_error = now_error * (now_rays / new_rays) ** CONVERGENCE_RATE
    predicted = np.sqrt((now_rays * now_error) ** 2 + (new_rays * new_error) ** 2) / (now_rays + new_rays)
    fits = (predicted <= target) | (new_rays >= budget[missing][:, None])
    choice = np.minimum(np.argmax(fits, axis=1), np.searchsorted(ladder, budget[missing] // settings.replicates,
                                                                 side="right") - 1)
    valid = choice >= 0
    sizes = ladder[np.maximum(choice, 0)]
    return [(int(size), missing[valid & (sizes == size)]) for size in np.unique(sizes[valid])]


def _combine(rounds, rays, count, order):
    """Weights rounds by their share of each vertex's rays: unbiased, optimal at the Monte Carlo rate."""
    estimate = np.zeros((count, order * order))
    variance = np.zeros((count, order * order))
    for vertices, round_rays, mean, var in rounds:
        weight = (round_rays / rays[vertices])[:, None]
        estimate[vertices] += weight * mean
        variance[vertices] += weight * weight * var
    return estimate, np.sqrt(variance.sum(1))


def _frames(normals):
    """(c, 3, 3) frames whose rows are a tangent, a bitangent and the unit normal (c, 3)."""
    return np.stack([*sampling.orthonormal_basis(normals), normals], axis=1)


def _share_rays(sets, positions, normals, touched, origins, offset) -> list:
    """For each set of shared groups (k > 1) among `sets`, in order: its groups' caps (_caps); and every row of a
    shared group gets the group's one ray origin in `origins` (_shared_origins). The groups of every size are worked
    at once, each padded to the largest with zero normals, which count for nothing below: a chunk of the flat-shaded
    cow holds groups of about 7 sizes, and each step's fixed cost was paid per size."""
    shared = [members for members in sets if members.shape[1] > 1]
    if not shared:
        return []
    # each row's step from its vertex to its own origin; a padding row's is zero
    rows, real, (group_normals, group_touched, steps) = _padded(shared, normals, touched, origins - positions)
    vertex = positions[rows[:, 0]]
    frames, floor = _caps(group_normals)
    _, direction, planes, climbs = _planes_to_clear(group_normals, group_touched)
    counts = real.sum(axis=1)
    origins[rows[real]] = np.repeat(_shared_origins(steps, counts, vertex, planes, direction, climbs, offset),
                                    counts, axis=0)
    cuts = np.cumsum([len(members) for members in shared])[:-1]
    return list(zip(np.split(frames, cuts), np.split(floor, cuts)))


def _padded(sets, *per_row):
    """Groups of rows of several sizes (`sets`: (g, k) arrays, k > 1) as one: their rows (G, K), padded to the largest
    size with -1; where they are real (G, K); and each array of `per_row` (rows, 3) at them (G, K, 3), zero at the
    padding, which is then no plane and no normal."""
    rows = np.full((sum(map(len, sets)), max(members.shape[1] for members in sets)), -1)
    first = 0
    for members in sets:  # (np.pad costs 20 µs a call)
        rows[first:first + len(members), :members.shape[1]] = members
        first += len(members)
    real = rows >= 0
    rows_there = np.where(real, rows, rows[:, :1])
    return rows, real, [np.where(real[..., None], values[rows_there], 0.0) for values in per_row]


def _caps(normals):
    """For ray groups of rows (normals (g, k, 3), k > 1, zero rows are none): the frames (g, 3, 3) of the cap their
    shared lattice covers, around the rows' mean normal n̄ (the third row); and the cap's floor s (g,), the lowest
    direction of the rows' hemispheres, so that the cap is n̄·ω ≥ s."""
    mean_normal = sampling.unit_or_zero(normals.sum(axis=1))
    heights = np.einsum("gd,gkd->gk", mean_normal, normals)
    closest = np.maximum(np.where(np.abs(normals).sum(-1) > 0, heights, np.inf).min(1), 0.0)
    return _frames(mean_normal), -np.sqrt(1.0 - closest * closest)


# A group whose points touch surfaces at an angle shares one origin when it can start in front of all of them and
# of its points' own planes: each plane climbs at least this much along the direction the origin is raised in, so
# the origin stays within a few offsets of the vertex (else those points cast alone from their own lifted origins).
LIFT_CLIMB = 1.0 / 3.0


def _planes_to_clear(normals, touched):
    """For ray groups (g, k) at one vertex each, the planes through the vertex its one origin must be in front of:
    every row's tangent plane (normals (g, k, 3)) and every surface a row touches at an angle (`touched` (g, k, 3),
    zero where none). Returns (lifts (g,): some row touches a surface, and the origin can clear them all; the
    direction to raise it along (g, 3): their mean where it lifts, else the mean of the rows' normals; the planes
    (g, 2k, 3); their climbs along that direction (g, 2k), zero for no plane)."""
    planes = np.concatenate([normals, touched], axis=1)
    real = np.abs(planes).sum(-1) > 0
    lifting = sampling.unit_or_zero(planes.sum(axis=1))
    lifts = real[:, normals.shape[1]:].any(axis=1) & (
        np.where(real, np.einsum("gd,gpd->gp", lifting, planes), 1.0).min(axis=1) >= LIFT_CLIMB)
    direction = np.where(lifts[:, None], lifting, sampling.unit_or_zero(normals.sum(axis=1)))
    return lifts, direction, planes, np.where(real, np.einsum("gd,gpd->gp", direction, planes), 0.0)


def _alone_unless_lifting(labels, baked, normals, touched):
    """`labels` with each row that touches a surface at an angle (a nonzero `touched` normal) made a group of its
    own (it then starts its rays in front of both, lifted) unless its group's one origin can clear every plane
    (_planes_to_clear); repeated for the groups that lost a row, since that changes their direction. Only groups
    with such a row are looked at (about 1 % of the flat-shaded cow's rows touch a surface)."""
    touching = np.abs(touched).sum(-1) > 0
    checked = labels[baked[touching[baked]]]
    while len(checked):
        shared = [members for members in ray_sets(labels, baked[np.isin(labels[baked], checked)])
                  if members.shape[1] > 1]
        if not shared:
            break
        rows, real, group_vectors = _padded(shared, normals, touched)
        parting = ~_planes_to_clear(*group_vectors)[0]
        rows = rows[parting][real[parting]]
        rows = rows[touching[rows]]
        checked = labels[rows]
        labels[rows] = -1 - rows
    return labels


def _shared_origins(steps, counts, positions, planes, direction, climbs, offset):
    """(g, 3) one ray origin for each group of rows (g, k) at one vertex (`positions` (g, 3)): the vertex plus the mean
    of the rows' steps to their own origins (g, k, 3; the first `counts` (g,) of each group's are rows, the rest
    zero), raised along `direction` (g, 3) until it is at least `offset` in front of every plane through the vertex
    (_planes_to_clear's: `planes` (g, p, 3), `climbs` (g, p), zero for none), as each row's own origin is in front of
    its own."""
    steps = steps.sum(axis=1) / counts[:, None]
    heights = np.einsum("gd,gpd->gp", steps, planes)
    raise_by = np.where(climbs > 0.0, np.maximum((offset - heights) / np.maximum(climbs, 1e-3), 0.0), 0.0)
    return positions + steps + raise_by.max(axis=1)[:, None] * direction


def weight_dtype(size):
    """The dtype of a ray group's directions, weights and SH values, for groups of `size` rows. A shared group's k
    rows each weigh every ray: in float32 that work moves half the bytes and its matrix products run twice as fast.
    The directions lose nothing (the ray caster casts float32), and a replicate's sums over its m rays round by
    √m·2^-24 of their size typically, m·2^-24 at worst (6e-5 at m = 1024), far below the Monte Carlo error they
    carry. A group of one has no k-fold work (its weights are 1) and keeps float64, so smooth meshes bake bit for
    bit as before."""
    return np.float64 if size == 1 else np.float32


def _blocked_round(caster, origins, normals, lattice, unshadowed, flat, ring_planes, settings):
    """One round for g ray groups of k rows (origins (g, 3), the rest (g, k, ...)): each group casts R replicates of
    its own shifted lattice from its origin. `lattice`: each group's frames (g, 3, 3) and cap floor (g,) or None
    (see _caps), the lattice points (m, 2) and each group's shifts (g, R, 2). Returns the mean and variance over
    replicates of each row's transfer estimate (g, k, n²), the hits (interreflected mode) and the rays each group
    cast (g,).

    A group of one samples its row's cosine lobe. A larger group samples the cap n̄·ω ≥ s about its mean normal n̄
    that covers every row's hemisphere, with density ∝ (n̄·ω − s)^q (q = sampling.CAP_EXPONENT); each row weighs each
    direction by its own cosine density over the cap's, W = 2(1 − s)^(q+1)·(n·ω)₊ / ((q + 1)(n̄·ω − s)^q): unbiased,
    and near 1 where the normals nearly agree (s = 0 and n = n̄: W = 2(n·ω)^(1−q)/(q + 1), whose mean square
    4/((q + 1)(3 − q)) is 1.016 at q = 0.75), so all rows of a vertex share one lattice at the cost of one row. A row
    estimates T = β·T_unshadowed + mean(W·((1 − β)·Y − (1 − V)·Y)), a control variate whose coefficient β is its
    visible fraction this round: β = 1 samples only blocked light (exact for an open vertex), β = 0 only visible light
    (exact for a buried one), in between it tracks the optimal coefficient.
    Rays are cast only where the answer is not known: one whose every weight is zero counts for nothing, and one that
    surely crosses a triangle meeting at its group's vertex (`ring_planes`: the group's, or None) is blocked.
    Flat polygons (`flat`: each group's cone planes (g, P, m, 3), the same for its rows as they share their origin,
    and the transfer G they block for each row; None without any) are exact: a ray counts as blocked only for what
    they do not explain, 1 − V − g with g its hits on them, and G is subtracted; unbiased for any polygon, and P's
    edges add no noise where P really is occluder geometry."""
    replicates, order = settings.replicates, settings.order
    groups, size = normals.shape[:2]
    lattice_frames, floor, points, shifts = lattice
    per_replicate, dtype = len(points), weight_dtype(size)
    if floor is None:  # a group of one samples its own lobe
        cast = sampling.cosine_lattice_directions(points, shifts, lattice_frames[:, None], dtype=dtype)
    else:
        floor = floor.astype(dtype)
        cast = sampling.cosine_lattice_directions(points, shifts, lattice_frames[:, None], floor[:, None], dtype)
    directions = cast  # (g, R, m, 3)
    cast = cast.reshape(groups, replicates * per_replicate, 3)  # a view: the rays of each group
    # Each row's W/m and W·(1 − V)/m per ray (the means' 1/m), made where _weighted_means multiplies them: (g, 2, k,
    # R, m).
    weighed = np.empty((groups, 2, size, replicates, per_replicate), dtype=dtype)
    weights, blocked_weights = weighed[:, 0], weighed[:, 1]
    # Each group's (3, R·m) coordinates, a view of the component-major directions: products with the normals and
    # planes are BLAS matrix products, 30× faster than einsum over the last axis of the (g, R, m, 3) view.
    coordinates = np.moveaxis(directions, -1, 0).reshape(3, groups, -1).transpose(1, 0, 2)
    live = None  # the rays to cast: every one
    if size > 1:  # W/m = (n·ω)₊/(π p(ω) m) = (n·(c·ω))₊ with c = 1/(π p m), p the cap's density (sampling.cap_weights)
        per_ray = np.matmul(lattice_frames[:, 2:].astype(dtype), coordinates)  # n̄·ω (g, 1, R·m)
        per_ray -= floor[:, None, None]
        sampling.cap_weights(per_ray, floor[:, None, None], 1.0 / per_replicate)
        # Scaling the 3 coordinates rather than the k rows' weights; a float mask multiplies faster than a bool one.
        np.matmul(normals.astype(dtype), coordinates * per_ray, out=weights.reshape(groups, size, -1))
        np.maximum(weights, 0.0, out=weights)
        # A ray of the cap below every row's horizon weighs nothing in any estimate: it is not cast (1.6 % of the
        # flat-shaded cow's rays, nearly all of them hits, which cost the most).
        live = weights.reshape(groups, size, -1).max(axis=1) > 0.0
    known = None if ring_planes is None else _surely_hit(ring_planes, coordinates.astype(np.float32, copy=False))
    if known is not None:
        live = ~known if live is None else live & ~known
    cast_rays = np.full(groups, cast.shape[1]) if live is None else np.count_nonzero(live, axis=1)
    if live is not None and cast_rays.sum() == live.size:
        live = None
    if settings.mode == "interreflected":
        occluded, triangle, distance = caster.occluded(origins, cast, hits=True, live=live)
    else:
        occluded = caster.occluded(origins, cast, live=live)
    if known is not None:
        occluded = occluded | known
    blocked = occluded.reshape(groups, 1, replicates, per_replicate)
    if flat is not None:
        cones, flat_blocked = flat  # a group's cones: its rows share their origin
        blocked = blocked - polygons.hits(cast, cones).reshape(groups, 1, replicates, per_replicate)
    if size == 1:  # every weight is 1
        beta = 1.0 - blocked.mean(axis=(2, 3))[..., None, None]
        weights[...] = 1.0 / per_replicate
        np.multiply(blocked, 1.0 / per_replicate, out=blocked_weights)
        weights = None
    else:
        np.multiply(weights, blocked.astype(dtype), out=blocked_weights)
        beta = 1.0 - blocked_weights.sum(axis=(2, 3))[..., None, None] / replicates  # (g, k, 1, 1)
    round_hits = (_round_hits(caster, origins, cast, occluded, triangle, distance, weights, per_replicate)
                  if settings.mode == "interreflected" else None)
    all_rays, blocked_rays = _weighted_means(directions, weighed, order)
    estimate = beta * unshadowed[:, :, None] + (1.0 - beta) * all_rays - blocked_rays  # (g, k, R, n²)
    if flat is not None:
        estimate -= flat_blocked[:, :, None]
    # np.mean and np.var's arithmetic, the sum over replicates taken once
    mean = estimate.sum(axis=2) / replicates
    deviation = estimate - mean[:, :, None]
    deviation *= deviation
    return mean, deviation.sum(axis=2) / (replicates - 1) / replicates, round_hits, cast_rays


def _weighted_means(directions, weighed, order):
    """Per row and replicate: the means of W·Y and of W·(1 − V)·Y over its group's directions (g, R, m, 3), from
    `weighed` (g, 2, k, R, m), W and W·(1 − V) already divided by m: one small matrix product per group and
    replicate, a few groups at a time so memory stays bounded at high orders and ray counts. Both (g, k, R, n²)."""
    groups, replicates, per_replicate = directions.shape[:3]
    size, coefficients = weighed.shape[2], order * order
    # (g, R, 2k, m): each group and replicate's (2k, m) matrix, its rows R·m apart, as BLAS reads it in place.
    rows = weighed.reshape(groups, 2 * size, replicates, per_replicate).transpose(0, 2, 1, 3)
    means = np.empty((groups, replicates, 2 * size, coefficients), dtype=weighed.dtype)
    step = max(1, REPLICATE_VALUES_AT_ONCE // (replicates * per_replicate * coefficients))
    for first in range(0, groups, step):
        part = slice(first, first + step)
        basis = sh.evaluate_components(order, directions[part].reshape(-1, 3), weighed.dtype)
        np.matmul(rows[part], basis.T.reshape(-1, replicates, per_replicate, coefficients), out=means[part])
    means = np.moveaxis(means.reshape(groups, replicates, 2, size, coefficients), 1, 3)  # (g, 2, k, R, n²)
    return means[:, 0], means[:, 1]


def _round_hits(caster, origins, cast, occluded, triangle, distance, weights, per_replicate):
    """(row in g·k, triangle, barycentric, weight, replicate) for every blocked ray that hit a front face, once for
    each row of the casting group whose estimate it enters, with that row's weight W for it (`weights`: W/m)."""
    group, ray = np.nonzero(occluded)
    barycentric, front = caster.front_hits(origins[group], cast[group, ray], triangle[group, ray],
                                           distance[group, ray])
    group, ray, triangle, barycentric = group[front], ray[front], triangle[group, ray][front], barycentric[front]
    replicate = ray // per_replicate
    if weights is None:
        return group, triangle, barycentric, np.ones(len(group)), replicate
    size = weights.shape[1]
    hit_weights = weights.reshape(len(weights), size, -1)[group, :, ray] * per_replicate  # (H, k): W, not W/m
    hit, member = np.nonzero(hit_weights > 0.0)
    return group[hit] * size + member, triangle[hit], barycentric[hit], hit_weights[hit, member], replicate[hit]


def vertex_keys(receiver: Receiver, rows: np.ndarray) -> np.ndarray:
    """Per-row random stream ids: 20 bits of the object's key above 30 bits of row index."""
    return (np.int64(receiver.key & 0xFFFFF) << np.int64(30)) + np.asarray(rows, dtype=np.int64)


def chunk_rows(receivers) -> list[tuple[int, np.ndarray]]:
    """(receiver index, rows) for chunks of CHUNK_VERTICES ray groups (rows, without groups) over every receiver,
    SHARED_CHUNK_FACTOR times as many where the groups are shared, fixed by the receivers alone: a group's rows
    share a chunk. Groups are taken in order of their size, so a chunk holds groups of one or two sizes and runs a
    round for each (ray_sets) rather than one for each of the many sizes a vertex's corners come in: the
    flat-shaded cow's 194 rounds of 18 groups on average became 138 of 25, and its chunks' CPU besides the rays
    0.84-0.88× (results bit for bit the same)."""
    chunks = []
    for index, receiver in enumerate(receivers):
        count = len(receiver.positions)
        if receiver.ray_groups is None:
            order, cuts = np.arange(count), np.arange(CHUNK_VERTICES, count, CHUNK_VERTICES)
        else:
            _, group, sizes = np.unique(receiver.ray_groups, return_inverse=True, return_counts=True)
            order = np.lexsort((receiver.ray_groups, sizes[group.ravel()]))
            labels = receiver.ray_groups[order]
            starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
            share = np.where(np.diff(np.r_[starts, count]) > 1, 1.0 / SHARED_CHUNK_FACTOR, 1.0)  # of a chunk's groups
            chunk_of_group = (np.cumsum(share) - share) // CHUNK_VERTICES  # exact for a power-of-two factor
            cuts = starts[np.flatnonzero(np.diff(chunk_of_group)) + 1]
        chunks.extend((index, rows) for rows in np.split(order, cuts))
    return chunks


def bake_chunk(caster, receiver: Receiver, rows: np.ndarray, settings: BakeSettings):
    """Generator over one chunk (the receiver's `rows`) in either mode; yields rays cast, returns a ChunkResult."""
    normals = receiver.normals[rows]
    if settings.mode == "unshadowed" or caster is None:
        count = len(rows)
        return ChunkResult(unshadowed_transfer(settings.order, normals), np.zeros(count),
                           np.zeros(count, dtype=np.int64), np.zeros(count, dtype=bool))
    keys = vertex_keys(receiver, rows)
    inward = np.zeros_like(normals) if receiver.inward is None else receiver.inward[rows]
    labels = None if receiver.ray_groups is None else receiver.ray_groups[rows]
    steps = None if receiver.surface_step is None else receiver.surface_step[rows]
    return (yield from shadowed_chunk(caster, receiver.positions[rows], normals, inward, keys, settings, labels,
                                      steps))
