"""Faults of messy models that decide a bake by rule rather than by geometry (docs/design/contact.md), found
by arithmetic alone before any ray: slivers and zero-area faces, parts whose surfaces cross, and parts inside
other closed parts. Each finder returns the triangles at fault, so the interface can select their faces.

Crossing surfaces: every pair of triangles of different parts (a part: triangles connected through shared vertices;
each object's parts are parts of their own) whose bounding boxes overlap and share a cell of a uniform grid (its
cells the median triangle's size) is tested exactly, in batches: an edge of one crossing the other's interior
strictly (its ends on opposite sides of the plane, the crossing inside all three edges), so surfaces that only touch
(a box standing on another, a face on a face) do not cross. Inside: a part whose bounding box lies in another's is
inside it when its sampled vertices' generalised winding numbers with respect to the other (the solid angle its
triangles subtend, over 4π) are none below 1/4 and some above 3/4: a point on the surface has 1/2 or less, so parts
that touch from inside are inside, parts that touch from outside are not. A bake's points inside another part
(points_inside) are judged alike, one by one: Cycles' rays meet that part whichever way they leave, and so do the
bake's, which find them black."""

import numpy as np

SLIVER_RATIO = 0.01      # a sliver's smallest height is below this fraction of its longest edge
DEGENERATE_RATIO = 1e-7  # a zero-area face's smallest height is below this fraction of its longest edge (float32)
PAIRS_AT_ONCE = 1 << 18   # triangle pairs tested exactly at once: bounded memory
INSIDE_SAMPLES = 16       # vertices of a part whose winding numbers decide whether it is inside another
INSIDE_WINDING = 0.75     # a point is inside a part when its winding number's magnitude is above this
WINDING_TERMS = 1 << 20   # point-triangle solid angles evaluated at once: bounded memory
STRICT = 1e-9             # of the scene's size: how far from a plane or an edge a crossing must be


def thin_triangles(positions: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(degenerate (T,), sliver (T,)) bool: each triangle's smallest height, 2·area ÷ its longest edge, against
    its longest edge. A degenerate triangle is not also a sliver."""
    corners = positions[triangles]
    edges = corners[:, [1, 2, 0]] - corners
    longest = np.sqrt((edges ** 2).sum(-1).max(axis=1))
    doubled_area = np.linalg.norm(np.cross(edges[:, 0], edges[:, 1]), axis=1)
    height = doubled_area / np.maximum(longest, np.finfo(float).tiny)
    degenerate = height <= DEGENERATE_RATIO * longest
    return degenerate, ~degenerate & (height < SLIVER_RATIO * longest)


def parts_of(triangles: np.ndarray, vertex_count: int) -> np.ndarray:
    """(T,) each triangle's part: connected through shared vertices, numbered from 0 by their first triangle."""
    label = np.arange(vertex_count)
    while True:  # each triangle pulls its corners to their least label; pointer jumping shortens the chains
        before = label.copy()
        np.minimum.at(label, triangles.ravel(), np.repeat(label[triangles].min(axis=1), 3))
        label = label[label]
        if np.array_equal(label, before):
            break
    _, first, part = np.unique(label[triangles[:, 0]], return_index=True, return_inverse=True)
    renumber = np.empty(len(first), dtype=np.int64)
    renumber[np.argsort(first)] = np.arange(len(first))
    return renumber[part.ravel()]


def crossing_pairs(positions: np.ndarray, triangles: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """(K, 2) the pairs of triangles (first < second) of different `parts` whose surfaces cross."""
    if len(triangles) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    corners = positions[triangles]
    low, high = corners.min(axis=1), corners.max(axis=1)
    size = float(np.linalg.norm(high.max(0) - low.min(0))) or 1.0
    candidates = _grid_pairs(low, high, parts)
    first, second = candidates[:, 0], candidates[:, 1]
    candidates = candidates[(low[first] <= high[second]).all(1) & (low[second] <= high[first]).all(1)]
    crossing = np.concatenate([
        _cross(corners[batch[:, 0]], corners[batch[:, 1]], STRICT * size) | _cross(
            corners[batch[:, 1]], corners[batch[:, 0]], STRICT * size)
        for batch in np.split(candidates, np.arange(PAIRS_AT_ONCE, len(candidates), PAIRS_AT_ONCE))] or
        [np.zeros(0, dtype=bool)])
    return candidates[crossing]


def inside_parts(positions: np.ndarray, triangles: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """(K, 2) pairs (inner part, outer part): the inner part lies inside the outer, closed one (module docstring)."""
    count = int(parts.max(initial=-1)) + 1
    corners = positions[triangles]
    low = np.full((count, 3), np.inf)
    high = np.full((count, 3), -np.inf)
    np.minimum.at(low, parts, corners.min(axis=1))
    np.maximum.at(high, parts, corners.max(axis=1))
    inner, outer = np.nonzero((low[:, None] >= low[None]).all(-1) & (high[:, None] <= high[None]).all(-1))
    found = []
    for part, around in zip(inner, outer):
        if part == around:
            continue
        vertices = np.unique(triangles[parts == part])
        sample = positions[vertices[np.linspace(0, len(vertices) - 1, min(INSIDE_SAMPLES, len(vertices))).astype(int)]]
        winding = np.abs(winding_numbers(sample, corners[parts == around]))
        if (winding >= 0.25).all() and (winding > 0.75).any():
            found.append((part, around))
    return np.array(found, dtype=np.int64).reshape(-1, 2)


def points_inside(points: np.ndarray, positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(n,) bool: each point (n, 3) lies inside a part of `triangles` (over `positions`) that has no vertex at the
    point, the part it is on being its own surface: its winding number with respect to that part is above
    INSIDE_WINDING in magnitude (a point on a surface has 1/2 or less, one inside a closed part 1). Vertices at one
    position join their triangles into one part: a bake's occluders repeat a split vertex per point (a flat-shaded
    box's every face apart). Only the parts whose bounding box holds a point are tested for it."""
    inside = np.zeros(len(points), dtype=bool)
    if not len(points) or not len(triangles):
        return inside
    _, welded = np.unique(_row_keys(positions), return_inverse=True)
    parts = parts_of(welded.ravel()[triangles], len(positions))
    order = np.argsort(parts, kind="stable")
    ends = np.cumsum(np.bincount(parts))
    keys = _row_keys(points)
    for first, end in zip(np.r_[0, ends[:-1]], ends):
        own = triangles[order[first:end]]
        corners = positions[own]
        low, high = corners.min(axis=(0, 1)), corners.max(axis=(0, 1))
        rows = np.flatnonzero(~inside & (points >= low).all(1) & (points <= high).all(1))
        rows = rows[~np.isin(keys[rows], _row_keys(positions[np.unique(own)]))]
        step = max(1, WINDING_TERMS // len(own))
        for batch in np.split(rows, np.arange(step, len(rows), step)):
            inside[batch[np.abs(winding_numbers(points[batch], corners)) > INSIDE_WINDING]] = True
    return inside


def _row_keys(rows: np.ndarray) -> np.ndarray:
    """Each row (n, 3) as one bytes value, so equal positions compare equal (-0.0 made 0.0)."""
    rows = np.ascontiguousarray(rows, dtype=np.float64) + 0.0
    return rows.view(np.dtype((np.void, 24))).ravel()


def winding_numbers(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(n,) generalised winding number of each point (n, 3) with respect to triangles (T, 3, 3): the signed solid
    angles they subtend (Van Oosterom and Strackee), summed over 4π. 1 inside a closed surface wound outward, 0
    outside, 1/2 on a face."""
    a, b, c = (corners[None, :, k] - points[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    numerator = np.einsum("ntk,ntk->nt", a, np.cross(b, c))
    denominator = (la * lb * lc + np.einsum("ntk,ntk->nt", a, b) * lc + np.einsum("ntk,ntk->nt", b, c) * la
                   + np.einsum("ntk,ntk->nt", c, a) * lb)
    return 2.0 * np.arctan2(numerator, denominator).sum(axis=1) / (4.0 * np.pi)


def _grid_pairs(low: np.ndarray, high: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """(K, 2) distinct pairs of triangles (first < second) of different `parts` whose bounding boxes (T, 3) share
    a cell of a grid whose cells are the median box's longest side. Within a cell, a triangle pairs only with those
    of parts after its own, so a part's own neighbours never make a pair."""
    cell = max(float(np.median((high - low).max(1))), 1e-12 * float((high.max(0) - low.min(0)).max()), 1e-300)
    first_cell = np.floor((low - low.min(0)) / cell).astype(np.int64)
    last_cell = np.floor((high - low.min(0)) / cell).astype(np.int64)
    extent = last_cell - first_cell + 1
    per_triangle = extent.prod(1)
    triangle = np.repeat(np.arange(len(low)), per_triangle)
    within = np.arange(len(triangle)) - np.repeat(np.cumsum(per_triangle) - per_triangle, per_triangle)
    steps = extent[triangle]
    cell_of = first_cell[triangle] + np.stack([within // (steps[:, 1] * steps[:, 2]),
                                               within // steps[:, 2] % steps[:, 1], within % steps[:, 2]], 1)
    dims = last_cell.max(0) + 1
    key = (cell_of[:, 0] * dims[1] + cell_of[:, 1]) * dims[2] + cell_of[:, 2]
    order = np.lexsort((parts[triangle], key))
    key, part, triangle = key[order], parts[triangle][order], triangle[order]
    new_cell = np.r_[True, key[1:] != key[:-1]]
    cell_end = _run_ends(new_cell)
    part_end = _run_ends(new_cell | np.r_[True, part[1:] != part[:-1]])
    partners = cell_end - part_end  # the entries of later parts in the same cell
    left = np.repeat(np.arange(len(key)), partners)
    right = np.repeat(part_end, partners) + np.arange(len(left)) - np.repeat(np.cumsum(partners) - partners, partners)
    first, second = np.minimum(triangle[left], triangle[right]), np.maximum(triangle[left], triangle[right])
    codes = np.sort(first * len(low) + second)
    codes = codes[np.r_[True, codes[1:] != codes[:-1]][: len(codes)]]  # a pair sharing several cells, once
    return np.stack([codes // len(low), codes % len(low)], 1)


def _run_ends(starts: np.ndarray) -> np.ndarray:
    """(n,) for each entry, the index after the last entry of its run (`starts` (n,) marks each run's first)."""
    bounds = np.r_[np.flatnonzero(starts), len(starts)]
    return np.repeat(bounds[1:], np.diff(bounds))


def _cross(edges_of: np.ndarray, faces: np.ndarray, tolerance: float) -> np.ndarray:
    """(n,) whether an edge of each triangle `edges_of` (n, 3, 3) crosses the interior of `faces` (n, 3, 3)
    strictly: its ends more than `tolerance` on either side of the plane, the crossing more than `tolerance` inside
    every edge."""
    normal = np.cross(faces[:, 1] - faces[:, 0], faces[:, 2] - faces[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    unit = normal / np.maximum(length, np.finfo(float).tiny)
    heights = np.einsum("nkd,nd->nk", edges_of - faces[:, :1], unit)  # (n, 3) each corner above the plane
    found = np.zeros(len(faces), dtype=bool)
    for start in range(3):
        p, q = edges_of[:, start], edges_of[:, (start + 1) % 3]
        hp, hq = heights[:, start], heights[:, (start + 1) % 3]
        through = (np.minimum(hp, hq) < -tolerance) & (np.maximum(hp, hq) > tolerance) & (length[:, 0] > 0)
        point = p + (hp / np.where(through, hp - hq, 1.0))[:, None] * (q - p)
        inside = through.copy()
        for corner in range(3):
            a, b = faces[:, corner], faces[:, (corner + 1) % 3]
            side = np.einsum("nd,nd->n", np.cross(b - a, point - a), unit)  # distance inside the edge × its length
            inside &= side > tolerance * np.linalg.norm(b - a, axis=1)
        found |= inside
    return found
