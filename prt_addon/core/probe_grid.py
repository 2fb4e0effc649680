"""A probe volume's grid, and the light it gives a point: trilinear interpolation of the probes' transfer matrices
(core.probe_transfer) over the valid probes only.

The volume is the cube [−1, 1]³ in its own frame (a Blender Empty's cube), placed by a 4×4 matrix; a resolution
(nx, ny, nz) puts one probe at the centre of each of its nx·ny·nz cells, as Blender's own irradiance volume does, so
one probe along an axis sits in the middle. Probes are numbered x slowest, z fastest (C order over (nx, ny, nz)).

The SH light arriving at a point p from distant light L is Σ_p w_p T_p L, w the trilinear weights of the 8 probes
of p's cell, with those inside geometry given no weight and the rest scaled to sum to 1: a point beside a wall is
lit by the probes on its own side. A point outside the lattice of probe centres takes the nearest cell's face
(its coordinates are clamped to it); a point whose 8 probes are all inside geometry receives no light.

The sum is linear in L, so it is formed from the probes' lights T_p L, computed once per light change (probe_lights):
a point's light is then a gather and a weighted sum (blend), and a moving object's vertices are shaded from them
without forming one matrix per vertex (shade_points).
"""

import numpy as np

from .arrays import SINGLE_THREAD_PRODUCT, one_thread_product


def probe_points(resolution) -> np.ndarray:
    """(nx·ny·nz, 3) the probes' positions in the volume's frame, at its cells' centres."""
    axes = [(2.0 * np.arange(n) + 1.0) / n - 1.0 for n in resolution]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def probe_positions(matrix_world, resolution) -> np.ndarray:
    """(P, 3) the probes in world space, the volume placed by `matrix_world` (4, 4)."""
    matrix = np.asarray(matrix_world, dtype=np.float64)
    return probe_points(resolution) @ matrix[:3, :3].T + matrix[:3, 3]


def placed_points(points, matrix) -> np.ndarray:
    """(N, 3) float32 points (N, 3) through the affine `matrix` (4, 4), e.g. into a volume's frame: the transpose
    of a (3, N) array, so that trilinear_weights reads each axis contiguous. Float32 is what a moving object's
    vertices are stored in, and halves the memory the weights pass through."""
    matrix = np.asarray(matrix, dtype=np.float32)
    points = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    placed = np.empty((3, len(points)), dtype=np.float32)
    step = max(1, SINGLE_THREAD_PRODUCT // 9)
    for first in range(0, len(points), step):
        np.matmul(matrix[:3, :3], points[first:first + step].T, out=placed[:, first:first + step])
    placed += matrix[:3, 3, None]
    return placed.T


def trilinear_weights(local_points, resolution, valid) -> tuple[np.ndarray, np.ndarray]:
    """(probe indices (..., 8), weights (..., 8)) of points (..., 3) in the volume's frame: the corners of each
    point's cell of probe centres, weighted trilinearly over the valid ones (`valid` (P,) bool) and renormalised to
    sum to 1; all zero where none of them is valid. Along an axis of one probe, that probe carries the weight. The
    first index is the cell's own (its lowest corner), so points with the same first index share all 8 probes.
    Weighed in float32 for float32 points (a moving object's vertices, every update), else in float64.

    Column by column, corner by corner, into (8, N) arrays returned transposed (views, F-ordered): numpy works an
    (N, 3) or (N, 8) array along its short rows with an inner loop of 3 or 8 (core.arrays), and shade_points takes
    each corner's weights as one contiguous row."""
    resolution = [int(n) for n in resolution]
    points = np.asarray(local_points)
    points = points.astype(np.float32 if points.dtype == np.float32 else np.float64, copy=False)
    shape = points.shape[:-1]
    points = points.reshape(-1, 3)
    strides = (resolution[1] * resolution[2], resolution[2], 1)
    base = np.zeros(len(points), dtype=np.int32)  # half the memory of intp, and it indexes as well
    sides, steps = [], []
    for axis, count in enumerate(resolution):
        grid = _probe_units(points[:, axis], count)
        np.clip(grid, 0.0, count - 1, out=grid)  # clamped onto the lattice
        low = np.minimum(np.floor(grid), max(count - 2, 0))
        fraction = grid - low
        low = low.astype(np.int32)
        low *= strides[axis]
        base += low
        sides.append((1.0 - fraction, fraction))
        # An axis of one probe repeats it, with weight 0 on the repeat.
        steps.append(min(1, count - 1) * strides[axis])
    offsets = [x * steps[0] + y * steps[1] + z * steps[2] for x in (0, 1) for y in (0, 1) for z in (0, 1)]  # x slowest
    weights = np.empty((8, len(points)), dtype=points.dtype)
    indices = np.empty((8, len(points)), dtype=np.int32)
    for corner, offset in enumerate(offsets):
        x, y, z = corner >> 2, (corner >> 1) & 1, corner & 1
        np.multiply(sides[0][x], sides[1][y], out=weights[corner])
        weights[corner] *= sides[2][z]
        np.add(base, offset, out=indices[corner])
    valid = np.asarray(valid, dtype=bool)
    if not valid.all():
        # Each cell's corners' validity, by its lowest probe (a table of P): only the points of cells with an invalid
        # corner are weighed again, usually the few beside a wall.
        lowest = np.arange(len(valid))
        corner_valid = np.stack([valid[np.minimum(lowest + offset, len(valid) - 1)] for offset in offsets])
        near = np.flatnonzero(~np.take(corner_valid.all(axis=0), base))
        if len(near):
            # Corner by corner along rows, as above: numpy's 2-D fancy indexing of (8, N) walks it across the rows.
            cells, again = base[near], np.empty((8, len(near)), dtype=weights.dtype)
            for corner in range(8):
                np.take(weights[corner], near, out=again[corner], mode="clip")
                again[corner] *= np.take(corner_valid[corner], cells)
            total = np.add.reduce(again, axis=0)
            again /= np.where(total > 0.0, total, 1.0)
            for corner in range(8):
                np.put(weights[corner], near, again[corner], mode="clip")
    return indices.T.reshape(shape + (8,)), weights.T.reshape(shape + (8,))


def _probe_units(coordinates, count: int) -> np.ndarray:
    """Coordinates along a volume axis of `count` probes ([−1, 1]) in probe units: probe i sits at i, the lattice
    spans 0..count−1. In the coordinates' own precision (float32 for a moving object's vertices)."""
    dtype = np.asarray(coordinates).dtype.type
    units = coordinates * dtype(count / 2.0)
    units += dtype(count / 2.0 - 0.5)
    return units


def probes_spanned(local_points, resolution) -> np.ndarray:
    """(K,) the probes of the box of lattice cells that holds points (N, 3) in the volume's frame, one probe wider on
    every side: at least the 8 around each point (trilinear_weights), found from each axis' least and greatest
    coordinate only, so that a moving object's probes' lights can be formed for it alone."""
    points = np.asarray(local_points).reshape(-1, 3)
    ranges = []
    for axis, count in enumerate(int(n) for n in resolution):
        if not len(points):
            ranges.append(np.zeros(0, dtype=np.int64))
            continue
        column = points[:, axis]
        ends = _probe_units(np.array([column.min(), column.max()], dtype=column.dtype), count)
        low, high = np.clip(np.floor(ends) + (-1, 2), 0, count - 1).astype(np.int64)
        ranges.append(np.arange(low, high + 1))
    return np.ravel_multi_index(np.meshgrid(*ranges, indexing="ij"), tuple(int(n) for n in resolution)).ravel()


def probe_lights(matrices, light) -> np.ndarray:
    """(P, 3, R) the SH of the radiance arriving at each probe from the distant light (3, n²): T_p L, one product
    per probe, each channel through its own matrix where they are coloured (matrices (P, C, R, n²), C = 1 or 3; R
    is n² for square ones, or more where the arriving light keeps a higher order than the light's). In the
    matrices' precision: float32 as a bake stores them, float64 where a reference gives them so. Computed once per
    light change; every point's light is then a blend of these (blend, shade_points).

    Real matrix products, not einsum (3-7× slower here): a product per probe, numpy looping over them in C; grey,
    the light's 3 channels by the probe's matrix at once."""
    matrices = np.asarray(matrices)
    count, channels, rows = matrices.shape[:3]
    light = np.asarray(light, dtype=np.result_type(matrices.dtype, np.float32))
    found = np.empty((count, 3, rows), dtype=np.result_type(matrices.dtype, light.dtype))
    if channels == 1:
        np.matmul(light, matrices[:, 0].transpose(0, 2, 1), out=found)
    else:
        for channel in range(3):
            np.matmul(matrices[:, channel], light[channel], out=found[:, channel])
    return found


def blend(lights, indices, weights) -> np.ndarray:
    """(..., 3, n²) Σ_k w_k lights[p_k]: the SH light arriving where the probes `indices` (..., 8) carry `weights`,
    from the probes' lights (P, 3, n²)."""
    return np.einsum("...k,...kcj->...cj", weights, lights[indices])


def shade_points(transfer, lights, indices, weights, turn=None, rows=None) -> np.ndarray:
    """(N, 3) float32 radiance Σ_k w_k transfer · lights[p_k] at N shading points, transfer (N, s) (grey) or
    (N, 3, s) (coloured: channel by channel), with their probes' indices and weights (N, 8) from trilinear_weights,
    from the probes' lights (P, 3, s); `turn` (s, s): a rotation of SH (core.rotation.sh_matrix) the lights are taken
    through first (lights @ turn.T), applied to the probes the points reach only. `rows` (N,): the points' rows of
    `transfer` where it holds more (an object partly in a volume), read in place rather than copied.

    The same as shading each point with its blend(), without gathering 8 probes' lights per point: points are
    grouped by their cell, whose 8 probes they share, and each group's transfer rows meet those probes' lights in
    matrix products (8·3, s) by (s, m) (kept under core.arrays.SINGLE_THREAD_PRODUCT); each corner's row of products
    is then weighed and the 8 summed along rows of m, while the group is in cache. The cells sort as 16-bit keys
    where they fit, which numpy sorts by radix, 8× faster than 64-bit ones."""
    # C order for np.take, which would copy the whole array for every cell otherwise.
    transfer = np.ascontiguousarray(transfer, dtype=np.float32)
    indices = np.asarray(indices)
    count, size = len(indices), np.shape(lights)[-1]
    if not count:
        return np.zeros((count, 3), dtype=np.float32)
    cells = indices[:, 0]
    if int(cells.max()) < np.iinfo(np.int16).max:
        cells = cells.astype(np.int16)
    order = np.argsort(cells, kind="stable")
    sources = order if rows is None else np.asarray(rows)[order]  # each point's transfer row, in the cells' order
    cells = cells[order]
    starts = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]])
    ends = np.r_[starts[1:], count]
    around = indices[order[starts]]  # (cells, 8): each cell's probes
    reached = np.unique(around)
    used = np.empty((len(lights), 3, size), dtype=np.float32)
    rows = np.asarray(lights)[reached].reshape(-1, size)
    used[reached] = (rows if turn is None else one_thread_product(rows, np.asarray(turn).T)).reshape(-1, 3, size)
    # (8, N) with corners along the rows: trilinear_weights' own layout, whose transpose it returns (so no copy).
    by_corner = np.ascontiguousarray(np.asarray(weights, dtype=np.float32).T)
    largest = int(np.max(ends - starts))
    gathered = np.empty((largest,) + transfer.shape[1:], dtype=np.float32)
    products, weighed = np.empty(24 * largest, dtype=np.float32), np.empty(8 * largest, dtype=np.float32)
    shaded = np.empty((3, count), dtype=np.float32)  # in the cells' order
    for probes, start, end in zip(around, starts.tolist(), ends.tolist()):
        points, m = order[start:end], end - start
        # np.take's mode "clip" writes straight into `out` ("raise" goes through a temporary).
        block = np.take(transfer, sources[start:end], axis=0, out=gathered[:m], mode="clip")
        cell, found = used[probes], products[:24 * m].reshape(8, 3, m)
        if transfer.ndim == 2:
            _product_into(cell.reshape(24, size), block, found.reshape(24, m))
        else:
            for channel in range(3):
                _product_into(cell[:, channel], block[:, channel], found[:, channel])
        found *= np.take(by_corner, points, axis=1, out=weighed[:8 * m].reshape(8, m), mode="clip")[:, None]
        np.add.reduce(found, axis=0, out=shaded[:, start:end])
    # Back to the points' order by a gather through the inverse order: 2× faster than scattering through `order`.
    place = np.empty(count, dtype=np.intp)
    place[order] = np.arange(count)
    return np.take(shaded, place, axis=1).T


def _product_into(matrix, rows, out):
    """out (r, m) = matrix (r, s) @ rows (m, s)ᵀ in pieces small enough for OpenBLAS to use one thread
    (core.arrays.SINGLE_THREAD_PRODUCT), the whole pieces in one stacked call: numpy loops over them in C, which
    halves the time of a loop in Python over pieces this small."""
    count, size = rows.shape
    step = max(1, SINGLE_THREAD_PRODUCT // (len(matrix) * size))
    whole = count - count % step
    if whole:
        # Both reshapes split an axis, so they are views: the products land in `out`.
        np.matmul(matrix, rows[:whole].reshape(-1, step, size).transpose(0, 2, 1),
                  out=out[:, :whole].reshape(len(matrix), -1, step).transpose(1, 0, 2))
    if whole < count:
        np.matmul(matrix, rows[whole:].T, out=out[:, whole:])
