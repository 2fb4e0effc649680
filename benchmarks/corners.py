"""What shading-aware transfer costs, measured side by side in one run.

    .venv/bin/python benchmarks/corners.py [--asset ../shared/assets/cow.obj] [--against REV] [--repeats 3]
        [--bakes 3] [--json [DIR]] [--quick]

1. Flat ÷ smooth at equal estimated error: the asset imported as a user would (OBJ without normals: flat-shaded)
   and the same mesh after Shade Smooth. The smooth mesh bakes shadowed at the defaults (order 4, 256 samples);
   the flat one at the fewest samples (a multiple of the replicates) whose estimated RMS error is at most the
   smooth bake's, found by baking it. Goal ≤ 1.5 (issue #13). Also printed: both at 256 samples, and that ratio
   scaled by (est. flat ÷ est. smooth)^(1/0.79), the convergence rate's prediction from one pair, which is not
   judged: it scales the work that does not grow with the samples (gathering the scene, the contact search) as if
   it did.
2. A smooth mesh before and after: the same smooth bake with this checkout and with revision REV (default: the
   commit before shading-aware transfer). Goal within 5 %.
Both sides bake in each of REPEATS fresh processes, taking turns BAKES times (the asset imported anew each time;
REV's add-on imported beside this checkout's under another name). The goal is judged on the median ratio of the
pairs of bakes taken in turn, and the ratio of the two sides' fastest bakes is printed beside it (see paired_ratio).
Both compare the transfer bake: what other issues added to every bake since REV is timed apart and printed: the
probes between vertices (#14's interpolation estimate, about 6 % more rays) with their placing, and the
fingerprints stored for the stale check (#16).
--quick is a smoke run: one process of one pair for each comparison (give a small --asset; the goals are for the
full run).
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
sys.path.insert(0, ROOT)

from benchmarks import results as result_files  # noqa: E402

DEFAULT_ASSET = os.path.join(os.path.dirname(ROOT), "shared", "assets", "cow.obj")
BEFORE_SHADING_AWARE = "d8f5541196f64e0fa0ccfe191fdcc045fb01dbd8"  # the commit before the corner split
FLAT_GOAL, SMOOTH_GOAL = 1.5, 0.05
CONVERGENCE_RATE = 0.79  # core.scheduling.CONVERGENCE_RATE; copied so that --against can run revisions without it
REPLICATES = 4  # core.bake.BakeSettings.replicates: samples are split evenly over them

# Run in a fresh process: bakes each side in turn, `bakes` times, the order of the sides turning each time, and prints
# JSON. A side is [folder holding the add-on's package, the package's name, shading, samples]: an older revision's
# add-on is imported under another name beside this checkout's (its imports are relative), so both bake in one process.
BAKE_SCRIPT = r"""
import contextlib, importlib, json, sys, time
asset, sides, bakes = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3])
import bpy
# Other issues' fixed work in a bake, timed apart like the probes' bake where a revision has it: the fingerprints
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
def load(folder, package):
    if folder not in sys.path:
        sys.path.insert(0, folder)
    try:
        scene_bake = importlib.import_module(package + ".blender.scene_bake")
    except ImportError:  # a revision of the older layout, one module for the scene's bake
        scene_bake = importlib.import_module(package + ".baking")
    for module, name in ((".blender.fingerprint", "fingerprints"), (".core.interpolation", "face_probes")):
        try:
            time_apart(importlib.import_module(package + module), name)
        except ImportError:  # a revision without them: nothing to time apart
            pass
    # The saved settings' schema (each object's storage choice, which the bake reads), where a revision has one; a
    # second package finds it registered and leaves it.
    schema_registered = getattr(importlib.import_module(package + ".commands.common"), "schema_registered", None)
    if schema_registered is not None:
        registered.enter_context(schema_registered())
    return scene_bake.SceneBake, importlib.import_module(package + ".core.bake").BakeSettings
registered = contextlib.ExitStack()
bakers = {(folder, package): load(folder, package) for folder, package, _, _ in sides}
times_s, results = [[] for _ in sides], [None] * len(sides)
# Where sides are compared, a first bake of each, untimed, warms the process (modules imported on first use, numpy's
# and Blender's caches): whichever side went first would otherwise carry it. A lone side is baked for its estimate.
for turn in range(-1 if len(sides) > 1 else 0, bakes):
    for index in (range(len(sides)) if turn % 2 == 0 else reversed(range(len(sides)))):
        folder, package, shading, samples = sides[index]
        SceneBake, BakeSettings = bakers[folder, package]
        # each from a file as the user's: the asset imported into an empty scene
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.ops.wm.obj_import(filepath=asset)
        ob = bpy.context.selected_objects[0]
        if shading == "smooth":
            ob.data.shade_smooth()
        bpy.ops.object.select_all(action="DESELECT")
        apart_s[0] = 0.0
        start = time.perf_counter()
        summary = SceneBake(bpy.context, BakeSettings(order=4, samples=samples), [ob.name]).run()
        # The transfer bake alone: the probes between vertices (issue 14, not in REV) are timed apart.
        probes_s = summary.phases_s.get("probes_s", 0.0)
        if turn >= 0:
            times_s[index].append(time.perf_counter() - start - probes_s - apart_s[0])
        results[index] = {"probes_s": probes_s, "apart_s": apart_s[0], "rays": summary.rays,
                          "est": summary.est_rms_rel_error, "line": summary.line()}
registered.close()
print(json.dumps([dict(result, times_s=times) for result, times in zip(results, times_s)]))
"""


def side(shading, samples=256, folder=ROOT, package="prt_addon") -> list:
    """A bake to time: the add-on `package` in `folder` baking the asset `shading` at `samples`."""
    return [folder, package, shading, samples]


def bake(asset, sides, bakes=1) -> list[dict]:
    """`bakes` bakes of each side in one fresh process, taking turns after an untimed first bake of each (none for a
    lone side): per side its times (`times_s`) and the last bake's summary."""
    result = subprocess.run([sys.executable, "-c", BAKE_SCRIPT, asset, json.dumps(sides), str(bakes)],
                            capture_output=True, text=True, timeout=1800, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def paired_ratio(asset, first, second, repeats, bakes) -> tuple[float, float, list, list]:
    """first ÷ second bake time: the median over every pair of bakes taken in turn in one process (`repeats` fresh
    processes of `bakes` pairs each); also each side's fastest bake over all, as a ratio; and both sides' runs.
    Other tenants of a shared machine slow bakes down by most of their speed for seconds at a time. Two bakes
    taken in turn see the same machine, and the median pair drops the pairs one burst hit; the fastest bakes, printed
    beside it, need a quiet moment for each side, which a busy hour may not have."""
    ones, twos = [], []
    for _ in range(repeats):
        one, two = bake(asset, [first, second], bakes)
        ones.append(one)
        twos.append(two)
    pairs = statistics.median(a / b for one, two in zip(ones, twos) for a, b in zip(one["times_s"], two["times_s"]))
    fastest = min(min(one["times_s"]) for one in ones) / min(min(two["times_s"]) for two in twos)
    return pairs, fastest, ones, twos


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
            tried[count] = bake(asset, [side("flat", count)])[0]
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
    parser.add_argument("--repeats", type=int, help="fresh processes, each baking both sides in turn (default 3; "
                        "--quick 1)")
    parser.add_argument("--bakes", type=int, help="bakes of each side in each process (default 3; --quick 1)")
    result_files.add_argument(parser)
    parser.add_argument("--quick", action="store_true", help="a smoke run: --repeats 1 --bakes 1")
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    args.repeats = args.repeats or (1 if args.quick else 3)
    args.bakes = args.bakes or (1 if args.quick else 3)
    asset = os.path.abspath(args.asset)
    print(f"asset {os.path.basename(asset)}, order 4, shadowed, {args.repeats} processes of {args.bakes} pairs of "
          f"bakes taken in turn" + ("  (quick: the goals are for the full run)" if args.quick else ""))

    flat_256, smooth_256 = bake(asset, [side("flat"), side("smooth")])
    samples, tried = equal_error_samples(asset, smooth_256["est"], flat_256["est"])
    time_ratio, fastest_ratio, flat, smooth = paired_ratio(asset, side("flat", samples), side("smooth"),
                                                           args.repeats, args.bakes)
    at_256 = flat_256["times_s"][0] / smooth_256["times_s"][0]
    print("1. flat ÷ smooth at equal estimated error")
    print(f"   at 256 samples each (one pair): time flat ÷ smooth {at_256:.2f}, "
          f"est. error {flat_256['est']:.4f} ÷ {smooth_256['est']:.4f}; predicted by the convergence "
          f"rate (time × error ratio^(1/{CONVERGENCE_RATE})): "
          f"{at_256 * (flat_256['est'] / smooth_256['est']) ** (1 / CONVERGENCE_RATE):.2f}")
    print("   flat samples tried: " + ", ".join(f"{count} (est. {result['est']:.4f})"
                                               for count, result in sorted(tried.items())))
    for label, runs in ((f"flat at {samples} samples", flat), ("smooth at 256", smooth)):
        times = " | ".join(" ".join(f"{t:.2f}" for t in r["times_s"]) for r in runs)
        print(f"   {label}: {times} s; est. {runs[0]['est']:.4f}; {runs[0]['rays']:,} rays; and the probes between "
              f"vertices {runs[0]['probes_s']:.2f} s, fingerprints and probe placing {runs[0]['apart_s']:.3f} s")
        print(f"      {runs[0]['line']}")
    goals = [result_files.goal("flat ÷ smooth bake time at equal estimated error", time_ratio, "<=", FLAT_GOAL)]
    print(f"   flat ÷ smooth at equal estimated error {time_ratio:.2f} (median pair; fastest bakes "
          f"{fastest_ratio:.2f})   goal <= {FLAT_GOAL}   {goals[-1]['verdict']}")

    folder = checkout(args.against)
    alias = tempfile.mkdtemp(prefix="prt_against_package_")
    os.symlink(os.path.join(folder, "prt_addon"), os.path.join(alias, "prt_against"))
    try:
        change, fastest_change, after, before = paired_ratio(asset, side("smooth"),
                                                             side("smooth", folder=alias, package="prt_against"),
                                                             args.repeats, args.bakes)
    finally:
        os.remove(os.path.join(alias, "prt_against"))
        os.rmdir(alias)
        subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", folder], capture_output=True)
    print(f"2. smooth bake, this checkout ÷ {args.against}")
    for label, runs in (("after", after), ("before", before)):
        times = " | ".join(" ".join(f"{t:.2f}" for t in r["times_s"]) for r in runs)
        probes = (f"; and the probes between vertices {runs[0]['probes_s']:.2f} s, fingerprints and probe placing "
                  f"{runs[0]['apart_s']:.3f} s" if runs[0]["probes_s"] else "")
        print(f"   {label:<6} {times} s; {runs[0]['rays']:,} rays{probes}")
    goals.append(result_files.goal(f"smooth bake time, this checkout ÷ {args.against[:7]}", change, "within",
                                   SMOOTH_GOAL))
    print(f"   after ÷ before {change:.3f} (median pair; fastest bakes {fastest_change:.3f})   "
          f"goal within {SMOOTH_GOAL:.0%}   {goals[-1]['verdict']}")
    if args.json:
        result_files.write("corners", args, {
            "flat_over_smooth": time_ratio, "flat_over_smooth_fastest": fastest_ratio, "flat_samples": samples,
            "flat_tried": tried, "flat_256": flat_256, "smooth_256": smooth_256, "smooth_after_over_before": change,
            "smooth_after_over_before_fastest": fastest_change, "flat": flat, "smooth": smooth, "after": after,
            "before": before}, goals, argv)


if __name__ == "__main__":
    main()
