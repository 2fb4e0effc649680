"""The shadowed estimator of diffuse SH transfer per point, one chunk of points at a time.

Transfer convention: T_k = (1/π) ∫ V(ω) max(n·ω, 0) Y_k(ω) dω, so radiance = albedo · Σ_k L_k T_k.

Shadowed estimator (what makes it cheap compared with the original program's uniform-sphere Monte Carlo):
- the unshadowed transfer is exact (closed form) and serves as a control variate:
  T ≈ β·T_unshadowed + mean over cosine-distributed rays of (V − β)·Y, β the vertex's visible fraction, so a
  vertex that sees the whole sky or none of it adds no noise, and one that provably sees the sky casts no ray;
- directions are a rank-1 lattice, Cranley-Patterson rotated per vertex and replicate, so R independent
  replicates give an honest standard error;
- with a target error, rounds double the rays per replicate until each vertex meets the target.
"""

import time

import numpy as np

from . import arrays, contact, error_curve, interreflect, polygons, ray_groups, rings, rules, sampling, scheduling, sh
from .bake import BakeSettings, ChunkResult, Receiver
from .lobes import unshadowed_transfer
from .ray_caster import RayCaster

WEIGHT_BYTES_PER_BATCH = 1 << 20
# Basis values that _weighted_means evaluates at once: 4M values = 32 MB in float64 (16 MB for a shared group's
# float32, weight_dtype), whatever the order and rays.
REPLICATE_VALUES_AT_ONCE = 1 << 22


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


def bake_chunk(caster, receiver: Receiver, rows: np.ndarray, settings: BakeSettings):
    """Generator over one chunk (the receiver's `rows`) in either mode; yields rays cast, returns a ChunkResult.
    Rows against their faces are measured as Cycles shades them, from behind (core.corners): with the normal −N,
    their sky clipped by their face reversed (the receiver's `clip`), and marked as decided by that rule (core.rules)
    so the report shows where normals are against their faces."""
    normals = receiver.normals[rows]
    against = None if receiver.against is None else receiver.against[rows]
    clip = None if receiver.clip is None else receiver.clip[rows]
    if against is not None:
        normals = np.where(against[:, None], -normals, normals)
    if settings.mode == "unshadowed" or caster is None:
        count = len(rows)
        result = ChunkResult(unshadowed_transfer(settings.order, normals), np.zeros(count),
                             np.zeros(count, dtype=np.int64), np.zeros(count, dtype=bool), rules.measured(count),
                             np.zeros(count), np.array([error_curve.chunk_row(0.0, 0, np.zeros(0))]))
    else:
        keys = scheduling.vertex_keys(receiver, rows)
        inward = np.zeros_like(normals) if receiver.inward is None else receiver.inward[rows]
        labels = None if receiver.ray_groups is None else receiver.ray_groups[rows]
        steps = None if receiver.surface_step is None else receiver.surface_step[rows]
        result = yield from shadowed_chunk(caster, receiver.positions[rows], normals, inward, keys, settings, labels,
                                           steps, clip, against)
    if against is not None:
        result.rules[against] = rules.AGAINST
    # The rules' doubt is no noise more rays take away: it stays in the chunk's error after every round.
    result.curve[:, 2] += np.square(result.rule_error).sum()
    return result


def shadowed_chunk(caster: RayCaster, positions, normals, inward, keys, settings: BakeSettings, labels=None,
                   surface_steps=None, clip=None, against=None):
    """Generator: bakes one chunk, yielding the rays cast after each round; returns a ChunkResult. Rows with
    the same `labels` entry share their rays (None: each row casts its own); contact is judged a step along
    `surface_steps` (None: `inward`). A row with a nonzero `clip` normal (c, 3; None: none) gathers only the
    directions above that plane, as Cycles' corner on that face does (core.corners): the lune's closed form less what
    its own rays, cast from above that plane a step into its face, find blocked in it. Contact never judges the rows
    `against` their faces ((c,) bool; None: none): shaded from behind, the faces at their vertex would seem to face
    them, their own first, and their clip already starts their rays behind their face. The result's curve has a row
    after each round (core.error_curve), its seconds those this generator spent working, not those it waited
    between yields."""
    resumed, busy = time.perf_counter(), 0.0
    order, replicates = settings.order, settings.replicates
    positions = positions - caster.center
    count = len(positions)
    unshadowed = unshadowed_transfer(order, normals)
    has_surface = np.abs(normals).sum(-1) > 0
    # Lying on a surface is judged a little inside the point's own faces, so that a surface merely touching the
    # vertex does not make it black.
    steps = inward if surface_steps is None else surface_steps
    touched, lying, ring = contact.touched_surfaces(caster, positions, normals, steps)
    if against is not None:
        touched[against] = 0.0
        lying &= ~against
    facing = np.einsum("ij,ij->i", touched, normals) < 0
    in_contact = has_surface & lying
    clipped = np.zeros(count, dtype=bool) if clip is None else np.abs(clip).sum(-1) > 0
    # A clipped row's rays estimate only what blocks its sky in front of its plane, whose transfer is their control
    # variate in closed form: exact where nothing else blocks it (a corner against its face on a convex part).
    if clipped.any():
        unshadowed[clipped] = polygons.lune_transfer(order, normals[clipped], clip[clipped])
    # The hull test assumes rays start an offset along the normal; a point touching a surface starts them elsewhere
    # (below), and a surface it faces squarely at its own tangent plane (a sphere's pole on a floor) passes the test.
    open_sky = provably_unoccluded(positions, normals, caster.hull, caster.offset) & ~facing & ~clipped
    skipped = has_surface & (open_sky | in_contact)
    rays = np.zeros(count, dtype=np.int64)  # cast from each row
    used = np.zeros(count, dtype=np.int64)  # each row's estimate rests on: its group's
    # A point touching a surface at an angle starts its rays in front of both (along the bisector of the two
    # normals, a step along its faces), so rays that cross that surface are blocked there and the others leave as
    # from its own face.
    lifted = normals + touched
    lifted /= np.maximum(np.linalg.norm(lifted, axis=1, keepdims=True), 1e-12)
    lift = normals + inward if clip is None else np.where(clipped[:, None], clip + steps, normals + inward)
    origins = positions + caster.offset * np.where(facing[:, None], lifted + steps, lift)
    baked = np.flatnonzero(has_surface & ~skipped)
    if labels is not None:
        labels = ray_groups.alone_unless_lifting(labels.copy(), baked, normals, touched)
        labels[clipped] = -1 - np.flatnonzero(clipped)  # each its own plane: no shared origin clears the others
    # A shadowed bake needs no hit but whether there is one: the rays of a shared group that surely cross a face
    # meeting at its vertex are known blocked without a cast, 8.6 % of the flat-shaded cow's rays. Not those of a
    # row casting alone: 1.3 % of the smooth cow's, which cost less to cast than to test. The interreflected bake
    # casts them, as it records where each ray hits.
    predicting = settings.mode != "interreflected"
    ring_sizes = np.count_nonzero(ring >= 0, axis=1)
    sets = ray_groups.ray_sets(labels, baked)
    sets = rings.by_ring_size(sets, ring_sizes) if predicting else sets
    # per set: each group's lattice frames (g, 3, 3) and the floor of its cap (g,), None: a hemisphere
    caps = iter(ray_groups.share_rays(sets, positions, normals, touched, origins, caster.offset))
    lattices = [(ray_groups.frames(normals[members[:, 0]]), None) if members.shape[1] == 1 else next(caps)
                for members in sets]
    cones, flat_blocked = _flat_shadows(caster, origins, normals, order)
    if cones is not None:  # their closed forms cover a whole lobe, not a clipped row's lune: its rays count them
        cones[clipped], flat_blocked[clipped] = 0.0, 0.0
    shared_rings = rings.shared_ring_planes(caster, sets, origins, ring, ring_sizes) if predicting else None
    rounds = []  # (rows, rays per row, transfer mean, transfer variance), combined below
    curve = []  # core.error_curve's row after each round
    hits = [] if settings.mode == "interreflected" else None  # (chunk row, triangle, barycentric, weight)
    plan = [(settings.points_per_replicate, members, lattice) for members, lattice in zip(sets, lattices)]
    for round_index in range(scheduling.MAX_ROUNDS):
        if not plan:  # every row exact without rays, or every row at its target
            break
        # Every group's lattice shifts for the round from one hash (each value depends on its key alone)
        heads = np.concatenate([members[:, 0] for _, members, _ in plan])
        stream = keys[heads, None] * scheduling.STREAMS_PER_VERTEX + round_index * replicates + np.arange(replicates)
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
            itemsize = np.dtype(ray_groups.weight_dtype(size)).itemsize
            batch = max(1, WEIGHT_BYTES_PER_BATCH // (group_rays * size * itemsize))
            for first in range(0, len(members), batch):
                part = slice(first, first + batch)
                groups = members[part]  # (g, k) rows
                lattice = lattice_frames[part], None if floor is None else floor[part], points, shifts[part]
                flat = None if cones is None else (cones[groups[:, 0]], flat_blocked[groups])
                planes = clip[groups[:, 0]] if size == 1 and clipped[groups[:, 0]].any() else None
                mean, variance, round_hits, cast = _blocked_round(
                    caster, origins[groups[:, 0]], normals[groups], lattice, unshadowed[groups], flat,
                    rings.group_ring_planes(shared_rings, groups[:, 0]), settings, planes)
                rows = groups.ravel()
                if hits is not None:
                    hits.append((rows[round_hits[0]], *round_hits[1:]))
                rounds.append((rows, group_rays, mean.reshape(len(rows), -1), variance.reshape(len(rows), -1)))
                used[rows] += group_rays
                rays[groups[:, 0]] += cast  # a group's rays are counted at its first row
                busy += time.perf_counter() - resumed
                yield int(cast.sum())
                resumed = time.perf_counter()
        if settings.target_error <= 0.0:
            break
        _, error = scheduling.combine(rounds, used, count, order)
        curve.append(error_curve.chunk_row(busy + time.perf_counter() - resumed, rays.sum(), error))
        plan = [(size, members[chosen], (frames[chosen], None if floor is None else floor[chosen]))
                for members, (frames, floor) in zip(sets, lattices)
                for size, chosen in scheduling.next_rounds(error[members].max(1), used[members[:, 0]], settings)]
    transfer, error = scheduling.combine(rounds, used, count, order)
    if not curve or curve[-1][1] < rays.sum():  # without a target: its one round; or no round at all
        curve.append(error_curve.chunk_row(busy + time.perf_counter() - resumed, rays.sum(), error))
    transfer[used == 0] = unshadowed[used == 0]  # exact: provably unoccluded, or no surface (zero)
    transfer[in_contact] = 0.0  # exact: every direction is blocked by the surface it rests on
    decided = rules.measured(count)
    decided[has_surface & facing] = rules.TOUCHING
    decided[in_contact] = rules.LYING
    doubt = np.zeros(count)
    doubt[in_contact] = rules.doubt(order, normals[in_contact], touched[in_contact])  # the sky past that surface
    return ChunkResult(transfer, error, rays, skipped, decided, doubt, np.array(curve), _records(hits, used))


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


def _blocked_round(caster, origins, normals, lattice, unshadowed, flat, ring_planes, settings, clip=None):
    """One round for g ray groups of k rows (origins (g, 3), the rest (g, k, ...)): each group casts R replicates of
    its own shifted lattice from its origin. `lattice`: each group's frames (g, 3, 3) and cap floor (g,) or None
    (see core.ray_groups), the lattice points (m, 2) and each group's shifts (g, R, 2). Returns the mean and
    variance over replicates of each row's transfer estimate (g, k, n²), the hits (interreflected mode) and the rays
    each group cast (g,).

    A group of one samples its row's cosine lobe. A larger group samples the cap n̄·ω ≥ s about its mean normal n̄
    that covers every row's hemisphere, with density ∝ (n̄·ω − s)^q (q = sampling.CAP_EXPONENT); each row weighs each
    direction by its own cosine density over the cap's, W = 2(1 − s)^(q+1)·(n·ω)₊ / ((q + 1)(n̄·ω − s)^q): unbiased,
    and near 1 where the normals nearly agree (s = 0 and n = n̄: W = 2(n·ω)^(1−q)/(q + 1), whose mean square
    4/((q + 1)(3 − q)) is 1.016 at q = 0.75), so all rows of a vertex share one lattice at the cost of one row. A row
    estimates T = β·T_unshadowed + mean(W·((1 − β)·Y − (1 − V)·Y)), a control variate whose coefficient β is its
    visible fraction this round: β = 1 samples only blocked light (exact for an open vertex), β = 0 only visible light
    (exact for a buried one), in between it tracks the optimal coefficient.
    Rays are cast only where the answer is not known: one whose every weight is zero counts for nothing, and one that
    surely crosses a triangle meeting at its group's vertex (`ring_planes`: the group's, or None) is blocked, and so
    is one below its group's `clip` plane (groups of one: (g, 3), zero for none; None: none).
    Flat polygons (`flat`: each group's cone planes (g, P, m, 3), the same for its rows as they share their origin,
    and the transfer G they block for each row; None without any) are exact: a ray counts as blocked only for what
    they do not explain, 1 − V − g with g its hits on them, and G is subtracted; unbiased for any polygon, and P's
    edges add no noise where P really is occluder geometry."""
    replicates, order = settings.replicates, settings.order
    groups, size = normals.shape[:2]
    lattice_frames, floor, points, shifts = lattice
    per_replicate, dtype = len(points), ray_groups.weight_dtype(size)
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
    known = None if ring_planes is None else rings.surely_hit(ring_planes, coordinates.astype(np.float32, copy=False))
    if clip is not None:
        below = np.matmul(clip[:, None].astype(dtype), coordinates)[:, 0] < 0.0  # (g, R·m)
        known = below if known is None else known | below
    if known is not None:
        live = ~known if live is None else live & ~known
    cast_rays = np.full(groups, cast.shape[1]) if live is None else np.count_nonzero(live, axis=1)
    if live is not None and cast_rays.sum() == live.size:
        live = None
    hits = caster.engine.hits(origins, cast, live) if settings.mode == "interreflected" else None
    occluded = caster.engine.occluded(origins, cast, live) if hits is None else hits.found
    if known is not None:
        occluded = occluded | known
    blocked = occluded.reshape(groups, 1, replicates, per_replicate)
    if flat is not None:
        cones, flat_blocked = flat  # a group's cones: its rows share their origin
        blocked = blocked - polygons.hits(cast, cones).reshape(groups, 1, replicates, per_replicate)
    if size == 1:  # every weight is 1
        beta = 1.0 - blocked.mean(axis=(2, 3))[..., None, None]
        weights[...] = 1.0 / per_replicate
        if clip is None:
            np.multiply(blocked, 1.0 / per_replicate, out=blocked_weights)
        else:  # but 0 below a clip plane, where the lune's transfer (`unshadowed`) stands for the rays with β = 1: a
            # β from the rays in a thin lune, none in most replicates, would pull its estimate towards the open lune
            rows = np.abs(clip).sum(-1) > 0
            weights[rows] *= ~below[rows].reshape(-1, 1, replicates, per_replicate)
            np.multiply(blocked, weights, out=blocked_weights)
            beta[rows] = 1.0
        weights = None
    else:
        np.multiply(weights, blocked.astype(dtype), out=blocked_weights)
        beta = 1.0 - blocked_weights.sum(axis=(2, 3))[..., None, None] / replicates  # (g, k, 1, 1)
    round_hits = None if hits is None else _round_hits(caster, cast, hits, weights, per_replicate)
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


def _round_hits(caster, cast, hits, weights, per_replicate):
    """(row in g·k, triangle, barycentric, weight, replicate) for every ray of `cast` (g, n, 3) that hit a front
    face (`hits`: core.ray_engine.RayHits), once for each row of the casting group whose estimate it enters, with that
    row's weight W for it (`weights`: W/m). The light leaving a surface is known on its front."""
    group, ray = np.nonzero(hits.found)
    triangle = hits.triangle[group, ray]
    corners = caster.vertices[caster.triangles[triangle]]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    front = np.einsum("ij,ij->i", normals, cast[group, ray]) < 0
    group, ray, triangle, barycentric = group[front], ray[front], triangle[front], hits.barycentric[group, ray][front]
    replicate = ray // per_replicate
    if weights is None:
        return group, triangle, barycentric, np.ones(len(group)), replicate
    size = weights.shape[1]
    hit_weights = weights.reshape(len(weights), size, -1)[group, :, ray] * per_replicate  # (H, k): W, not W/m
    hit, member = np.nonzero(hit_weights > 0.0)
    return group[hit] * size + member, triangle[hit], barycentric[hit], hit_weights[hit, member], replicate[hit]

