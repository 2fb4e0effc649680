"""The heatmap's colour map, scale and legend label: known values give known colours."""

import numpy as np
import pytest

from prt_addon.core import heatmap

VIRIDIS_8BIT = [(68, 1, 84), (71, 45, 123), (59, 82, 139), (44, 114, 142), (33, 145, 140), (40, 174, 128),
                (94, 201, 98), (173, 220, 48), (253, 231, 37)]


def linear(srgb_8bit):
    """IEC 61966-2-1, written out independently of the module."""
    c = np.asarray(srgb_8bit, dtype=np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def test_stops_map_to_viridis_and_alpha_is_one():
    top = 0.02
    values = top * np.arange(9) / 8
    rgba = heatmap.heatmap_rgba(values, top)
    assert rgba.dtype == np.float32 and rgba.shape == (9, 4)
    np.testing.assert_allclose(rgba[:, :3], linear(VIRIDIS_8BIT), rtol=1e-6)
    np.testing.assert_array_equal(rgba[:, 3], 1.0)


def test_between_stops_interpolates_in_srgb_and_outside_the_scale_clamps():
    top = 0.5
    rgba = heatmap.heatmap_rgba(np.array([3 / 16 * top, -1.0, 2 * top]), top)
    halfway = (np.array(VIRIDIS_8BIT[1]) + np.array(VIRIDIS_8BIT[2])) / 2
    np.testing.assert_allclose(rgba[0, :3], linear(halfway), rtol=1e-6)
    np.testing.assert_allclose(rgba[1, :3], linear(VIRIDIS_8BIT[0]), rtol=1e-6)
    np.testing.assert_allclose(rgba[2, :3], linear(VIRIDIS_8BIT[-1]), rtol=1e-6)


def test_missing_values_are_neutral_grey():
    np.testing.assert_allclose(heatmap.missing_rgba(2), [[0.21404114, 0.21404114, 0.21404114, 1.0]] * 2,
                               rtol=1e-6)


@pytest.mark.parametrize("value, top", [(0.0137, 0.02), (0.02, 0.02), (0.021, 0.05), (0.05, 0.05),
                                        (0.051, 0.1), (0.0009, 0.001), (3.2, 5.0), (0.0, 1e-4)])
def test_scale_top_is_the_next_1_2_or_5(value, top):
    assert heatmap.nice_ceiling(value) == pytest.approx(top, rel=1e-12)


def test_scale_top_is_the_99th_percentile_rounded_up():
    values = np.concatenate([np.full(995, 0.004), np.full(5, 0.9)])  # 0.5 % outliers do not set the scale
    assert heatmap.scale_top(values) == pytest.approx(0.005, rel=1e-12)
    assert heatmap.scale_top(np.zeros(0)) == heatmap.SMALLEST_TOP


@pytest.mark.parametrize("top, label", [(0.02, "0 – 2 %"), (0.005, "0 – 0.5 %"), (1e-4, "0 – 0.01 %"),
                                        (0.1, "0 – 10 %")])
def test_range_label(top, label):
    assert heatmap.range_label(top) == label


def test_legend_runs_from_the_first_stop_to_the_last():
    legend = heatmap.legend_srgb(5)
    np.testing.assert_allclose(legend, np.array(VIRIDIS_8BIT[::2]) / 255.0, rtol=1e-12)
