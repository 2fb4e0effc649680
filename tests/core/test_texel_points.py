"""Texels as receiver points (core.texels) against geometry
worked out by hand."""

import numpy as np
import pytest

from prt_addon.core import texels

SQUARE = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], dtype=np.float64)


def test_a_unit_square_covers_every_texel_once_and_places_it_at_its_centre():
    layout = texels.rasterise(SQUARE, 8, 4)
    assert len(layout.texels) == 32 and layout.overlapping == 0 and not layout.zero_area.any()
    assert sorted(layout.texels) == list(range(32))
    centres = np.einsum("nc,ncd->nd", layout.barycentric, SQUARE[layout.triangles])
    x, y = layout.texels % 8, layout.texels // 8
    assert np.allclose(centres, np.stack([(x + 0.5) / 8, (y + 0.5) / 4], axis=1))


def test_a_triangle_covers_the_centres_inside_it():
    """Half the square (below its diagonal, edges included) at 4 × 4: the 10 centres with x ≥ y."""
    layout = texels.rasterise(SQUARE[:1], 4, 4)
    x, y = layout.texels % 4, layout.texels // 4
    assert len(layout.texels) == 10 and (x >= y).all()


def test_overlaps_are_counted_and_shared_edges_are_not():
    twice = texels.rasterise(np.concatenate([SQUARE, SQUARE]), 8, 8)
    assert twice.overlapping == 64 - 8 and twice.overlap_share == pytest.approx(56 / 64)  # the diagonal is an edge
    half = texels.rasterise(np.concatenate([SQUARE, SQUARE[:1] * 0.5]), 8, 8)
    assert half.overlapping == 6  # the centres strictly inside the small triangle: x > y, both < 3.5 texels


def test_zero_area_uv_triangles_are_found_and_get_no_texels():
    flat = np.array([[[0.2, 0.2], [0.6, 0.6], [0.4, 0.4]]])
    layout = texels.rasterise(np.concatenate([SQUARE[:1], flat]), 8, 8)
    assert layout.zero_area.tolist() == [False, True] and (layout.triangles == 0).all()


def test_border_texels_are_baked_at_the_nearest_point_of_their_island():
    """An island over the lower-left quarter of a 16 × 16 map: centres 0-7 lie in it, and the texels of column
    and row 8, whose squares reach into it, are placed on its edge; texel (8, 8) touches it at a corner only."""
    layout = texels.rasterise(SQUARE * 0.5, 16, 16)
    x, y = layout.texels % 16, layout.texels // 16
    assert len(layout.texels) == 80 and x.max() == 8 and y.max() == 8 and 8 * 16 + 8 not in layout.texels
    assert layout.overlapping == 0
    points = np.einsum("nc,ncd->nd", layout.barycentric, SQUARE[layout.triangles] * 0.5)
    expected = np.stack([np.minimum((x + 0.5) / 16, 0.5), np.minimum((y + 0.5) / 16, 0.5)], axis=1)
    np.testing.assert_allclose(points, expected, atol=1e-12)


def test_gutters_take_their_islands_values_and_leave_the_islands_alone():
    layout = texels.rasterise(SQUARE * 0.5, 16, 16)  # an island in the lower-left quarter, texels 0-8
    values = np.full((len(layout.texels), 1), 3.0)
    image = texels.to_image(layout, values, gutter=2)
    assert np.all(image[:9, :9] == 3.0) and image[5, 10] == 3.0 and image[10, 5] == 3.0  # 2 texels out
    assert np.all(image[11:, :] == 0.0) and np.all(image[:, 11:] == 0.0)
    assert np.array_equal(texels.from_image(layout, image), values)


def test_surface_points_interpolate_positions_and_corner_normals_and_step_into_their_triangle():
    corners = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]]], dtype=np.float64)
    normals = np.array([[[0, 0, 1], [1, 0, 0], [0, 0, 1]]], dtype=np.float64)
    weights = np.array([[0.5, 0.5, 0.0], [1 / 3, 1 / 3, 1 / 3]])
    positions, unit_normals, inward = texels.surface_points(np.array([0, 0]), weights, corners, normals)
    assert np.allclose(positions, [[1, 0, 0], [2 / 3, 2 / 3, 0]])
    assert np.allclose(unit_normals[0], np.array([1, 0, 1]) / np.sqrt(2))
    assert np.allclose(np.einsum("ij,ij->i", inward, unit_normals), 0.0)  # tangent
    assert inward[0] @ np.array([0, 1, 0]) > 0 and np.allclose(inward[1], 0.0)  # the centroid has no step


def test_resolution_follows_the_texel_size_and_the_target():
    assert texels.resolution_for_texel_size(16.0, 1.0, 0.25) == 16  # a 4 m square filling its UV map
    assert texels.resolution_for_texel_size(16.0, 0.25, 0.25) == 32
    # an error 4 × the target at 1 m spacing: spacing ÷ 16 (error ∝ √spacing at a sharp edge)
    assert texels.resolution_for_target(1.0, 0.04, 0.01, 16.0, 1.0) == 64
    assert texels.resolution_for_target(1.0, 0.001, 0.01, 16.0, 1.0) == 16


def test_memory_grows_with_texels_and_coefficients():
    assert texels.texel_bake_bytes(8192, 8192, 10) > 64 * 2 ** 30
    assert texels.texel_bake_bytes(256, 256, 4) < 64 * 2 ** 20


# -- refinement (core.texel_refine) -------------------------------------------------------------------------------
from prt_addon.core import bake, rules, texel_refine  # noqa: E402
from prt_addon.core.job import ReceiverResult  # noqa: E402
from prt_addon.core.progress import Progress  # noqa: E402


class ExactJob:
    """Stands in for a TransferJob: every point's transfer is `field(position)`, exact (no noise, no rays)."""

    def __init__(self, receivers, field):
        self.receivers, self.field, self.progress = receivers, field, Progress("test")

    def step(self, budget_s):
        return True

    def results(self):
        return [ReceiverResult(self.field(r.positions), np.zeros(len(r.positions)), np.zeros(len(r.positions)),
                               np.ones(len(r.positions), dtype=np.int64), np.zeros(len(r.positions), dtype=bool),
                               rules.measured(len(r.positions)), np.zeros(len(r.positions)))
                for r in self.receivers]


def floor_grid(side, gap_after=None):
    """Every texel of a side × side map on a unit floor; past column `gap_after` the surface jumps 1 m away."""
    y, x = np.divmod(np.arange(side * side), side)
    positions = np.stack([(x + 0.5) / side, (y + 0.5) / side, np.zeros(side * side)], axis=1)
    if gap_after is not None:
        positions[x > gap_after, 0] += 1.0
    normals = np.tile([0.0, 0.0, 1.0], (side * side, 1))
    receiver = bake.Receiver("Floor", positions, normals, 1, np.zeros_like(positions))
    return texel_refine.TexelGrid(receiver, x, y, side, side)


def refine(grid, field, target=0.01):
    settings = bake.BakeSettings(order=1)
    refining = texel_refine.RefiningJob([grid.receiver], {0: grid}, settings, target,
                                        lambda receivers: ExactJob(receivers, field))
    while not refining.step(0.1):
        pass
    return refining


def test_a_linear_field_is_baked_on_the_coarsest_lattice_and_its_borders_and_interpolated_elsewhere():
    grid = floor_grid(128)  # strides 4, 2, 1
    linear = lambda p: (0.3 + 0.2 * p[:, 0] + 0.1 * p[:, 1])[:, None]  # noqa: E731
    refining = refine(grid, linear)
    result = refining.results()[0]
    np.testing.assert_allclose(result.transfer, linear(grid.receiver.positions), rtol=1e-6)
    assert refining.strides == [4, 2, 1]
    baked = sum(refining.baked.values())
    # the coarsest lattice (every 4th), then the last row and column of each finer lattice, whose cells would
    # reach past the map: 126 on the lattice of 2, 127 on every texel
    assert baked == 32 * 32 + (2 * 64 - 1) + (2 * 128 - 1)
    assert sum(refining.interpolated.values()) == 128 * 128 - baked


def test_a_shadow_edge_is_baked_texel_by_texel_and_a_gap_is_never_interpolated_across():
    grid = floor_grid(64)  # strides 2, 1
    step = lambda p: np.where(p[:, 0] < 0.3, 0.1, 0.3)[:, None]  # noqa: E731
    result = refine(grid, step).results()[0]
    np.testing.assert_allclose(result.transfer, step(grid.receiver.positions), atol=1e-7)
    gapped = floor_grid(64, gap_after=30)
    smooth = lambda p: (0.3 + 0.01 * p[:, 0])[:, None]  # noqa: E731 (0.01 m⁻¹: the gap alone is what differs)
    refined = refine(gapped, smooth)
    np.testing.assert_allclose(refined.results()[0].transfer, smooth(gapped.receiver.positions), rtol=1e-6)
    state = refined.states[0]
    assert not state.interpolated[gapped.x == 31].any()  # its cell's corners lie on both sides of the gap


def test_bilinear_sampling_reproduces_a_linear_image_and_clamps_at_its_edges():
    height, width = 6, 8
    y, x = np.mgrid[0:height, 0:width]
    image = np.stack([2.0 * x + 3.0 * y + 1.0, -x + 0.5 * y], axis=-1)  # linear in the texel centres
    uvs = np.array([[0.3, 0.6], [0.5, 0.5], [(2 + 0.5) / width, (4 + 0.5) / height], [0.0, 0.0], [1.0, 1.0]])
    sampled = texels.sample_bilinear(image, uvs)
    inside = uvs[:3] * [width, height] - 0.5
    np.testing.assert_allclose(sampled[:3, 0], 2.0 * inside[:, 0] + 3.0 * inside[:, 1] + 1.0)
    np.testing.assert_allclose(sampled[:3, 1], -inside[:, 0] + 0.5 * inside[:, 1])
    np.testing.assert_allclose(sampled[3], image[0, 0])  # outside the outermost centres: Extend
    np.testing.assert_allclose(sampled[4], image[-1, -1])
