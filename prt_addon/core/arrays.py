"""Array helpers the bake's geometry uses: products kept on one thread, and the bounds of many points.

numpy reduces an (N, 3) array along its rows with an inner loop of 3 and multiplies large matrices on every core;
neither suits a bake that runs on one core among others."""

import numpy as np


# Multiplications in one matrix product that OpenBLAS still does on one thread: it splits a larger one over threads,
# and its idle thread then spins (sched_yield) on the other core for about 0.1 s after the product, through the ray
# casts that follow, which a busy second core slows by about 10 % here (and a worker process, one a core, is meant
# to use one). Its limit for a matrix product is 2^18 multiplications, and 9,216 for a matrix times a vector.
SINGLE_THREAD_PRODUCT = 1 << 16


def one_thread_product(rows, matrix):
    """rows (n, d) @ matrix (d, m), bit for bit, in blocks of rows small enough for OpenBLAS to use one thread
    (SINGLE_THREAD_PRODUCT); a vector (d,) is multiplied by einsum, which never threads."""
    if np.ndim(matrix) == 1:
        return np.einsum("ij,j->i", rows, matrix)
    step = max(1, SINGLE_THREAD_PRODUCT // max(1, rows.shape[1] * matrix.shape[1]))
    # Into one C-ordered array: joining the blocks' products (which follow a transposed matrix's order) and
    # reducing along the rows cost 10× the products.
    product = np.empty((len(rows), matrix.shape[1]), dtype=np.result_type(rows.dtype, matrix.dtype))
    for first in range(0, len(rows), step):
        np.matmul(rows[first:first + step], matrix, out=product[first:first + step])
    return product


def bounds(points):
    """(lowest (d,), highest (d,)) of points (N, d) taken column by column: numpy's min(axis=0) of an (N, 3) array
    runs an inner loop of 3, 10-20× slower."""
    points = np.asarray(points)
    return (np.array([points[:, axis].min() for axis in range(points.shape[1])]),
            np.array([points[:, axis].max() for axis in range(points.shape[1])]))
