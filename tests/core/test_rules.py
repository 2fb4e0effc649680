"""The rule that decided each point travels with its result and is counted in the report: on a floor, a point lying
on it facing into it (black), a card's edge standing on it at an angle (rays from in front of both), a corner whose
normal points against its face (measured as Cycles shades it, from behind), and an open point that rays measure. A
black rule's doubt, the sky it may have left out, joins the estimate."""

import numpy as np

from prt_addon.core import bake, corners, executors, job, lobes, polygons, rules

FLOOR = bake.Occluders(np.array([[-5.0, -5.0, 0.0], [5.0, -5.0, 0.0], [5.0, 5.0, 0.0], [-5.0, 5.0, 0.0]]),
                       np.array([[0, 1, 2], [0, 2, 3]]), np.array([[-5.0, -5.0, 0.0], [5.0, 5.0, 0.0]]),
                       engine="reference")
TILTED = np.array([np.sqrt(0.75), 0.0, -0.5])  # 30° below the horizon: the card faces the floor at an angle


def points() -> bake.Receiver:
    """Lying (normal straight down, its face along the floor), touching (a card standing on the floor, its face
    rising from it), against (normal up, its face down: exactly reversed, clipped by its face reversed as
    core.corners.clip_planes gives it), open (a point high above the floor)."""
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.5], [0.0, 2.0, 1.0]])
    normals = np.array([[0.0, 0.0, -1.0], TILTED, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    inward = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    against = np.array([False, False, True, False])
    return bake.Receiver("points", positions, normals, bake.Receiver.key_for("points"), inward, against=against,
                         clip=np.where(against[:, None], [0.0, 0.0, 1.0], 0.0))


def test_each_point_carries_the_rule_that_decided_it_and_the_report_counts_them():
    the_job = job.TransferJob([points()], FLOOR, bake.BakeSettings(order=3, samples=32))
    (result,) = the_job.run()
    assert result.rules.tolist() == [rules.LYING, rules.TOUCHING, rules.AGAINST, rules.MEASURED]
    # Lying is black, and so is the exactly reversed normal, which has no direction in front of both its normal and
    # its face (README, R2), both without a ray; the card's edge sees the half of its hemisphere above the floor,
    # (1 + n·up)/2 of its cosine-weighted sky (its DC coefficient against the open sky's, exactly, as a floor is
    # flat).
    assert not result.transfer[[0, 2]].any() and result.rays[[0, 2]].sum() == 0
    open_dc = result.transfer[3, 0]
    np.testing.assert_allclose(result.transfer[1, 0] / open_dc, (1.0 - 0.5) / 2.0, atol=0.05)
    summary = the_job.summary([result])
    found = {"lying": 1, "touching": 1, "against": 1}
    assert summary.per_object["points"]["decided_by_rule"] == found and summary.decided_by_rule == found
    assert ("decided by rule: 1 lying on a surface (black), 1 touching a surface at an angle, "
            "1 normal against their face (shaded from behind, as Cycles)") in summary.line()


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


def against_plane(tilts_deg) -> bake.Receiver:
    """Points of a plane wound facing down (Ng = −z) high above the floor, each custom normal N tilted `tilt` degrees
    from Ng about y: past 90° it points against its face, and Cycles gathers −N's directions in front of −Ng, the
    open sky above the plane. The receiver is as the bake makes it: `against` and its clip −Ng
    (core.corners.clip_planes)."""
    tilts = np.radians(tilts_deg)
    count = len(tilts)
    normals = np.stack([np.sin(tilts), np.zeros(count), -np.cos(tilts)], axis=1)
    positions = np.stack([np.arange(count) * 0.5, np.zeros(count), np.full(count, 3.0)], axis=1)
    face = np.tile([0.0, 0.0, -1.0], (count, 1))
    against = corners.against_faces(normals, face)
    return bake.Receiver("plane", positions, normals, bake.Receiver.key_for("plane"),
                         np.tile([1.0, 0.0, 0.0], (count, 1)), against=against,
                         clip=corners.clip_planes(face, against, np.zeros(count, dtype=bool)))


def test_a_normal_against_its_face_is_measured_as_the_lune_cycles_leaves_it():
    # A corner whose normal is 120° from its face normal gathers, in Cycles, −N's hemisphere in front of −Ng: the
    # lune of (1 + N·Ng)/2 = 1/4 of the open sky's cosine-weighted light, whose transfer polygons.lune_transfer
    # gives in closed form; the rays that find nothing in it leave that closed form exact, without noise, and no
    # black rule decided it (no doubt). Exactly reversed (180°) it gathers nothing: black, without a ray. The 60°
    # point is not against its face: it sees the sky below the plane, down to the floor.
    order = 3
    plane = against_plane([120.0, 180.0, 60.0, 120.0])
    the_job = job.TransferJob([plane], FLOOR, bake.BakeSettings(order=order, samples=64))
    (result,) = the_job.run()
    assert result.rules.tolist() == [rules.AGAINST, rules.AGAINST, rules.MEASURED, rules.AGAINST]
    assert not result.rel_rule_error.any()
    assert not result.transfer[1].any() and result.rays[1] == 0 and result.rel_error[1] == 0.0
    lune = polygons.lune_transfer(order, -plane.normals[[0, 3]], np.tile([0.0, 0.0, 1.0], (2, 1)))
    np.testing.assert_allclose(lune[:, 0] / lobes.unshadowed_transfer(order, plane.normals[:1])[0, 0], 0.25,
                               rtol=1e-12)  # the lune's DC: a quarter of the sky
    np.testing.assert_allclose(result.transfer[[0, 3]], lune, rtol=0.0, atol=1e-6 * np.abs(lune).max())
    assert (result.rays[[0, 3]] > 0).all() and not result.rel_error[[0, 1, 3]].any()
    summary = the_job.summary([result])
    assert summary.est_rule_rms_rel_error == 0.0 and "decided by rule: 3 normal against their face" in summary.line()


def test_a_point_lying_a_few_degrees_off_the_surface_doubts_the_sky_past_it():
    # A face lying on the floor, its shading normal 5° off straight down (within the 8° lying takes): black, in doubt
    # by the lune past the floor, (1 + n·n_s)/2 of its sky
    tilt = np.radians(5.0)
    lying = bake.Receiver("lying", np.zeros((1, 3)), np.array([[np.sin(tilt), 0.0, -np.cos(tilt)]]), 7,
                          np.array([[np.cos(tilt), 0.0, np.sin(tilt)]]), surface_step=np.array([[1.0, 0.0, 0.0]]))
    the_job = job.TransferJob([lying], FLOOR, bake.BakeSettings(order=1, samples=16))
    (result,) = the_job.run()
    assert result.rules.tolist() == [rules.LYING] and not result.transfer.any()
    np.testing.assert_allclose(result.rel_rule_error, [(1 - np.cos(tilt)) / 2], rtol=1e-9)
    summary = the_job.summary([result])
    assert abs(summary.est_rms_rel_error - (1 - np.cos(tilt)) / 2) < 1e-9
    assert abs(summary.est_rule_rms_rel_error - summary.est_rms_rel_error) < 1e-12
    # more rays take no doubt away: the error against time ends at the same estimate
    assert abs(summary.error_curve[-1].est_rms_rel_error - summary.est_rms_rel_error) < 1e-12


def test_the_doubt_and_the_noise_add_in_quadrature_and_a_higher_order_doubt_is_its_lunes_norm():
    # At order 3 the lying point's doubt is the norm of its lune's transfer past the floor, relative to the
    # unshadowed norm; the card's edge, measured by rays, adds its noise in quadrature.
    order, tilt = 3, np.radians(5.0)
    normal = np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    receiver = bake.Receiver("two", np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), np.array([normal, TILTED]), 7,
                             np.array([[np.cos(tilt), 0.0, np.sin(tilt)], [0.0, 0.0, 1.0]]),
                             surface_step=np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    the_job = job.TransferJob([receiver], FLOOR, bake.BakeSettings(order=order, samples=32))
    (result,) = the_job.run()
    assert result.rules.tolist() == [rules.LYING, rules.TOUCHING]
    lune = polygons.lune_transfer(order, normal[None], np.array([[0.0, 0.0, 1.0]]))
    doubt = np.linalg.norm(lune) / lobes.unshadowed_norm(order)
    np.testing.assert_allclose(result.rel_rule_error, [doubt, 0.0], rtol=1e-12)
    summary = the_job.summary([result])
    total = np.sqrt(np.mean(result.rel_error ** 2 + result.rel_rule_error ** 2))
    assert result.rel_error[1] > 0 and abs(summary.est_rms_rel_error - total) < 1e-12


def test_points_inside_another_part_are_measured_black_and_counted_apart_from_the_rules():
    """A 0.8 cube inside a 2-unit one (both closed, wound outward): every ray from the inner cube's corners meets
    the outer cube from inside, so the rays find them black, no rule decides them, and the report counts them
    inside another part. The outer cube's corners are on their own part: not counted."""
    cube = [(x, y, z) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    outer, inner = np.array(cube, float), np.array(cube, float) * 0.4 + [0.2, 0.0, 0.0]
    vertices = np.concatenate([inner, outer])
    occluders = bake.Occluders(vertices, np.concatenate([triangles, triangles + 8]), vertices, engine="reference")
    receivers = [bake.Receiver(name, positions, normals, bake.Receiver.key_for(name), -normals)
                 for name, positions, normals in (("inner", inner, np.array(cube) / np.sqrt(3)),
                                                  ("outer", outer, np.array(cube) / np.sqrt(3)))]
    the_job = job.TransferJob(receivers, occluders, bake.BakeSettings(order=2, samples=16))
    results = the_job.run()
    assert not results[0].transfer.any() and not results[0].rules.any() and results[1].transfer[:, 0].min() > 0.1
    summary = the_job.summary(results)
    assert summary.inside_another_part == 8 and summary.per_object["inner"]["inside_another_part"] == 8
    assert summary.per_object["outer"]["inside_another_part"] == 0 and summary.decided_by_rule == {}
    assert "; 8 points inside another part (black)" in summary.line()
    # A farm shard holds zeros for the points the other shards bake: it counts only the points it measured.
    counted = []
    for shard in (1, 2):
        sharded = job.TransferJob(receivers, occluders, bake.BakeSettings(order=2, samples=16),
                                  executors.FarmShard((shard, 2)))
        counted.append(sharded.summary(sharded.run()).inside_another_part)
    assert sum(counted) == 8
