"""A probe volume's grid, and the light it gives a point: trilinear interpolation of the probes' transfer matrices
(core.probe_transfer) over the valid probes only.

The volume is the cube [−1, 1]³ in its own frame (a Blender Empty's cube), placed by a 4×4 matrix; a resolution
(nx, ny, nz) puts one probe at the centre of each of its nx·ny·nz cells, as Blender's own irradiance volume does, so
one probe along an axis sits in the middle. Probes are numbered x slowest, z fastest (C order over (nx, ny, nz)).

The SH light arriving at a point p from distant light L is Σ_p w_p T_p L, w the trilinear weights of the 8 probes
of p's cell, with those inside geometry given no weight and the rest scaled to sum to 1: a point beside a wall is
lit by the probes on its own side. A point outside the lattice of probe centres takes the nearest cell's face
(its coordinates are clamped to it); a point whose 8 probes are all inside geometry receives no light.
"""

import numpy as np


def probe_points(resolution) -> np.ndarray:
    """(nx·ny·nz, 3) the probes' positions in the volume's frame, at its cells' centres."""
    axes = [(2.0 * np.arange(n) + 1.0) / n - 1.0 for n in resolution]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def probe_positions(matrix_world, resolution) -> np.ndarray:
    """(P, 3) the probes in world space, the volume placed by `matrix_world` (4, 4)."""
    matrix = np.asarray(matrix_world, dtype=np.float64)
    return probe_points(resolution) @ matrix[:3, :3].T + matrix[:3, 3]


def trilinear_weights(local_point, resolution, valid) -> tuple[np.ndarray, np.ndarray]:
    """(probe indices (8,), weights (8,)) of a point (3,) in the volume's frame: the corners of its cell of probe
    centres, weighted trilinearly over the valid ones (`valid` (P,) bool) and renormalised to sum to 1; all zero
    where none of them is valid. Along an axis of one probe, that probe carries the weight."""
    resolution = np.asarray(resolution, dtype=np.int64)
    # The point in probe units: probe i sits at i, the lattice spans 0..n−1; clamped onto it.
    grid = np.clip((np.asarray(local_point, dtype=np.float64) + 1.0) * resolution / 2.0 - 0.5, 0.0, resolution - 1)
    low = np.minimum(np.floor(grid).astype(np.int64), np.maximum(resolution - 2, 0))
    fraction = grid - low
    corners = np.array([(a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    cells = np.minimum(low + corners, resolution - 1)  # (8, 3): an axis of one probe repeats it with weight 0
    weights = np.prod(np.where(corners == 1, fraction, 1.0 - fraction), axis=1)
    indices = np.ravel_multi_index(cells.T, tuple(resolution))
    weights = weights * np.asarray(valid, dtype=bool)[indices]
    total = weights.sum()
    return indices, (weights / total if total > 0.0 else weights)


def incoming_light(matrices, indices, weights, light) -> np.ndarray:
    """(3, n²) the SH of the radiance arriving where the probes `indices` carry `weights`: Σ w_p T_p L, with
    matrices (P, C, n², n²) (C = 1 or 3) and the distant light (3, n²), each channel through its own matrix."""
    blended = np.einsum("p,pcij->cij", weights, matrices[indices])  # (C, n², n²)
    return np.einsum("cij,cj->ci", np.broadcast_to(blended, (3,) + blended.shape[1:]), light)
