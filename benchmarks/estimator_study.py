"""Estimator study: where the shadowed estimator's error at 256 rays per vertex comes from, and what moves it.

The bake benchmark's goal is "ours ÷ seed ≤ 0.1 at 256 rays", which its flat occluders, integrated in closed form,
bring within reach. This study measures, on the same 300 occludable demo vertices and against the same kind of
16,384-ray reference:

1. replicates R = 2, 4, 8 at 256 rays: actual and estimated RMS error (fewer, denser lattices are more accurate);
2. the error against rays at R = 4, its log-log slope, and the ray count at which ours ÷ seed reaches 0.1;
3. the same rays spread unevenly over the vertices (more where the first 128 rays' estimated error is larger);
4. the honesty of the error estimate when a target error decides where to stop, at R = 2 and R = 4.

Run from the repository root:  .venv/bin/python benchmarks/estimator_study.py [--quick]   (under a minute on 2
cores; --quick: the bake benchmark's quick sizes and fewer ray counts, a smoke run of seconds)
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bake as bench  # noqa: E402  (benchmarks/bake.py: the scene, picks, reference and seed estimator)
import numpy as np  # noqa: E402

from prt_addon.core import bake, lobes, ray_caster  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402

SAMPLES = 256
RAY_COUNTS = (128, 256, 512, 1024, 2048)
QUICK_RAY_COUNTS = (128, 256, 512)


def errors(settings, receivers, occluders, picks, reference):
    """(per-vertex norm of the coefficient error, per-vertex estimated standard error) on the picks."""
    transfer, std_error, _ = bench.bake_picks(receivers, occluders, picks, settings)
    return np.linalg.norm(transfer - reference, axis=1), std_error


def replicates_table(receivers, occluders, picks, reference, seed_error):
    print(f"\n1. Replicates at {SAMPLES} rays per vertex (R independent lattices of {SAMPLES}/R points)")
    print(f"   {'R':>3}{'actual RMS':>12}{'estimated':>11}{'ours÷seed':>11}")
    for replicates in (2, 4, 8):
        actual, estimated = errors(bake.BakeSettings(samples=SAMPLES, replicates=replicates),
                                   receivers, occluders, picks, reference)
        print(f"   {replicates:>3}{bench.rms(actual):12.5f}{bench.rms(estimated):11.5f}"
              f"{bench.rms(actual) / seed_error:11.3f}")


def rate_table(receivers, occluders, picks, reference, seed_error, ray_counts):
    print("\n2. Error against rays per vertex, R = 4")
    per_vertex, estimated = {}, {}
    for rays in ray_counts:
        per_vertex[rays], estimated[rays] = errors(bake.BakeSettings(samples=rays, max_samples=max(rays, 16384)),
                                                   receivers, occluders, picks, reference)
        print(f"   {rays:>5} rays   actual RMS {bench.rms(per_vertex[rays]):.5f}   ours÷seed(256) "
              f"{bench.rms(per_vertex[rays]) / seed_error:.3f}")
    rms = np.array([bench.rms(per_vertex[rays]) for rays in ray_counts])
    slope = np.polyfit(np.log(ray_counts), np.log(rms), 1)[0]
    crossing = np.exp(np.interp(np.log(0.1 * seed_error), np.log(rms[::-1]), np.log(ray_counts)[::-1]))
    print(f"   error ∝ rays^{slope:.2f}; ours reaches 1/10 of the seed's 256-ray error at about {crossing:.0f} rays")
    return per_vertex, estimated


def uneven_rays(per_vertex, estimated, seed_error):
    """Each vertex gets one of the measured ray counts, at least 128, more where the 128-ray estimate is larger
    (n ∝ e^p), with the same mean as 256 everywhere; the error of each vertex is the one measured at its count."""
    print(f"\n3. The same total rays spread unevenly (mean ≤ {SAMPLES}, from the 128-ray estimated error)")
    counts = np.array(sorted(per_vertex))
    table = np.stack([per_vertex[rays] for rays in counts], axis=1)
    first = estimated[counts[0]]
    for power in (0.5, 0.75, 1.0):
        best = None
        for scale in np.geomspace(1.0, 1e8, 400):
            level = np.clip(np.searchsorted(counts, np.maximum(counts[0], scale * first ** power), side="right") - 1,
                            0, len(counts) - 1)
            if counts[level].mean() <= SAMPLES:
                best = level
        spent = table[np.arange(len(best)), best]
        print(f"   n ∝ error^{power:.2f}: mean {counts[best].mean():.0f} rays, actual RMS {bench.rms(spent):.5f}, "
              f"ours÷seed {bench.rms(spent) / seed_error:.3f}")


def target_honesty(receivers, occluders, picks, reference, max_samples):
    print("\n4. Target error 0.01 (relative): does the estimate still tell the truth when it decides where to stop?")
    scale = lobes.unshadowed_norm(bench.ORDER)
    for replicates in (2, 4):
        settings = bake.BakeSettings(samples=SAMPLES, replicates=replicates, target_error=0.01,
                                     max_samples=max_samples)
        actual, estimated = errors(settings, receivers, occluders, picks, reference)
        print(f"   R = {replicates}: actual RMS rel. {bench.rms(actual) / scale:.5f}, "
              f"estimated {bench.rms(estimated) / scale:.5f}, actual ÷ estimated "
              f"{bench.rms(actual) / bench.rms(estimated):.2f}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run: the bake benchmark's quick sizes")
    args = parser.parse_args(argv)
    config = bench.QUICK if args.quick else bench.FULL
    ray_counts = QUICK_RAY_COUNTS if args.quick else RAY_COUNTS
    receivers, occluders = bench.scene_geometry()
    caster = ray_caster.RayCaster(occluders)
    picks = bench.pick_vertices(caster, receivers, config.error_vertices, None, True,
                                np.random.default_rng(bench.PICK_SEED))
    reference = bench.reference_transfer(receivers, occluders, picks, config)["transfer"]
    seeds = bench.seed_estimator(caster, picks.positions(receivers), picks.normals(receivers), picks.inward(receivers),
                                 SAMPLES, np.random.default_rng(bench.PICK_SEED + 1))
    seed_error = bench.rms_error(seeds, reference)
    print(f"{len(picks.owner)} occludable demo vertices, order {bench.ORDER}; seed's estimator at {SAMPLES} rays: "
          f"RMS error {seed_error:.5f}")
    replicates_table(receivers, occluders, picks, reference, seed_error)
    per_vertex, estimated = rate_table(receivers, occluders, picks, reference, seed_error, ray_counts)
    uneven_rays(per_vertex, estimated, seed_error)
    target_honesty(receivers, occluders, picks, reference, config.max_samples)
    return 0


if __name__ == "__main__":
    with schema_registered():  # each object's storage choice, which the bake reads, is a schema property
        sys.exit(main())
