"""The rule that decided each point travels with its result and is counted in the report: on a floor, a point lying
on it facing into it (black), a card's edge standing on it at an angle (rays from in front of both), a corner whose
normal points against its face (black), and an open point that rays measure."""

import numpy as np

from prt_addon.core import bake, job, rules

FLOOR = bake.Occluders(np.array([[-5.0, -5.0, 0.0], [5.0, -5.0, 0.0], [5.0, 5.0, 0.0], [-5.0, 5.0, 0.0]]),
                       np.array([[0, 1, 2], [0, 2, 3]]), np.array([[-5.0, -5.0, 0.0], [5.0, 5.0, 0.0]]),
                       engine="reference")
TILTED = np.array([np.sqrt(0.75), 0.0, -0.5])  # 30° below the horizon: the card faces the floor at an angle


def points() -> bake.Receiver:
    """Lying (normal straight down, its face along the floor), touching (a card standing on the floor, its face
    rising from it), against (normal up, but against its face), open (a point high above the floor)."""
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.5], [0.0, 2.0, 1.0]])
    normals = np.array([[0.0, 0.0, -1.0], TILTED, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    inward = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    return bake.Receiver("points", positions, normals, bake.Receiver.key_for("points"), inward,
                         against=np.array([False, False, True, False]))


def test_each_point_carries_the_rule_that_decided_it_and_the_report_counts_them():
    the_job = job.TransferJob([points()], FLOOR, bake.BakeSettings(order=3, samples=32))
    (result,) = the_job.run()
    assert result.rules.tolist() == [rules.LYING, rules.TOUCHING, rules.AGAINST, rules.MEASURED]
    # Both black rules are black; the card's edge sees the half of its hemisphere above the floor, (1 + n·up)/2 of
    # its cosine-weighted sky (its DC coefficient against the open sky's, exactly, as a floor is flat).
    assert not result.transfer[[0, 2]].any() and result.rays[[0, 2]].sum() == 0
    open_dc = result.transfer[3, 0]
    np.testing.assert_allclose(result.transfer[1, 0] / open_dc, (1.0 - 0.5) / 2.0, atol=0.05)
    summary = the_job.summary([result])
    found = {"lying": 1, "touching": 1, "against": 1}
    assert summary.per_object["points"]["decided_by_rule"] == found and summary.decided_by_rule == found
    assert ("decided by rule: 1 lying on a surface (black), 1 touching a surface at an angle, "
            "1 normal against their face (black)") in summary.line()


def test_a_bake_no_rule_decided_says_nothing_of_rules():
    open_point = bake.Receiver("open", np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]), 1)
    the_job = job.TransferJob([open_point], FLOOR, bake.BakeSettings(order=2, samples=8))
    summary = the_job.summary(the_job.run())
    assert summary.decided_by_rule == {} and "rule" not in summary.line()
    assert summary.per_object["open"]["decided_by_rule"] == {}


def test_unshadowed_bakes_mark_the_points_against_their_faces():
    the_job = job.TransferJob([points()], FLOOR, bake.BakeSettings(order=2, mode="unshadowed"))
    (result,) = the_job.run()
    assert result.rules.tolist() == [rules.MEASURED, rules.MEASURED, rules.AGAINST, rules.MEASURED]
