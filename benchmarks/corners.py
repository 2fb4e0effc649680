"""What shading-aware transfer costs, measured side by side in one run.

    .venv/bin/python benchmarks/corners.py [--asset ../shared/assets/cow.obj] [--target-error 0]
        [--against REV] [--repeats 3] [--json PATH]

1. Flat ÷ smooth at equal estimated error: the asset imported as a user would (OBJ without normals: flat-shaded)
   and the same mesh after Shade Smooth, each baked shadowed at the defaults (order 4, 256 samples; or to a target
   error), alternating; the median of the neighbouring pairs' time ratios. Equal error: the flat bake's time is
   scaled by (its estimated RMS error ÷ the smooth one's)^(1/0.79), the rays it would need for the smooth bake's
   error at this estimator's measured convergence rate (core.bake.CONVERGENCE_RATE). Goal ≤ 1.5 (issue #13).
2. A smooth mesh before and after: the same smooth bake with this checkout and with revision REV (default: the
   commit before shading-aware transfer), each in a fresh process, alternating; the median of the pairs'
   ratios. Goal within 5 %.
Both compare the transfer bake: the probes between vertices that a bake now also bakes (its interpolation estimate,
about 6 % more rays) are timed apart and printed.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_ASSET = os.path.join(os.path.dirname(ROOT), "shared", "assets", "cow.obj")
BEFORE_SHADING_AWARE = "d8f5541196f64e0fa0ccfe191fdcc045fb01dbd8"  # the commit before the corner split
FLAT_GOAL, SMOOTH_GOAL = 1.5, 0.05
CONVERGENCE_RATE = 0.79  # core.bake.CONVERGENCE_RATE; copied so that --against can run revisions without it

# Run in a fresh process with the add-on of `root` on the path: imports the asset, bakes it, prints JSON.
BAKE_SCRIPT = r"""
import json, sys, time
root, asset, shading, target = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
sys.path.insert(0, root)
import bpy
try:
    from prt_addon.blender.scene_bake import SceneBake
except ImportError:  # before the restructure
    from prt_addon.baking import SceneBake
from prt_addon.core.bake import BakeSettings
bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.wm.obj_import(filepath=asset)
ob = bpy.context.selected_objects[0]
if shading == "smooth":
    ob.data.shade_smooth()
bpy.ops.object.select_all(action="DESELECT")
start = time.perf_counter()
samples = 64 if target > 0 else 256
summary = SceneBake(bpy.context, BakeSettings(order=4, samples=samples, target_error=target), [ob.name]).run()
# The transfer bake alone: the probes between vertices (issue 14, not in REV) are timed apart.
probes_s = summary.phases_s.get("probes_s", 0.0)
print(json.dumps({"time_s": time.perf_counter() - start - probes_s, "probes_s": probes_s, "rays": summary.rays,
                  "est": summary.est_rms_rel_error, "line": summary.line()}))
"""


def bake(root, asset, shading, target) -> dict:
    result = subprocess.run([sys.executable, "-c", BAKE_SCRIPT, root, asset, shading, str(target)],
                            capture_output=True, text=True, timeout=1800, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def paired_ratio(first, second, repeats) -> tuple[float, list, list]:
    """Median over alternating pairs of first() ÷ second() times, and both sides' runs."""
    ones, twos = [], []
    for _ in range(repeats):
        ones.append(first())
        twos.append(second())
    return statistics.median(a["time_s"] / b["time_s"] for a, b in zip(ones, twos)), ones, twos


def checkout(revision) -> str:
    folder = tempfile.mkdtemp(prefix="prt_against_")
    subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", folder, revision], check=True,
                   capture_output=True)
    return folder


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", default=DEFAULT_ASSET, help="an OBJ without normals (imports flat-shaded)")
    parser.add_argument("--target-error", type=float, default=0.0, help="0: the default bake (256 samples)")
    parser.add_argument("--against", default=BEFORE_SHADING_AWARE, help="git revision for the smooth bake")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", metavar="PATH")
    args = parser.parse_args(argv)
    asset, target = os.path.abspath(args.asset), args.target_error
    print(f"asset {os.path.basename(asset)}, order 4, shadowed, "
          f"{f'target error {target}' if target else '256 samples'}, {args.repeats} alternations")

    time_ratio, flat, smooth = paired_ratio(lambda: bake(ROOT, asset, "flat", target),
                                            lambda: bake(ROOT, asset, "smooth", target), args.repeats)
    error_ratio = statistics.median(f["est"] for f in flat) / statistics.median(s["est"] for s in smooth)
    ratio = time_ratio * error_ratio ** (1.0 / CONVERGENCE_RATE)
    print("1. flat ÷ smooth at equal estimated error")
    for label, runs in (("flat", flat), ("smooth", smooth)):
        times = " ".join(f"{r['time_s']:.2f}" for r in runs)
        print(f"   {label:<7} {times} s; est. {runs[0]['est']:.4f}; "
              f"{runs[0]['rays']:,} rays; and the probes between vertices {runs[0]['probes_s']:.2f} s")
        print(f"           {runs[0]['line']}")
    print(f"   time flat ÷ smooth {time_ratio:.2f}, est. error flat ÷ smooth {error_ratio:.3f}")
    print(f"   at equal estimated error {ratio:.2f}   goal <= {FLAT_GOAL}   {'PASS' if ratio <= FLAT_GOAL else 'MISS'}")

    folder = checkout(args.against)
    try:
        change, after, before = paired_ratio(lambda: bake(ROOT, asset, "smooth", target),
                                             lambda: bake(folder, asset, "smooth", target), args.repeats)
    finally:
        subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", folder], capture_output=True)
    print(f"2. smooth bake, this checkout ÷ {args.against}")
    for label, runs in (("after", after), ("before", before)):
        times = " ".join(f"{r['time_s']:.2f}" for r in runs)
        probes = f"; and the probes between vertices {runs[0]['probes_s']:.2f} s" if runs[0]["probes_s"] else ""
        print(f"   {label:<6} {times} s; {runs[0]['rays']:,} rays{probes}")
    met = abs(change - 1.0) <= SMOOTH_GOAL
    print(f"   after ÷ before {change:.3f}   goal within {SMOOTH_GOAL:.0%}   {'PASS' if met else 'MISS'}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"flat_over_smooth": ratio, "time_ratio": time_ratio, "error_ratio": error_ratio,
                       "smooth_after_over_before": change, "flat": flat,
                       "smooth": smooth, "after": after, "before": before}, handle, indent=2)


if __name__ == "__main__":
    main()
