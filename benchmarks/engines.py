"""The ray engines side by side (issue 32): Embree (embreex) and BVHTree casting the very same rays, in one run.

Every ray batch a bake asks its engine (occluded or hits) is recorded as the Embree bake casts it; the batches do not
depend on the engine's answers (a round's rays are fixed by the seed), so both engines replay exactly the bake's rays.

1. Agreement: the demo scene and every case of benchmarks/assets.py baked at the defaults (256 samples), every
   recorded ray replayed through both engines' `hits`: the share of rays whose occlusion agrees and of hits on the
   same triangle (goal ≥ 99.99 %), and why the rest differ, judged in float64 on the float32 corners: a crossing
   within 1e-4 of a face's edge (rounding decides whether the ray is inside), two faces within 1e-5 of one distance,
   or neither (unexplained).
2. Casts alone: rays/s of `occluded` over the recorded batches, the engines alternating batch by batch, best of
   the passes; Embree ÷ BVHTree (goal ≥ 15×) on the demo and on the demo with its torus subdivided three times
   (1.4 M triangles), the rays of 2048 floor and wall vertices. Beside them a bare Python loop of BVHTree.ray_cast
   calls over the same rays, given as Python lists (the rate one call per ray allows, which the BVHTree engine's
   map over ray_cast nearly reaches; a loop over numpy rows, each parsed as a sequence, runs at half of it), and
   Embree ÷ that loop.
3. The whole demo bake at 256 samples with 2 workers: wall time, BVHTree ÷ Embree (goal ≥ 5×); and one process's
   bake split into casting (occluded, hits), the contact search (nearest, BVHTree in both) and the rest.
4. Memory: resident memory each engine adds, built over the dense scene (the Embree engine holds the contact
   search's BVHTree too).
5. The Final preset on the demo (interreflected, order 6, target 0.5 %) with 2 workers, once per engine: wall time,
   BVHTree ÷ Embree, and each bake split into its rays, its bounces (building G and bouncing) and their error
   estimate; with the load average, as the bounces are most of it and share the machine. Not in --quick.
6. Error against run time: each engine's curve for the demo as its bake reports it (after each round and after the
   bounces: seconds, rays, estimated RMS error), printed and drawn in one figure (--plot): the Final bakes of
   section 5; in --quick, the demo at 64 samples with a 2 % target error.
7. Same answers (benchmarks/engine_answers.py): the demo and every case of benchmarks/assets.py baked by each
   engine, their transfers point by point against the bakes' own noise (a z-test), and both bakes against one
   Cycles render (goal: the RMS moves ≤ 0.1 points).
8. The texel room of benchmarks/texels.py (1024², 1 % target) with 2 workers, the engines alternating, best of 2:
   wall time, BVHTree ÷ Embree (goal ≥ 3×); and one process's bake split into casting and the rest.
Sections 3, 5, 6 and 8 bake whole scenes (benchmarks/engine_bakes.py).

Run from the repository root:  .venv/bin/python benchmarks/engines.py [--quick | --final] [--rays] [--answers]
[--texels] [--json [DIR]] [--plot PNG] [--assets FOLDER]   (--rays: sections 1-4; --final: 5 and 6; --answers: 7;
--texels: 8; any of them together; none: all)
"""

import argparse
from collections import Counter
from dataclasses import asdict, replace
import gc
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (bpy before mathutils, which the core imports)
import numpy as np  # noqa: E402

from benchmarks import assets, engine_curves, results as result_files, texels  # noqa: E402
from benchmarks.bake import time_bare_loop  # noqa: E402
from benchmarks.engine_answers import RMS_MOVE, same_answers_cases  # noqa: E402
from benchmarks.engine_bakes import ENGINES, curve_bakes, final_bakes, planned, texel_room, whole_bakes  # noqa: E402
from prt_addon.blender.execute import execute  # noqa: E402
from prt_addon.blender.request import ray_engine_label  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402
from prt_addon.core import bake, engines, executors, job  # noqa: E402

EDGE = 1e-4   # barycentric margin within which float32 rounding decides whether a ray crosses a face
TIE = 1e-5    # relative distance within which two faces are at one distance
GOALS = {"agreement": (">=", 99.99), "casts": (">=", 15.0), "bake": (">=", 5.0), "texels": (">=", 3.0)}
QUICK_CASES = ["sphere flat", "cylinder"]


class Recording:
    """Stands in for a bake's engine: answers with it, keeping every batch of rays it is asked, as asked."""

    def __init__(self, engine):
        self.engine, self.max_distance, self.batches = engine, engine.max_distance, []

    def _kept(self, origins, directions, live):
        self.batches.append((origins.copy(), directions.copy(order="K"), None if live is None else live.copy()))

    def occluded(self, origins, directions, live=None):
        self._kept(origins, directions, live)
        return self.engine.occluded(origins, directions, live)

    def hits(self, origins, directions, live=None):
        self._kept(origins, directions, live)
        return self.engine.hits(origins, directions, live)

    def nearest(self, points, radius):
        return self.engine.nearest(points, radius)


def rays_in(batches) -> int:
    return sum(directions.shape[0] * directions.shape[1] if live is None else int(live.sum())
               for _, directions, live in batches)


def dense_demo(levels: int):
    """The demo scene with its torus subdivided `levels` times: 1.4 M triangles at 3."""
    assets.fresh_file()
    torus = assets.sample_scenes.build_demo_scene()["torus"]
    torus.modifiers.new("Subdivision", "SUBSURF").levels = levels


# -- 1. agreement --------------------------------------------------------------------------------------------------
def recorded_bake(settings, objects=None):
    """Bakes the scene as it is now with Embree, recording its rays → (caster, recorded batches)."""
    plan = planned(replace(settings, ray_engine="embree"), objects)
    caster = plan.occluders.ray_caster()
    caster.engine = Recording(caster.engine)
    execute(plan, executors.InProcess()).run()
    return caster, caster.engine.batches


def agreement(caster, batches) -> dict:
    """Both engines' hits of every recorded ray: how many rays, how many agree on occlusion and on the face hit, and
    why the others differ."""
    tree = engines.build("bvhtree", caster.vertices, caster.triangles, caster.engine.max_distance)
    embree = caster.engine.engine
    corners = caster.single_vertices.astype(np.float64)[caster.triangles]
    counts, reasons, worst_distance = Counter(), Counter(), 0.0
    for origins, directions, live in batches:
        mine, theirs = embree.hits(origins, directions, live), tree.hits(origins, directions, live)
        cast = np.ones(mine.found.shape, dtype=bool) if live is None else live
        found_differs = cast & (mine.found != theirs.found)
        face_differs = cast & mine.found & theirs.found & (mine.triangle != theirs.triangle)
        same = cast & mine.found & theirs.found & (mine.triangle == theirs.triangle)
        counts.update(rays=int(cast.sum()), hits=int((cast & theirs.found).sum()),
                      found_differs=int(found_differs.sum()), face_differs=int(face_differs.sum()))
        if same.any():
            gap = np.abs(mine.distance[same] - theirs.distance[same]).max() / tree.max_distance
            worst_distance = max(worst_distance, float(gap))
        for group, ray in zip(*np.nonzero(found_differs | face_differs)):
            reasons[why_they_differ(corners, origins[group], directions[group, ray], tree.max_distance)] += 1
    return {**counts, "reasons": dict(reasons), "worst_distance": worst_distance,
            "occlusion_agreement": 1.0 - counts["found_differs"] / max(1, counts["rays"]),
            "face_agreement": 1.0 - (counts["found_differs"] + counts["face_differs"]) / max(1, counts["rays"])}


def why_they_differ(corners, origin, direction, reach) -> str:
    """Why float32 rounding may decide this ray, from every face (`corners` (T, 3, 3): the float32 corners, as the
    engines hold them) it crosses before `reach`, by Möller–Trumbore in float64: 'edge', 'tie' or 'unexplained'."""
    origin, direction = (np.asarray(value, dtype=np.float32).astype(np.float64) for value in (origin, direction))
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("td,td->t", e1, p)
    s = origin - corners[:, 0]
    q = np.cross(s, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v, t = np.einsum("td,td->t", s, p) / det, q @ direction / det, np.einsum("td,td->t", e2, q) / det
    ahead = (t >= 0) & (t <= reach)
    margin = np.minimum.reduce([u, v, 1.0 - u - v])
    if (ahead & (np.abs(margin) < EDGE)).any():
        return "edge"
    crossed = np.sort(t[ahead & (margin >= 0)])
    if len(crossed) > 1 and crossed[1] - crossed[0] <= TIE * max(crossed[0], 1e-9):
        return "tie"
    return "unexplained"


def agreement_cases(quick: bool) -> list:
    names = QUICK_CASES if quick else [case.name for case in assets.CASES]
    rows = []
    for name in names:
        objects = assets.build_case(assets.case_named(name))
        caster, batches = recorded_bake(bake.BakeSettings(samples=64 if quick else 256), objects)
        row = {"case": name, "triangles": len(caster.triangles), **agreement(caster, batches)}
        print(f"   {name:18} {row['triangles']:8d} faces {row['rays']:10d} rays  occlusion "
              f"{100 * row['occlusion_agreement']:8.4f} %  face {100 * row['face_agreement']:8.4f} %  "
              f"{reasons_text(row['reasons'])}", flush=True)
        rows.append(row)
    return rows


def reasons_text(reasons: dict) -> str:
    return ", ".join(f"{count} {reason}" for reason, count in sorted(reasons.items())) or "all agree"


# -- 2. casts alone ------------------------------------------------------------------------------------------------
def casts_alone(caster, batches, passes: int) -> dict:
    """Seconds of each engine's `occluded` over the batches and of a bare loop of BVHTree.ray_cast calls over the
    same rays, alternating batch by batch, the best of `passes` for each batch; rays/s, Embree ÷ the BVHTree engine
    and Embree ÷ the bare loop."""
    built = {"embree": caster.engine.engine,
             "bvhtree": engines.build("bvhtree", caster.vertices, caster.triangles, caster.engine.max_distance)}
    best = {name: np.full(len(batches), np.inf) for name in (*ENGINES, "bare")}
    gc.collect()
    for _ in range(passes):
        for index, (origins, directions, live) in enumerate(batches):
            for name in ENGINES:
                start = time.perf_counter()
                built[name].occluded(origins, directions, live)
                best[name][index] = min(best[name][index], time.perf_counter() - start)
            bare = time_bare_loop(built["bvhtree"], *ray_lists(origins, directions, live))
            best["bare"][index] = min(best["bare"][index], bare)
    rays = rays_in(batches)
    rates = {name: rays / seconds.sum() for name, seconds in best.items()}
    return {"rays": rays, "triangles": len(caster.triangles), "rays_per_s": rates,
            "ratio": rates["embree"] / rates["bvhtree"], "ratio_to_bare": rates["embree"] / rates["bare"]}


def ray_lists(origins, directions, live):
    """A batch's rays as a bare loop takes them, one Python list of an origin and one of a direction per ray (the
    same list for a group's rays), made before the loop is timed."""
    counts = directions.shape[1] if live is None else np.count_nonzero(live, axis=1)
    flat = directions.reshape(-1, 3) if live is None else directions.reshape(-1, 3)[live.ravel()]
    per_ray = np.repeat(np.arange(len(origins)), counts)
    groups = origins.tolist()
    return [groups[group] for group in per_ray.tolist()], flat.tolist()


def room_rays(count: int, quick: bool):
    """The dense scene's bake's rays from `count` floor and wall vertices → (caster, batches)."""
    dense_demo(1 if quick else 3)
    room = ["Floor", "BackWall", "LeftWall"]
    settings = bake.BakeSettings(samples=64 if quick else 256, ray_engine="embree")
    plan = planned(settings, room)
    receivers = [layout.receiver for layout in plan.layouts()]
    picked = []
    for receiver in receivers:
        rows = np.linspace(0, len(receiver.positions) - 1, count // len(receivers)).round().astype(int)
        picked.append(bake.Receiver(receiver.name, receiver.positions[rows], receiver.normals[rows], receiver.key,
                                    None if receiver.inward is None else receiver.inward[rows]))
    caster = plan.occluders.ray_caster()
    caster.engine = Recording(caster.engine)
    job.TransferJob(picked, plan.occluders, settings).run()
    return caster, caster.engine.batches


# -- 4. memory -----------------------------------------------------------------------------------------------------
def resident_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def engine_memory(caster) -> dict:
    """Resident bytes each engine adds as it is built (both kept, BVHTree's first)."""
    added, kept = {}, []
    for name in ("bvhtree", "embree"):
        gc.collect()
        before = resident_bytes()
        kept.append(engines.build(name, caster.vertices, caster.triangles, caster.engine.max_distance))
        added[name] = resident_bytes() - before
    return {"triangles": len(caster.triangles), "bytes": added, "embree_scene": added["embree"] - added["bvhtree"]}


# -- the run -------------------------------------------------------------------------------------------------------
def verdict(key, value) -> str:
    relation, goal = GOALS[key]
    return f"goal {relation} {goal:g}: {result_files.verdict(value, relation, goal)}"


def goals(figures: dict) -> list:
    """The goals of the sections this run measured, as benchmarks/results.py records them."""
    found = []
    if "agreement" in figures:
        worst = 100 * min(row["face_agreement"] for row in figures["agreement"])
        found.append(result_files.goal("face hit agreement, worst case", worst, *GOALS["agreement"], "%"))
        found += [result_files.goal(f"casts alone, Embree ÷ BVHTree, {scene}", figures["casts"][scene]["ratio"],
                                    *GOALS["casts"], "×") for scene in ("demo", "dense")]
        found.append(result_files.goal("whole demo bake, BVHTree ÷ Embree", figures["whole_bake"]["ratio"],
                                       *GOALS["bake"], "×"))
    if "same_answers" in figures:
        rows = figures["same_answers"]
        found.append(result_files.goal("cases whose transfers differ beyond their noise",
                                       sum(not row["z_pass"] for row in rows), "<=", 0))
        found.append(result_files.goal("largest move of the RMS against Cycles",
                                       100 * max(abs(row["rms_move"]) for row in rows), "<=", 100 * RMS_MOVE, "points"))
    if "texel_room" in figures:
        found.append(result_files.goal("texel room, BVHTree ÷ Embree", figures["texel_room"]["ratio"],
                                       *GOALS["texels"], "×"))
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Embree and BVHTree side by side")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--quick", action="store_true", help="smoke run: two small cases, 64 samples, one pass, the "
                       "dense scene subdivided once, Cycles 2 × 16 samples, the texel room at 64², no Final bakes")
    which.add_argument("--final", action="store_true", help="sections 5 and 6: the Final preset's bakes and their "
                       "error against run time")
    for flag, section in (("rays", "sections 1 to 4: the rays, the demo bake and memory"),
                          ("answers", "section 7: the same answers, transfers and against Cycles"),
                          ("texels", "section 8: the texel room")):
        parser.add_argument(f"--{flag}", action="store_true", help=section)
    result_files.add_argument(parser)
    parser.add_argument("--plot", default="engine_curves.png", help="the figure of both engines' error against run "
                        "time on the demo (default: %(default)s)")
    parser.add_argument("--assets", default=assets.ASSETS, help="the folder of the public test meshes "
                        "benchmarks/assets.py's cases import (default: %(default)s)")
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    assets.ASSETS = args.assets
    if not engines.embree_installed():
        print(f"engines: error: {engines.EMBREE_MISSING}", file=sys.stderr)
        return 1
    with schema_registered():  # the bake settings of the objects (blender.schema)
        return run(args)


def run(args) -> int:
    print(f"engines benchmark: {ray_engine_label('embree')} against {ray_engine_label('bvhtree')}"
          + ("  (quick: the goals are for the full run)" if args.quick else ""), flush=True)
    started = time.perf_counter()
    figures = {"quick": args.quick}
    every = not (args.rays or args.final or args.answers or args.texels)  # no section named: all of them
    if every or args.rays:
        figures.update(engines_compared(args.quick))
    if (every and not args.quick) or args.final:
        print(f"\n5. The Final preset on the demo, 2 workers (cpu count {os.cpu_count()})")
        curves = {}
        figures["final"] = final_bakes(curves)
    if every or args.final:
        if args.quick:
            curves = curve_bakes(bake.BakeSettings(samples=64, target_error=0.02, max_samples=1024))
        what = "the Final preset" if not args.quick else "64 samples, target 2 %"
        print(f"\n6. Error against run time, the demo with {what}, as each bake reports it")
        print("\n".join(engine_curves.printed(curves)))
        engine_curves.plot(curves, args.plot, f"The demo, {what}: estimated error against time")
        print(f"   wrote {os.path.abspath(args.plot)}")
        figures["curves"] = {name: [asdict(row) for row in rows] for name, rows in curves.items()}
    if every or args.answers:
        figures["same_answers"] = answers(args.quick)
    if every or args.texels:
        figures["texel_room"] = room(args.quick)
    print(f"\ntotal {(time.perf_counter() - started) / 60:.1f} min")
    if args.json:
        result_files.write("engines", args, figures, goals(figures))
    return 0


def answers(quick: bool) -> list:
    """Section 7, at benchmarks/assets.py's sizes (its quick ones with --quick)."""
    settings = (assets.Settings(bake_samples=64, cycles_samples=16, passes=2) if quick else assets.Settings())
    print(f"\n7. Same answers: each case baked by each engine ({settings.bake_samples} samples, one seed), the "
          f"transfers point by point against their own noise, and both bakes against one Cycles render "
          f"({settings.passes} × {settings.cycles_samples} samples)")
    return same_answers_cases(QUICK_CASES if quick else [case.name for case in assets.CASES], settings)


def room(quick: bool) -> dict:
    """Section 8, at benchmarks/texels.py's sizes (its quick ones with --quick)."""
    sizes, passes = (texels.QUICK, 1) if quick else (texels.FULL, 2)
    print(f"\n8. The texel room of benchmarks/texels.py: floor and walls at {sizes.resolution} × {sizes.resolution}, "
          f"1 % target, {sizes.room_samples} samples first ({sizes.room_max_samples} at most), best of {passes}")
    found = texel_room(sizes, passes)
    print(f"   BVHTree ÷ Embree wall time {found['ratio']:.2f}×  {verdict('texels', found['ratio'])}", flush=True)
    return found


def engines_compared(quick: bool) -> dict:
    """Sections 1 to 4."""
    passes, samples = (1, 64) if quick else (3, 256)
    print("\n1. Agreement, ray by ray, on every ray of each case's bake (Embree's hits against BVHTree's)")
    rows = agreement_cases(quick)
    rays = sum(row["rays"] for row in rows)
    worst = min(row["face_agreement"] for row in rows)
    reasons = sum((Counter(row["reasons"]) for row in rows), Counter())
    print(f"   all {rays} rays: occlusion {100 * (1 - sum(r['found_differs'] for r in rows) / rays):.4f} %, face "
          f"{100 * (1 - sum(r['found_differs'] + r['face_differs'] for r in rows) / rays):.4f} %; the rest: "
          f"{reasons_text(reasons)}; the same face's distances within {max(r['worst_distance'] for r in rows):.1e} of "
          "the rays' reach")
    print(f"   agreement on the face hit, worst case {100 * worst:.4f} %  {verdict('agreement', 100 * worst)}",
          flush=True)

    print("\n2. Casts alone: occluded over the bake's recorded rays, and a bare ray_cast loop over them, best of "
          f"{passes} pass{'es' * (passes > 1)}")
    assets.fresh_file()
    assets.sample_scenes.build_demo_scene()
    casts = {"demo": casts_alone(*recorded_bake(bake.BakeSettings(samples=samples)), passes)}
    dense = room_rays(256 if quick else 2048, quick)
    casts["dense"] = casts_alone(*dense, passes)
    for name, found in casts.items():
        rate = found["rays_per_s"]
        print(f"   {name:6} {found['triangles']:8d} faces {found['rays']:9d} rays: Embree "
              f"{rate['embree'] / 1e6:6.3f} M rays/s, BVHTree {rate['bvhtree'] / 1e6:6.3f} M rays/s, bare ray_cast "
              f"loop {rate['bare'] / 1e6:6.3f} M rays/s; Embree ÷ bare loop {found['ratio_to_bare']:5.2f}×, Embree ÷ "
              f"BVHTree {found['ratio']:5.2f}×  {verdict('casts', found['ratio'])}", flush=True)
    memory = engine_memory(dense[0])
    del dense

    print(f"\n3. The whole demo bake, {samples} samples, 2 workers, best of {passes}")
    whole = whole_bakes(samples, passes)
    for name in ENGINES:
        split = whole["one_process"][name]
        print(f"   {name:8} 2 workers {whole['best_s'][name]:6.2f} s; one process {split['total_s']:6.2f} s: "
              f"casting {split['casting_s']:6.2f} s, contact search {split['contact_s']:5.2f} s, the rest "
              f"{split['rest_s']:6.2f} s")
    print(f"   BVHTree ÷ Embree wall time {whole['ratio']:.2f}×  {verdict('bake', whole['ratio'])}")
    mb = {name: size / 2 ** 20 for name, size in memory["bytes"].items()}
    print(f"\n4. Memory over the dense scene ({memory['triangles']} faces): BVHTree {mb['bvhtree']:.0f} MB, Embree "
          f"engine {mb['embree']:.0f} MB (its scene {memory['embree_scene'] / 2 ** 20:.0f} MB, its contact "
          "search's BVHTree the rest)")
    return {"agreement": rows, "casts": casts, "memory": memory, "whole_bake": whole}


if __name__ == "__main__":
    sys.exit(main())
