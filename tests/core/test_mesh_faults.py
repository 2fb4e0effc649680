"""Faults found before any ray, against closed forms: boxes that cross, touch or nest, slivers and zero-area
triangles, and the parts of a mesh."""

import numpy as np
import pytest

from prt_addon.core import mesh_faults

# A unit box's 8 corners and 12 triangles wound outward, with the face (0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z) of each.
BOX_CORNERS = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
BOX_QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
BOX_TRIANGLES = np.array([t for a, b, c, d in BOX_QUADS for t in ((a, b, c), (a, c, d))])
BOX_FACES = np.repeat(np.arange(6), 2)


def boxes(*placed):
    """One mesh of boxes, each (low corner, size): positions, triangles, and each triangle's box and face."""
    positions = np.vstack([np.asarray(low) + BOX_CORNERS * np.asarray(size) for low, size in placed])
    triangles = np.vstack([BOX_TRIANGLES + 8 * index for index in range(len(placed))])
    return positions, triangles, np.repeat(np.arange(len(placed)), 12), np.tile(BOX_FACES, len(placed))


def test_a_box_is_wound_outward_so_its_inside_winds_once():
    positions, triangles, *_ = boxes(((0, 0, 0), 1))
    winding = mesh_faults.winding_numbers(np.array([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [0.5, 0.5, 1.0]]),
                                          positions[triangles])
    np.testing.assert_allclose(winding, [1.0, 0.0, 0.5], atol=1e-12)


def test_parts_are_the_triangles_connected_through_shared_vertices():
    positions, triangles, box, _ = boxes(((0, 0, 0), 1), ((3, 0, 0), 1), ((6, 0, 0), 1))
    assert np.array_equal(mesh_faults.parts_of(triangles, len(positions)), box)
    shuffled = np.random.default_rng(1).permutation(len(triangles))
    parts = mesh_faults.parts_of(triangles[shuffled], len(positions))
    assert len(np.unique(parts)) == 3 and all(len(np.unique(parts[box[shuffled] == b])) == 1 for b in range(3))


def test_crossing_boxes_cross_at_exactly_the_faces_the_other_box_passes_through():
    """Box B = [0.3, 1.6] × [0.55, 1.7] × [0.7, 1.8] overlaps A = [0, 1]³ at A's corner (1, 1, 1): A's +x, +y and
    +z faces pass through B, and B's -x, -y and -z faces through A; no other face meets the other box (the offsets
    are generic, so no crossing runs along a triangle's diagonal)."""
    positions, triangles, box, face = boxes(((0, 0, 0), 1), ((0.3, 0.55, 0.7), (1.3, 1.15, 1.1)))
    pairs = mesh_faults.crossing_pairs(positions, triangles, box)
    assert len(pairs) and (box[pairs[:, 0]] != box[pairs[:, 1]]).all()
    crossed = set(zip(box[pairs.ravel()].tolist(), face[pairs.ravel()].tolist()))
    assert crossed == {(0, 1), (0, 3), (0, 5), (1, 0), (1, 2), (1, 4)}


@pytest.mark.parametrize("second", [((0, 0, 1), 1), ((1, 0.2, 0.3), 0.5), ((0.25, 0.25, 1), 0.5)],
                         ids=["stacked", "against-a-side", "smaller-on-top"])
def test_boxes_that_touch_do_not_cross_and_neither_is_inside_the_other(second):
    positions, triangles, box, _ = boxes(((0, 0, 0), 1), second)
    assert len(mesh_faults.crossing_pairs(positions, triangles, box)) == 0
    assert len(mesh_faults.inside_parts(positions, triangles, box)) == 0


@pytest.mark.parametrize("inner", [((1, 1, 1), 1), ((0, 1, 1), 1)], ids=["floating", "against-a-wall"])
def test_a_box_inside_another_crosses_nothing_and_is_found_inside(inner):
    positions, triangles, box, _ = boxes(((0, 0, 0), 3), inner)
    assert len(mesh_faults.crossing_pairs(positions, triangles, box)) == 0
    assert mesh_faults.inside_parts(positions, triangles, box).tolist() == [[1, 0]]


def test_slivers_and_zero_area_triangles_by_their_smallest_height():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0.005, 0], [0.5, 0.02, 0], [0.5, 0, 0]], float)
    triangles = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4], [0, 1, 5], [0, 0, 1]])
    degenerate, sliver = mesh_faults.thin_triangles(positions, triangles)
    assert degenerate.tolist() == [False, False, False, True, True]  # collinear; two corners at one place
    assert sliver.tolist() == [False, True, False, False, False]     # height 0.005 and 0.02 of a unit edge



def test_points_inside_another_closed_part_are_found_and_points_on_their_own_part_are_not():
    """A 2-unit box around a 0.8 one: the inner box's corners (its own vertices) are inside the outer box, the outer
    box's corners are on their own part and outside the inner one; a point beside both is inside neither, one
    between the two boxes is inside the outer one."""
    positions, triangles, *_ = boxes(((-1, -1, -1), 2), ((-0.2, -0.4, -0.4), 0.8))
    points = np.concatenate([positions[8:], positions[:8], [[3.0, 0.0, 0.0], [0.0, 0.8, 0.0]]])
    found = mesh_faults.points_inside(points, positions, triangles)
    np.testing.assert_array_equal(found, [True] * 8 + [False] * 8 + [False, True])
    # each triangle with vertices of its own, as a flat-shaded bake's occluders repeat its split vertices: the same
    split = positions[triangles].reshape(-1, 3)
    found = mesh_faults.points_inside(points, split, np.arange(len(split)).reshape(-1, 3))
    np.testing.assert_array_equal(found, [True] * 8 + [False] * 8 + [False, True])
