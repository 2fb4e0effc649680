"""Section 7 of benchmarks/engines.py (issue 32, item 4): the two engines' bakes give the same answers. Each case (the
demo scene and every case of benchmarks/assets.py) is baked at the defaults (order 4, shadowed, 256 samples, one
seed, one process) once by each engine, and

a. their transfers are compared point by point against the bakes' own noise: |z| = ‖a − b‖ / sqrt(σa² + σb²), for a
   point's transfer vectors a and b and σ each bake's estimate of the point's noise: the norm of its coefficients'
   standard errors, from the spread of its replicates (core.job.ReceiverResult.std_error; the bake keeps no
   figure per coefficient). Were a and b independent estimates, ‖a − b‖² / (σa² + σb²) would be a sum of squared
   standard normals weighted by each coefficient's share of the variance (the weights summing to 1), whose tail
   beyond 9 is at most that of one squared normal (Székely and Bakirov, 2003): |z| > 3 at no more than 0.27 % of
   the points, as for a normal z. Goal: |z| > 3 at no more than 0.27 % plus three binomial standard deviations of
   the case's points, and nowhere |z| > 6. The bound is for known σ: estimated from 4 replicates, σ is sometimes
   small by chance and the tail heavier, so two bakes of one engine with different seeds, truly independent noise,
   give |z| > 3 at 0.44 % of the cow's points and 0.25 % of the teapot's, and a largest |z| of 5.6 and 25 (mean z²
   1.18 and 1.50, where known σ gives 1). Both engines trace the very same rays, so a point's transfers differ only
   where the answer to one of its rays does (section 1 counts those rays and says why they differ).
b. both bakes are validated against one Cycles render of the case (`prt validate`, 4 passes of 64 samples, as
   benchmarks/assets.py validates): Cycles renders after the first bake, and the second bake is compared with the
   same passes (blender.validation.Validation reads the stored transfer each time it compares), so the difference
   is the engines' alone. Goal: the RMS error against Cycles (its noise taken out) moves by no more than 0.1
   points.
"""

from dataclasses import replace
import math

import numpy as np

from benchmarks import assets
from benchmarks.engine_bakes import ENGINES

Z_FLAG, Z_WORST = 3.0, 6.0
NOISE_SHARE = math.erfc(Z_FLAG / math.sqrt(2.0))  # 0.27 %: a standard normal beyond ±3
RMS_MOVE = 0.001  # of the RMS error against Cycles: 0.1 points


def transfer_z(first, second) -> np.ndarray:
    """Per point |z| (see the module) between two bakes' results (core.job.ReceiverResult) of one receiver: 0 where
    the transfers are equal, infinite where they differ and neither bake estimates any noise."""
    count = len(first.transfer)
    difference = np.linalg.norm(first.transfer.reshape(count, -1).astype(np.float64)
                                - second.transfer.reshape(count, -1), axis=1)
    noise = np.hypot(first.std_error, second.std_error)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(difference == 0.0, 0.0, difference / noise)


def allowed_share(points: int) -> float:
    """The share of `points` beyond |z| = 3 that noise alone stays under: 0.27 % and three binomial standard
    deviations."""
    return NOISE_SHARE + 3.0 * math.sqrt(NOISE_SHARE * (1.0 - NOISE_SHARE) / max(points, 1))


def same_answers(case: assets.Case, settings: assets.Settings) -> dict:
    """The case baked by each engine, its transfers compared point by point and both bakes against one Cycles
    render; prints its two lines."""
    names = assets.build_case(case)
    results, errors, check = {}, {}, None
    for name in ENGINES:
        results[name] = assets.bake_scene(names, replace(settings, ray_engine=name)).results.results
        if check is None:  # Cycles renders once, against the first engine's bake
            check, comparisons, _ = assets.validate(names, settings)
        else:  # its passes against the bake now stored
            comparisons = check.comparisons()
        errors[name] = comparisons[-1].error
    z = np.concatenate([transfer_z(*pair) for pair in zip(*(results[name] for name in ENGINES))])
    row = {"case": case.name, "points": len(z), "differ": int(np.count_nonzero(z)),
           "flagged_share": float(np.mean(z > Z_FLAG)), "allowed_share": allowed_share(len(z)),
           "max_z": float(z.max(initial=0.0)), "rel_rms_error": errors,
           "rms_move": errors["bvhtree"] - errors["embree"], "cycles_s": check.cycles.time_s}
    row["z_pass"] = row["flagged_share"] <= row["allowed_share"] and row["max_z"] <= Z_WORST
    row["cycles_pass"] = abs(row["rms_move"]) <= RMS_MOVE
    print(f"   {case.name:18} {row['points']:6d} points, transfers differ at {row['differ']:4d}: |z| > 3 at "
          f"{100 * row['flagged_share']:.4f} % (allowed {100 * row['allowed_share']:.4f} %), max |z| "
          f"{row['max_z']:.3f}  {'PASS' if row['z_pass'] else 'MISS'}", flush=True)
    print(f"   {'':18} against Cycles ({check.cycles.time_s:.0f} s): RMS Embree {100 * errors['embree']:.3f} %, "
          f"BVHTree {100 * errors['bvhtree']:.3f} %, Δ {100 * row['rms_move']:+.4f} points  "
          f"{'PASS' if row['cycles_pass'] else 'MISS'}", flush=True)
    return row


def same_answers_cases(names: list, settings: assets.Settings) -> list:
    """Every case named, then the figures over all of them → the rows."""
    rows = [same_answers(assets.case_named(name), settings) for name in names]
    points = sum(row["points"] for row in rows)
    flagged = sum(row["flagged_share"] * row["points"] for row in rows) / max(points, 1)
    worst_z = max(row["max_z"] for row in rows)
    print(f"   all {points} points: transfers differ at {sum(row['differ'] for row in rows)}, |z| > 3 at "
          f"{100 * flagged:.4f} %, max |z| {worst_z:.3f}; every case within its noise: "
          f"{'PASS' if all(row['z_pass'] for row in rows) else 'MISS'}")
    move = max(abs(row["rms_move"]) for row in rows)
    print(f"   largest move of the RMS against Cycles {100 * move:.4f} points  goal <= {100 * RMS_MOVE:g}: "
          f"{'PASS' if move <= RMS_MOVE else 'MISS'}", flush=True)
    return rows
