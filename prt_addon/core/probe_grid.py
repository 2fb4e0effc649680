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

from .arrays import one_thread_product


def probe_points(resolution) -> np.ndarray:
    """(nx·ny·nz, 3) the probes' positions in the volume's frame, at its cells' centres."""
    axes = [(2.0 * np.arange(n) + 1.0) / n - 1.0 for n in resolution]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def probe_positions(matrix_world, resolution) -> np.ndarray:
    """(P, 3) the probes in world space, the volume placed by `matrix_world` (4, 4)."""
    matrix = np.asarray(matrix_world, dtype=np.float64)
    return probe_points(resolution) @ matrix[:3, :3].T + matrix[:3, 3]


def trilinear_weights(local_points, resolution, valid) -> tuple[np.ndarray, np.ndarray]:
    """(probe indices (..., 8), weights (..., 8)) of points (..., 3) in the volume's frame: the corners of each
    point's cell of probe centres, weighted trilinearly over the valid ones (`valid` (P,) bool) and renormalised to
    sum to 1; all zero where none of them is valid. Along an axis of one probe, that probe carries the weight. The
    first index is the cell's own (its lowest corner), so points with the same first index share all 8 probes.

    Column by column, corner by corner: numpy works an (N, 3) or (N, 8) array along its short rows with an inner
    loop of 3 or 8 (core.arrays), and these weights are formed for every vertex of a moving object at every update."""
    resolution = [int(n) for n in resolution]
    points = np.asarray(local_points, dtype=np.float64)
    shape = points.shape[:-1]
    points = points.reshape(-1, 3)
    strides = (resolution[1] * resolution[2], resolution[2], 1)
    base = np.zeros(len(points), dtype=np.int64)
    sides, steps = [], []
    for axis, count in enumerate(resolution):
        # The point in probe units: probe i sits at i, the lattice spans 0..n−1; clamped onto it.
        grid = np.clip((points[:, axis] + 1.0) * (count / 2.0) - 0.5, 0.0, count - 1)
        low = np.minimum(grid.astype(np.int64), max(count - 2, 0))  # grid ≥ 0: truncation is the floor
        fraction = grid - low
        base += low * strides[axis]
        sides.append((1.0 - fraction, fraction))
        # An axis of one probe repeats it, with weight 0 on the repeat.
        steps.append(min(1, count - 1) * strides[axis])
    weights = np.empty((8, len(points)))
    offsets = np.empty(8, dtype=np.int64)
    for corner in range(8):  # x slowest
        x, y, z = corner >> 2, (corner >> 1) & 1, corner & 1
        np.multiply(sides[0][x], sides[1][y], out=weights[corner])
        weights[corner] *= sides[2][z]
        offsets[corner] = x * steps[0] + y * steps[1] + z * steps[2]
    indices = base[:, None] + offsets
    valid = np.asarray(valid, dtype=bool)
    if not valid.all():
        weights *= valid[indices].T
        total = sum(weights[corner] for corner in range(8))
        weights /= np.where(total > 0.0, total, 1.0)
    return indices.reshape(shape + (8,)), weights.T.reshape(shape + (8,))


def probe_lights(matrices, light) -> np.ndarray:
    """(P, 3, n²) the SH of the radiance arriving at each probe from the distant light (3, n²): T_p L, one product
    per probe, each channel through its own matrix where they are coloured (matrices (P, C, n², n²), C = 1 or 3).
    Computed once per light change; every point's light is then a blend of these (blend, shade_points)."""
    matrices = np.asarray(matrices)
    if matrices.shape[1] == 1:
        return np.einsum("pij,cj->pci", matrices[:, 0], light)
    return np.einsum("pcij,cj->pci", matrices, light)


def blend(lights, indices, weights) -> np.ndarray:
    """(..., 3, n²) Σ_k w_k lights[p_k]: the SH light arriving where the probes `indices` (..., 8) carry `weights`,
    from the probes' lights (P, 3, n²)."""
    return np.einsum("...k,...kcj->...cj", weights, lights[indices])


def shade_points(transfer, lights, indices, weights) -> np.ndarray:
    """(N, 3) float32 radiance Σ_k w_k transfer · lights[p_k] at N shading points, transfer (N, n²) (grey) or
    (N, 3, n²) (coloured: channel by channel), with their probes' indices and weights (N, 8) from trilinear_weights.

    The same as shading each point with its blend(), without gathering 8 probes' lights per point: points are
    grouped by their cell, whose 8 probes they share, and each group's transfer rows meet those probes' lights in
    one matrix product, (m, n²) by (n², 8·3); each point then weighs its 8 products (one (1, 8) by (8, 3) product).
    The cells sort as 16-bit keys where they fit, which numpy sorts by radix, 8× faster than 64-bit ones."""
    count, size = len(transfer), lights.shape[-1]
    cells = indices[:, 0]
    key = cells.astype(np.int16) if count and int(cells.max()) < np.iinfo(np.int16).max else cells
    order = np.argsort(key, kind="stable")
    cells = cells[order]
    starts = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]]) if count else np.zeros(0, dtype=np.int64)
    ends = np.r_[starts[1:], count].astype(np.int64)
    # np.take rather than indexing: 2-3× faster on rows this short.
    rows = np.take(np.asarray(transfer, dtype=np.float32), order, axis=0)
    lights = np.asarray(lights, dtype=np.float32)
    products = np.empty((count, 8, 3), dtype=np.float32)
    for start, end in zip(starts, ends):
        around = lights[indices[order[start]]]  # (8, 3, n²)
        if rows.ndim == 2:
            products[start:end] = one_thread_product(rows[start:end], around.reshape(-1, size).T).reshape(-1, 8, 3)
        else:
            for channel in range(3):
                products[start:end, :, channel] = one_thread_product(rows[start:end, channel], around[:, channel].T)
    radiance = np.empty((count, 3), dtype=np.float32)
    weights = np.take(np.asarray(weights, dtype=np.float32, order="C"), order, axis=0)
    radiance[order] = np.matmul(weights[:, None, :], products)[:, 0]
    return radiance
