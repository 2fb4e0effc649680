"""Whole bakes by each ray engine, timed side by side: sections 3, 5, 6 and 8 of benchmarks/engines.py (issue 32,
items 5 and 6), which runs them and prints their goals.

3. The whole demo bake at 256 samples with 2 workers, the engines alternating, best of the passes; and one process's
   bake split into casting (occluded, hits), the contact search (nearest, BVHTree in both) and the rest.
5. The Final preset on the demo (interreflected, order 6, target 0.5 %) with 2 workers, once per engine, each bake
   split into its rays, its bounces and their error estimate, with the load average.
6. The bakes whose error curves section 6 draws: the Final bakes of section 5, or in --quick smaller ones.
8. The texel room of benchmarks/texels.py (the demo's floor and walls per texel at 1024², to a 1 % target) with 2
   workers, the engines alternating, best of the passes; and one process's bake split into casting and the rest,
   with the load average.
"""

from collections import Counter
from dataclasses import replace
import os
import time

import bpy  # before mathutils, which the core imports

from benchmarks import assets, texels
from prt_addon.blender.execute import execute, local_executor
from prt_addon.blender.plan import plan_bake
from prt_addon.blender.request import read_request
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import bake, executors, presets

ENGINES = ("embree", "bvhtree")


class Timed:
    """Stands in for a bake's engine: answers with it, adding up the seconds of each question."""

    def __init__(self, engine):
        self.engine, self.max_distance, self.seconds = engine, engine.max_distance, Counter()

    def __getattr__(self, question):
        answer = getattr(self.engine, question)

        def timed(*arguments):
            start = time.perf_counter()
            try:
                return answer(*arguments)
            finally:
                self.seconds[question] += time.perf_counter() - start
        return timed


def planned(settings, objects=None):
    """The bake of the scene as it is now: its plan, its ray caster built."""
    plan = plan_bake(read_request(bpy.context, settings, objects))
    plan.occluders.ray_caster()
    return plan


def timed_caster(plan):
    """The plan's ray caster, its engine wrapped in Timed: the bake then adds up the seconds of each question."""
    caster = plan.occluders.ray_caster()
    caster.engine = Timed(caster.engine)
    return caster


def split_of(caster, total: float) -> dict:
    """A one-process bake's `total` seconds split by its Timed engine: casting (occluded, hits), the contact search
    (nearest) and the rest."""
    casting = caster.engine.seconds["occluded"] + caster.engine.seconds["hits"]
    contact = caster.engine.seconds["nearest"]
    return {"total_s": total, "casting_s": casting, "contact_s": contact, "rest_s": total - casting - contact}


def load_text() -> str:
    return " ".join(f"{load:.1f}" for load in os.getloadavg())


# -- 3. the whole demo bake ----------------------------------------------------------------------------------------
def whole_bakes(samples: int, passes: int) -> dict:
    """The demo bake with 2 workers, the engines alternating, best of `passes`; and one process's bake, timed by
    question."""
    walls, split = {name: [] for name in ENGINES}, {}
    for _ in range(passes):
        for name in ENGINES:
            assets.fresh_file()
            assets.sample_scenes.build_demo_scene()
            start = time.perf_counter()
            plan = planned(bake.BakeSettings(samples=samples, ray_engine=name))
            summary = execute(plan, local_executor(2)).run().summary
            walls[name].append(time.perf_counter() - start)
    for name in ENGINES:
        assets.fresh_file()
        assets.sample_scenes.build_demo_scene()
        start = time.perf_counter()
        plan = planned(bake.BakeSettings(samples=samples, ray_engine=name))
        caster = timed_caster(plan)
        execute(plan, executors.InProcess()).run()
        split[name] = split_of(caster, time.perf_counter() - start)
    best = {name: min(times) for name, times in walls.items()}
    return {"samples": samples, "rays": summary.rays, "wall_s": walls, "best_s": best,
            "ratio": best["bvhtree"] / best["embree"], "one_process": split}


# -- 5. the Final preset ------------------------------------------------------------------------------------------
def final_bakes(curves: dict) -> dict:
    """The demo baked with the Final preset and 2 workers by each engine: wall seconds and the bake's phases; each
    bake's error curve into `curves`."""
    found = {}
    for name in ENGINES:
        assets.fresh_file()
        assets.sample_scenes.build_demo_scene()
        start = time.perf_counter()
        plan = planned(bake.BakeSettings(**presets.preset_values("final"), ray_engine=name))
        summary = execute(plan, local_executor(2)).run().summary
        phases, wall = summary.phases_s, time.perf_counter() - start
        split = {"rays_s": phases["rays_s"], "bounces_s": phases["gather_setup_s"] + phases["bounces_s"],
                 "error_s": phases["bounce_error_s"]}
        found[name] = {"wall_s": wall, **split, "rest_s": wall - sum(split.values()), "load": os.getloadavg()}
        curves[name] = summary.error_curve
        print(f"   {name:8} {wall:7.1f} s: rays {split['rays_s']:6.1f} s, bounces {split['bounces_s']:6.1f} s, "
              f"their error {split['error_s']:6.1f} s, the rest {found[name]['rest_s']:5.1f} s  (load average "
              f"{load_text()})", flush=True)
    found["ratio"] = found["bvhtree"]["wall_s"] / found["embree"]["wall_s"]
    print(f"   BVHTree ÷ Embree wall time {found['ratio']:.2f}×")
    return found


# -- 6. error against run time ------------------------------------------------------------------------------------
def curve_bakes(settings) -> dict:
    """{engine: the demo bake's error curve (core.error_curve rows)} with 2 workers."""
    curves = {}
    for name in ENGINES:
        assets.fresh_file()
        assets.sample_scenes.build_demo_scene()
        plan = planned(replace(settings, ray_engine=name))
        curves[name] = execute(plan, local_executor(2)).run().summary.error_curve
    return curves


# -- 8. the texel room ---------------------------------------------------------------------------------------------
def texel_room(sizes: texels.Sizes, passes: int) -> dict:
    """benchmarks/texels.py's room baked by each engine: with 2 workers, wall seconds from reading the scene to the
    maps stored (the figure texels.py's goal judges), the engines alternating, best of `passes`; then in one
    process, split into casting and the rest."""
    walls, found = {name: [] for name in ENGINES}, {}
    for _ in range(passes):
        for name in ENGINES:
            settings = texels.room_scene(sizes)
            start = time.perf_counter()
            summary = SceneBake(bpy.context, replace(settings, ray_engine=name), workers=2).run()
            walls[name].append(time.perf_counter() - start)
    for name in ENGINES:
        load = load_text()
        settings = texels.room_scene(sizes)
        start = time.perf_counter()
        scene_bake = SceneBake(bpy.context, replace(settings, ray_engine=name), workers=1)
        caster = timed_caster(scene_bake.plan)
        scene_bake.run()
        split = split_of(caster, time.perf_counter() - start)
        found[name] = {"wall_s": walls[name], "best_s": min(walls[name]), "one_process": split, "load": load}
        print(f"   {name:8} 2 workers {found[name]['best_s']:6.1f} s (of {' '.join(f'{s:.1f}' for s in walls[name])}"
              f"); one process {split['total_s']:6.1f} s: casting {split['casting_s']:6.1f} s, contact search "
              f"{split['contact_s']:5.1f} s, the rest {split['rest_s']:6.1f} s  (load average {load})", flush=True)
    found["rays"] = summary.rays
    found["ratio"] = found["bvhtree"]["best_s"] / found["embree"]["best_s"]
    return found
