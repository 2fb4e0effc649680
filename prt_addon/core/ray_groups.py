"""Ray groups: rows of a chunk that share their rays (the corner points of one vertex whose hemispheres overlap,
core.corners.ray_groups). A group casts one lattice from one origin over the cap n̄·ω ≥ s about its mean normal that
covers every row's hemisphere; each row weighs each ray by its own cosine (core.estimator). This module finds the
groups, their caps and their one origin, and parts a row from its group where one origin cannot serve it."""

import numpy as np

from . import sampling


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


def frames(normals):
    """(c, 3, 3) frames whose rows are a tangent, a bitangent and the unit normal (c, 3)."""
    return np.stack([*sampling.orthonormal_basis(normals), normals], axis=1)


def share_rays(sets, positions, normals, touched, origins, offset) -> list:
    """For each set of shared groups (k > 1) among `sets`, in order: its groups' caps (_caps); and every row of a
    shared group gets the group's one ray origin in `origins` (_shared_origins). The groups of every size are worked
    at once, each padded to the largest with zero normals, which count for nothing below: a chunk of the flat-shaded
    cow holds groups of about 7 sizes, and working each size apart would pay each step's fixed cost per size."""
    shared = [members for members in sets if members.shape[1] > 1]
    if not shared:
        return []
    # each row's step from its vertex to its own origin; a padding row's is zero
    rows, real, (group_normals, group_touched, steps) = _padded(shared, normals, touched, origins - positions)
    vertex = positions[rows[:, 0]]
    cap_frames, floor = _caps(group_normals)
    _, direction, planes, climbs = _planes_to_clear(group_normals, group_touched)
    counts = real.sum(axis=1)
    origins[rows[real]] = np.repeat(_shared_origins(steps, counts, vertex, planes, direction, climbs, offset),
                                    counts, axis=0)
    cuts = np.cumsum([len(members) for members in shared])[:-1]
    return list(zip(np.split(cap_frames, cuts), np.split(floor, cuts)))


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
    return frames(mean_normal), -np.sqrt(1.0 - closest * closest)


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


def alone_unless_lifting(labels, baked, normals, touched):
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
    The directions lose nothing (engines cast in float32), and a replicate's sums over its m rays round by
    √m·2^-24 of their size typically, m·2^-24 at worst (6e-5 at m = 1024), far below the Monte Carlo error they
    carry. A group of one has no k-fold work (its weights are 1) and keeps float64, so a smooth mesh, whose points
    all cast alone, bakes in float64 throughout."""
    return np.float64 if size == 1 else np.float32
