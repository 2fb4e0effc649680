"""Every bake's own error against its run time (core.error_curve): after each round, the rays, the estimated RMS
error and the seconds. The rows are checked against bakes that stop there: round 1 of a bake with a target error is
the bake without one, its last round is its summary, and the bounces' row the interreflected bake's summary."""

import json

import bpy
import numpy as np
import pytest

from conftest import run_cli
from test_bake_core import COARSE_DISC, FORKED, disc
from test_heatmaps import labels_drawn
from test_interreflect import ENGINE, open_box

from prt_addon.core import bake, error_curve, job

SETTINGS = dict(order=4, samples=64, max_samples=4096)


def points_under_a_disc(count=300, name="w"):
    rng = np.random.default_rng(5)
    positions = np.column_stack([rng.uniform(-1.5, 1.5, (count, 2)), np.zeros(count)])
    return bake.Receiver(name, positions, np.tile([0.0, 0.0, 1.0], (count, 1)), bake.Receiver.key_for(name))


def summary_of(settings, executor=None, receivers=None):
    the_job = job.TransferJob(receivers or [points_under_a_disc()], disc(1.0, 1.0, COARSE_DISC), settings, executor)
    return the_job, the_job.summary(the_job.run())


def test_rows_add_up_over_bakes_run_one_after_another():
    first = [error_curve.Row("round 1", 1.0, 100, 4.0, 4), error_curve.Row("round 2", 3.0, 300, 1.0, 4)]
    second = [error_curve.Row("round 1", 2.0, 50, 9.0, 1), error_curve.Row(error_curve.BOUNCES, 5.0, 50, 16.0, 1)]
    # at round 2 the second bake is as it was after its round 1; at the bounces the first as after its round 2
    assert error_curve.added([first, second]) == [error_curve.Row("round 1", 3.0, 150, 13.0, 5),
                                                   error_curve.Row("round 2", 5.0, 350, 10.0, 5),
                                                   error_curve.Row(error_curve.BOUNCES, 8.0, 350, 17.0, 5)]
    assert error_curve.Row("round 1", 3.0, 150, 13.0, 5).est_rms_rel_error == pytest.approx(np.sqrt(13 / 5))
    assert error_curve.line(first) == ("error against time: round 1 1.0 s 0.00 M rays RMS 1.0000 | "
                                       "round 2 3.0 s 0.00 M rays RMS 0.5000")


def test_round_one_is_the_bake_without_a_target_and_the_last_round_is_the_summary():
    _, without = summary_of(bake.BakeSettings(**SETTINGS))
    the_job, targeted = summary_of(bake.BakeSettings(target_error=0.02, **SETTINGS))
    rows = targeted.error_curve
    assert [row.after for row in rows] == [f"round {k}" for k in range(1, len(rows) + 1)] and len(rows) >= 3
    assert rows[0].rays == without.rays and rows[0].points == without.points == 300
    assert rows[0].est_rms_rel_error == pytest.approx(without.est_rms_rel_error, rel=1e-12)
    assert [(row.after, row.rays, row.squared) for row in without.error_curve] == [
        ("round 1", rows[0].rays, pytest.approx(rows[0].squared, rel=1e-12))]
    assert rows[-1].rays == targeted.rays and rows[-1].est_rms_rel_error == pytest.approx(targeted.est_rms_rel_error)
    assert all(b.rays > a.rays and b.est_rms_rel_error < a.est_rms_rel_error and b.seconds >= a.seconds
               for a, b in zip(rows, rows[1:]))
    assert rows[-1].seconds == pytest.approx(the_job.phase_times["rays_s"])
    # one object: its own curve is the bake's
    assert targeted.per_object["w"]["error_curve"] == rows


def test_workers_give_the_same_rays_and_errors_after_every_round(chunks_baked_here):
    settings = bake.BakeSettings(target_error=0.05, order=4, samples=64, max_samples=1024)
    receivers = [points_under_a_disc(600)]
    _, alone = summary_of(settings, receivers=receivers)
    executor = FORKED(owners=[1, 0, 1, 1, 0])  # a fixed split: the worker bakes three of the five chunks
    executor.min_rays = 0  # a job this small would otherwise stay in one process
    chunks_baked_here.clear()
    _, forked = summary_of(settings, executor, receivers)
    assert chunks_baked_here == [128, 512]
    assert [(row.after, row.rays, row.squared) for row in forked.error_curve] == [
        (row.after, row.rays, row.squared) for row in alone.error_curve]


def test_the_bounces_row_is_the_interreflected_bakes_summary():
    vertices, triangles, normals, polygons = open_box()
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), polygons, solved_vertices=len(vertices),
                               engine=ENGINE)
    the_job = job.TransferJob([bake.Receiver("box", vertices, normals, 9)], occluders,
                              bake.BakeSettings(mode="interreflected", order=3, samples=64, bounces=3),
                              albedo=[np.full((len(vertices), 1), 0.7)])
    summary = the_job.summary(the_job.run())
    rounds, bounced = summary.error_curve
    assert rounds.after == "round 1" and bounced.after == error_curve.BOUNCES and bounced.rays == rounds.rays
    assert bounced.est_rms_rel_error == pytest.approx(summary.est_rms_rel_error)
    assert bounced.est_rms_rel_error > rounds.est_rms_rel_error  # the bounces gather over the same noisy rays
    phases = the_job.phase_times
    assert bounced.seconds == pytest.approx(phases["rays_s"] + phases["gather_setup_s"] + phases["bounces_s"]
                                            + phases["bounce_error_s"])


def test_the_report_the_log_the_stored_bake_and_the_panel_give_the_curve(tmp_path, sample_scene_files, addon):
    out, report = tmp_path / "out.blend", tmp_path / "report.json"
    done = run_cli("bake", sample_scene_files / "suzanne.blend", "--objects", "Plane", "--order", "3", "--samples", "32",
               "--target-error", "0.01", "--max-samples", "512", "--output", out, "--report", report)
    assert done.returncode == 0, done.stderr
    written = json.loads(report.read_text())
    rows = written["error_curve"]
    assert [row["after"] for row in rows][:2] == ["round 1", "round 2"]
    assert rows[-1]["rays"] == written["rays"]
    assert rows[-1]["est_rms_rel_error"] == pytest.approx(written["est_rms_rel_error"])
    assert rows[0]["rays"] == 32 * (written["vertices"] - written["skipped_vertices"])
    logged = next(line for line in done.stdout.splitlines() if line.startswith("PRT bake error against time: "))
    assert logged == "PRT bake " + error_curve.line([error_curve.Row(
        row["after"], row["seconds"], row["rays"], row["squared"], row["points"]) for row in rows])
    bpy.ops.wm.open_mainfile(filepath=str(out), load_ui=False)
    try:
        plane = bpy.data.objects["Plane"]
        stored = [dict(row) for row in plane.data["prt"]["error_curve"]]
        assert stored == written["per_object"]["Plane"]["error_curve"]
        bpy.context.view_layer.objects.active = plane
        drawn = labels_drawn(bpy.types.PRT_PT_bake_info, [])
        assert (f"  after round 1: {rows[0]['seconds']:.1f} s, {rows[0]['rays']:,} rays, "
                f"RMS {rows[0]['est_rms_rel_error']:.4f}") in drawn
    finally:
        bpy.ops.wm.read_homefile(use_empty=True)
