"""Rotation of real SH coefficients, and the quaternion-to-matrix conversion that feeds it.

Convention: rotating coefficients of f by R gives the coefficients of g(ω) = f(Rᵀω), so a
lobe pointing at d ends up pointing at R·d. Band blocks are built from the 3×3 matrix by the
Ivanic–Ruedenberg recurrences (J. Phys. Chem. 100, 6342 (1996), corrected in J. Phys.
Chem. A 102, 9099 (1998)), which use only products of matrix entries: no Euler angles, so
no gimbal singularity.
A rotation may be given as a (3, 3) matrix or as a quaternion (w, x, y, z).
"""
import functools
import math

import numpy as np

from . import sh

_ORTHONORMAL_TOLERANCE = 1e-6  # float32 matrices from Blender still pass


def quaternion_to_matrix(q):
    """(3, 3) rotation matrix of quaternion q = (w, x, y, z); q need not be unit."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def band_matrices(order, R):
    """Rotation blocks [(2l+1, 2l+1) for l < order] of rotation R ((3, 3) or quaternion)."""
    matrix = _as_rotation_matrix(R)
    blocks = [np.ones((1, 1)), _band_one(matrix)][:order]
    for l in range(2, order):
        blocks.append(_next_band(l, blocks[-1], blocks[1]))
    return blocks


def sh_matrix(order, R) -> np.ndarray:
    """(n², n²) the block-diagonal matrix of band_matrices: rotate(c, R) = c @ sh_matrix(order, R).T, as one product
    for many rows at once."""
    matrix = np.zeros((order * order, order * order))
    for l, block in enumerate(band_matrices(order, R)):
        matrix[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2] = block
    return matrix


def rotate(coeffs, R):
    """Coefficients (..., n²) of f(Rᵀω) from those of f (any leading dims, e.g. RGB)."""
    coeffs = np.asarray(coeffs, dtype=np.float64)
    order = math.isqrt(coeffs.shape[-1])
    if order * order != coeffs.shape[-1]:
        raise ValueError(f"{coeffs.shape[-1]} is not a square number of coefficients")
    rotated = np.empty(coeffs.shape[:-1] + (order * order,))
    for l, block in enumerate(band_matrices(order, R)):
        band = slice(l * l, (l + 1) ** 2)
        rotated[..., band] = coeffs[..., band] @ block.T
    return rotated


def zonal_to_sh(zonal, direction):
    """SH of the zonal lobe with coefficients z_l about +Z, turned to point along direction.

    zonal (n,) or (N, n), direction (3,) or (N, 3) -> (n²,) or (N, n²): f_lm = sqrt(4π/(2l+1)) z_l Y_lm(d).
    N lobes in one call share one SH evaluation.
    """
    zonal = np.asarray(zonal, dtype=np.float64)
    order = zonal.shape[-1]
    bands = sh.coefficient_bands(order)
    scale = np.sqrt(4.0 * math.pi / (2 * bands + 1)) * zonal[..., bands]
    return sh.evaluate(order, direction) * scale


def _as_rotation_matrix(rotation):
    """Accept a quaternion or a 3×3 matrix; refuse anything that is not a proper rotation."""
    rotation = np.asarray(rotation, dtype=np.float64)
    if rotation.shape == (4,):
        return quaternion_to_matrix(rotation)
    if rotation.shape != (3, 3):
        raise ValueError(f"expected a (3, 3) matrix or a (4,) quaternion, got {rotation.shape}")
    deviation = np.abs(rotation.T @ rotation - np.eye(3)).max()
    if deviation > _ORTHONORMAL_TOLERANCE or np.linalg.det(rotation) < 0:
        raise ValueError("matrix is not a proper rotation (scaled, sheared or mirrored)")
    return rotation


def _band_one(matrix):
    """Band-1 block: Y_1,(-1, 0, 1) ∝ (-y, z, -x), so it is R permuted and signed."""
    axes = [1, 2, 0]
    signs = np.array([-1.0, 1.0, -1.0])
    return signs[:, None] * matrix[np.ix_(axes, axes)] * signs[None, :]


def _next_band(l, previous, band_one):
    """Band-l block from band l-1: R^l = Σ weight ∘ P-term (u·U + v·V + w·W of I&R)."""
    p_terms = _p_terms(l, previous, band_one)
    source, rows, weights = _recurrence_tables(l)
    return np.einsum("tmn,tmn->mn", weights, p_terms[source, rows])


def _p_terms(l, previous, band_one):
    """I&R's P(i, a, b) for i = -1, 0, 1 as (3, 2l+3, 2l+1), rows a = -l-1..l+1.

    Rows with |a| >= l are zero padding: the recurrence uses them only with zero weight.
    """
    p = np.zeros((3, 2 * l + 3, 2 * l + 1))
    inner = p[:, 2:-2]
    lower, upper = previous[:, 0], previous[:, -1]  # columns b' = -(l-1) and l-1
    inner[:, :, 1:-1] = band_one[:, 1, None, None] * previous
    inner[:, :, -1] = band_one[:, 2, None] * upper - band_one[:, 0, None] * lower
    inner[:, :, 0] = band_one[:, 2, None] * lower + band_one[:, 0, None] * upper
    return p


@functools.lru_cache(maxsize=None)
def _recurrence_tables(l):
    """For the five terms U, V(i=±1), W(i=±1): source i, source row a and weight per (m, m').

    Returns (source (5, 2l+1), rows (5, 2l+1), weights (5, 2l+1, 2l+1)), indices into _p_terms.
    """
    u, v, w = _uvw(l)
    terms = [[(0, m, 1.0)] + _v_terms(m) + _w_terms(m) for m in range(-l, l + 1)]
    source = np.array([[i + 1 for i, _, _ in row] for row in terms]).T
    rows = np.array([[a + l + 1 for _, a, _ in row] for row in terms]).T
    factors = np.array([[f for _, _, f in row] for row in terms]).T
    scales = np.stack([u, v, v, w, w])
    weights = scales * factors[:, :, None]
    for table in (source, rows, weights):
        table.flags.writeable = False  # shared by every call through the cache
    return source, rows, weights


def _uvw(l):
    """I&R Table 1 coefficients u, v, w as (2l+1, 2l+1) arrays over (m, m')."""
    m = np.arange(-l, l + 1)[:, None]
    m_prime = np.arange(-l, l + 1)[None, :]
    abs_m, at_zero = np.abs(m), (m == 0).astype(np.float64)
    denominator = np.where(np.abs(m_prime) < l, (l + m_prime) * (l - m_prime), 2 * l * (2 * l - 1))
    u = np.sqrt((l + m) * (l - m) / denominator)
    v = 0.5 * np.sqrt((1 + at_zero) * (l + abs_m - 1) * (l + abs_m) / denominator)
    v *= 1 - 2 * at_zero
    w = -0.5 * np.sqrt((l - abs_m - 1) * (l - abs_m) / denominator) * (1 - at_zero)
    return u, v, w


def _v_terms(m):
    """V as [(i, a, factor)] for P(i, a, ·): I&R Table 2 as corrected in 1998."""
    if m == 0:
        return [(1, 1, 1.0), (-1, -1, 1.0)]
    if m > 0:
        return [(1, m - 1, math.sqrt(1 + (m == 1))), (-1, 1 - m, -float(m != 1))]
    return [(1, m + 1, float(m != -1)), (-1, -m - 1, math.sqrt(1 + (m == -1)))]


def _w_terms(m):
    """W as [(i, a, factor)]; at m = 0 its coefficient w vanishes, so the terms are zero."""
    if m == 0:
        return [(1, 0, 0.0), (-1, 0, 0.0)]
    if m > 0:
        return [(1, m + 1, 1.0), (-1, -m - 1, 1.0)]
    return [(1, m - 1, 1.0), (-1, 1 - m, -1.0)]
