"""Array helpers: products kept on one thread, bit for bit; the bounds of many points."""

import numpy as np

from prt_addon.core import arrays


class _ShapeRecorder(np.ndarray):
    """An array that records the shapes of every matrix product it takes part in."""
    products = []

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        if ufunc is np.matmul:
            _ShapeRecorder.products.append(tuple(np.shape(x) for x in inputs))
        if "out" in kwargs:
            kwargs["out"] = tuple(np.asarray(x) for x in kwargs["out"])
        return getattr(ufunc, method)(*(np.asarray(x) for x in inputs), **kwargs)


def test_one_thread_product_is_the_matrix_product_bit_for_bit_in_blocks_below_the_threading_limit():
    rng = np.random.default_rng(4)
    rows, matrix = rng.standard_normal((5000, 3)), rng.standard_normal((3, 145))
    _ShapeRecorder.products.clear()
    product = arrays.one_thread_product(rows.view(_ShapeRecorder), matrix)
    np.testing.assert_array_equal(np.asarray(product), rows @ matrix)
    sizes = [a[0] * a[1] * b[1] for a, b in _ShapeRecorder.products]
    assert max(sizes) <= arrays.SINGLE_THREAD_PRODUCT and sum(a[0] for a, _ in _ShapeRecorder.products) == 5000
    assert len(sizes) == -(-5000 // (arrays.SINGLE_THREAD_PRODUCT // (3 * 145)))
    # A small product is one block; a vector is taken by einsum (no matrix product at all).
    _ShapeRecorder.products.clear()
    np.testing.assert_array_equal(arrays.one_thread_product(rows[:10].view(_ShapeRecorder), matrix),
                                  rows[:10] @ matrix)
    vector = arrays.one_thread_product(rows.view(_ShapeRecorder), matrix[:, 0])
    assert len(_ShapeRecorder.products) == 1
    np.testing.assert_allclose(vector, rows @ matrix[:, 0], rtol=0, atol=1e-14)


def test_bounds_are_each_columns_extremes():
    points = np.random.default_rng(2).standard_normal((10_001, 3)) * [1.0, 1e-9, 1e9]
    low, high = arrays.bounds(points)
    np.testing.assert_array_equal(low, [min(points[:, 0]), min(points[:, 1]), min(points[:, 2])])
    np.testing.assert_array_equal(high, [max(points[:, 0]), max(points[:, 1]), max(points[:, 2])])
