"""What shading-aware transfer costs, measured side by side in one run.

    .venv/bin/python benchmarks/corners.py [--asset ../shared/assets/cow.obj] [--against REV] [--repeats 3]
        [--json PATH]

1. Flat ÷ smooth at equal estimated error: the asset imported as a user would (OBJ without normals: flat-shaded)
   and the same mesh after Shade Smooth. The smooth mesh bakes shadowed at the defaults (order 4, 256 samples);
   the flat one at the fewest samples (a multiple of the replicates) whose estimated RMS error is at most the
   smooth bake's, found by baking it. Then both alternate, each in a fresh process; the median of the neighbouring
   pairs' time ratios. Goal ≤ 1.5 (issue #13). Also printed: both at 256 samples, and that ratio scaled by
   (est. flat ÷ est. smooth)^(1/0.79) as earlier versions of this benchmark judged it, which scales the work that
   does not grow with the samples (gathering the scene, the contact search) as if it did.
2. A smooth mesh before and after: the same smooth bake with this checkout and with revision REV (default: the
   commit before shading-aware transfer), each in a fresh process, alternating; the median of the pairs'
   ratios. Goal within 5 %.
Both compare the transfer bake: what other issues added to every bake since REV is timed apart and printed: the
probes between vertices (#14's interpolation estimate, about 6 % more rays) with their placing, and the
fingerprints stored for the stale check (#16).
"""

import argparse
import json
import math
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
REPLICATES = 4  # core.bake.BakeSettings.replicates: samples are split evenly over them

# Run in a fresh process with the add-on of `root` on the path: imports the asset, bakes it, prints JSON.
BAKE_SCRIPT = r"""
import json, sys, time
root, asset, shading, samples = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
sys.path.insert(0, root)
import bpy
try:
    from prt_addon.blender.scene_bake import SceneBake
except ImportError:  # before the restructure
    from prt_addon.baking import SceneBake
from prt_addon.core.bake import BakeSettings
# Other issues' fixed work in a bake, timed apart like the probes' bake where this checkout has it: the fingerprints
# stored for the stale check (#16) and placing the probes between vertices (#14).
apart_s = [0.0]
def time_apart(module, name):
    function = getattr(module, name)
    def timed(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            apart_s[0] += time.perf_counter() - start
    setattr(module, name, timed)
try:
    from prt_addon.blender import fingerprint
    from prt_addon.core import interpolation
    time_apart(fingerprint, "fingerprints")
    time_apart(interpolation, "face_probes")
except ImportError:  # a revision before them
    pass
bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.wm.obj_import(filepath=asset)
ob = bpy.context.selected_objects[0]
if shading == "smooth":
    ob.data.shade_smooth()
bpy.ops.object.select_all(action="DESELECT")
start = time.perf_counter()
summary = SceneBake(bpy.context, BakeSettings(order=4, samples=samples), [ob.name]).run()
# The transfer bake alone: the probes between vertices (issue 14, not in REV) are timed apart.
probes_s = summary.phases_s.get("probes_s", 0.0)
print(json.dumps({"time_s": time.perf_counter() - start - probes_s - apart_s[0], "probes_s": probes_s,
                  "apart_s": apart_s[0], "rays": summary.rays, "est": summary.est_rms_rel_error,
                  "line": summary.line()}))
"""


def bake(root, asset, shading, samples=256) -> dict:
    result = subprocess.run([sys.executable, "-c", BAKE_SCRIPT, root, asset, shading, str(samples)],
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


def equal_error_samples(asset, smooth_est, flat_est) -> tuple[int, dict]:
    """The fewest samples (a multiple of REPLICATES) at which the flat bake's estimated RMS error is at most
    `smooth_est`, and every bake tried ({samples: result}): predicted from the error `flat_est` at 256 samples by the
    convergence rate, then stepped one sample per replicate at a time, baking each, down while met or up until met."""
    predicted = 256 * (flat_est / smooth_est) ** (1.0 / CONVERGENCE_RATE)
    samples = REPLICATES * math.ceil(predicted / REPLICATES)
    tried = {}

    def meets(count):
        if count not in tried:
            tried[count] = bake(ROOT, asset, "flat", count)
        return tried[count]["est"] <= smooth_est

    if meets(samples):
        while samples > REPLICATES and meets(samples - REPLICATES):
            samples -= REPLICATES
    else:
        while not meets(samples):
            samples += REPLICATES
    return samples, tried


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--asset", default=DEFAULT_ASSET, help="an OBJ without normals (imports flat-shaded)")
    parser.add_argument("--against", default=BEFORE_SHADING_AWARE, help="git revision for the smooth bake")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", metavar="PATH")
    args = parser.parse_args(argv)
    asset = os.path.abspath(args.asset)
    print(f"asset {os.path.basename(asset)}, order 4, shadowed, {args.repeats} alternations")

    flat_256, smooth_256 = bake(ROOT, asset, "flat"), bake(ROOT, asset, "smooth")
    samples, tried = equal_error_samples(asset, smooth_256["est"], flat_256["est"])
    time_ratio, flat, smooth = paired_ratio(lambda: bake(ROOT, asset, "flat", samples),
                                            lambda: bake(ROOT, asset, "smooth"), args.repeats)
    print("1. flat ÷ smooth at equal estimated error")
    print(f"   at 256 samples each (one pair): time flat ÷ smooth {flat_256['time_s'] / smooth_256['time_s']:.2f}, "
          f"est. error {flat_256['est']:.4f} ÷ {smooth_256['est']:.4f}; scaled as this benchmark did before "
          f"(time × error ratio^(1/{CONVERGENCE_RATE})): "
          f"{flat_256['time_s'] / smooth_256['time_s'] * (flat_256['est'] / smooth_256['est']) ** (1 / CONVERGENCE_RATE):.2f}")
    print("   flat samples tried: " + ", ".join(f"{count} (est. {result['est']:.4f})"
                                               for count, result in sorted(tried.items())))
    for label, runs in ((f"flat at {samples} samples", flat), ("smooth at 256", smooth)):
        times = " ".join(f"{r['time_s']:.2f}" for r in runs)
        print(f"   {label}: {times} s; est. {runs[0]['est']:.4f}; {runs[0]['rays']:,} rays; and the probes between "
              f"vertices {runs[0]['probes_s']:.2f} s, fingerprints and probe placing {runs[0]['apart_s']:.3f} s")
        print(f"      {runs[0]['line']}")
    met = time_ratio <= FLAT_GOAL
    print(f"   flat ÷ smooth at equal estimated error {time_ratio:.2f}   goal <= {FLAT_GOAL}   "
          f"{'PASS' if met else 'MISS'}")

    folder = checkout(args.against)
    try:
        change, after, before = paired_ratio(lambda: bake(ROOT, asset, "smooth"),
                                             lambda: bake(folder, asset, "smooth"), args.repeats)
    finally:
        subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", folder], capture_output=True)
    print(f"2. smooth bake, this checkout ÷ {args.against}")
    for label, runs in (("after", after), ("before", before)):
        times = " ".join(f"{r['time_s']:.2f}" for r in runs)
        probes = (f"; and the probes between vertices {runs[0]['probes_s']:.2f} s, fingerprints and probe placing "
                  f"{runs[0]['apart_s']:.3f} s" if runs[0]["probes_s"] else "")
        print(f"   {label:<6} {times} s; {runs[0]['rays']:,} rays{probes}")
    met = abs(change - 1.0) <= SMOOTH_GOAL
    print(f"   after ÷ before {change:.3f}   goal within {SMOOTH_GOAL:.0%}   {'PASS' if met else 'MISS'}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"flat_over_smooth": time_ratio, "flat_samples": samples, "flat_tried": tried,
                       "flat_256": flat_256, "smooth_256": smooth_256,
                       "smooth_after_over_before": change, "flat": flat,
                       "smooth": smooth, "after": after, "before": before}, handle, indent=2)


if __name__ == "__main__":
    main()
