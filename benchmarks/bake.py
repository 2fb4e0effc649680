"""Bake benchmarks, measured side by side in one run on the demo scene (the original program's torus room).

1. Ray-cast efficiency: the bake's rays/s ÷ a bare BVHTree.ray_cast loop over the very same rays.
2. Estimator error: our estimator and the original program's (uniform sphere, weight 4π/N) at 256 rays per vertex,
   both against an independent 16,384-ray reference.
3. The demo bake at order 4, shadowed, target error 0.01, 2 workers: wall time and actual error.
4. Workers: 2 workers ÷ 1 worker wall time, and bit-identical results.

Run from the repository root:  .venv/bin/python benchmarks/bake.py [--quick] [--json [DIR]]
"""

import argparse
import copy
import gc
from dataclasses import dataclass
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (bpy before mathutils, which the core imports)
import numpy as np  # noqa: E402

from benchmarks import results as result_files  # noqa: E402
from prt_addon.blender import sample_scenes  # noqa: E402
from prt_addon.blender.execute import local_executor  # noqa: E402
from prt_addon.blender.plan import plan_bake  # noqa: E402
from prt_addon.blender.request import read_request  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402
from prt_addon.core import bake, estimator, job, lobes, ray_caster, scheduling, sh  # noqa: E402

ORDER = 4
COMPARED_SAMPLES = 256
# The reference must be randomised independently of every estimate it judges.
REFERENCE_SEED = 1_000_003
PICK_SEED = 20080601  # which vertices are sampled; fixed so runs compare


@dataclass
class Config:
    cast_vertices: int       # vertices (half floor, half torus) whose bake rays are replayed bare
    cast_repeats: int        # passes, bake and bare loop alternating chunk by chunk; median of pass ratios
    error_vertices: int      # vertices per sample set in the error benchmarks
    reference_samples: int   # rays per vertex of the reference
    bake_objects: list       # receivers of the scene bakes; None = every mesh
    max_samples: int         # ray budget per vertex of the target-error bake
    worker_samples: int      # rays per vertex of the workers benchmark
    worker_repeats: int      # alternations of 1 and 2 workers; median of the paired ratios
    spin_iterations: int     # the machine check's fixed pure-Python work per process


FULL = Config(cast_vertices=2048, cast_repeats=7, error_vertices=300, reference_samples=16384,
              bake_objects=None, max_samples=16384, worker_samples=256, worker_repeats=5,
              spin_iterations=20_000_000)
QUICK = Config(cast_vertices=128, cast_repeats=2, error_vertices=32, reference_samples=1024,
               bake_objects=["Floor"], max_samples=512, worker_samples=32, worker_repeats=1,
               spin_iterations=1_000_000)

GOALS = {
    "ray_cast_efficiency": (">=", 0.85),
    "error_ratio_ours_to_seed": ("<=", 0.1),
    "demo_bake_wall_s": ("<=", 30.0),
    "demo_bake_actual_rms_rel_error": ("<=", 0.01),
    "workers_2_to_1_time": ("<=", 0.6),
    "workers_bit_identical": ("==", True),
}


# -- the scene ------------------------------------------------------------------------------------------
def fresh_demo_scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    sample_scenes.build_demo_scene()


def scene_geometry():
    """Receivers and occluders exactly as the bake gathers them (nothing is baked), cast with BVHTree: the
    engine whose bare ray_cast loop the bake is measured against (benchmarks/engines.py has both engines)."""
    fresh_demo_scene()
    plan = plan_bake(read_request(bpy.context, bake.BakeSettings(order=ORDER, ray_engine="bvhtree")))
    return [receiver.layout.receiver for receiver in plan.receivers], plan.occluders


@dataclass
class Picks:
    """Sampled vertices: receivers[owner[i]] vertex index[i]."""
    owner: np.ndarray
    index: np.ndarray

    def positions(self, receivers):
        return np.array([receivers[o].positions[i] for o, i in zip(self.owner, self.index)])

    def normals(self, receivers):
        return np.array([receivers[o].normals[i] for o, i in zip(self.owner, self.index)])

    def inward(self, receivers):
        return np.array([inward_of(receivers[o])[i] for o, i in zip(self.owner, self.index)])

    def of(self, per_receiver):
        """Gathers per-receiver arrays (one per receiver) at the picks."""
        return np.array([per_receiver[o][i] for o, i in zip(self.owner, self.index)])

    def union(self, other):
        pairs = sorted(set(zip(self.owner.tolist(), self.index.tolist()))
                       | set(zip(other.owner.tolist(), other.index.tolist())))
        return Picks(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))

    def rows_in(self, superset):
        """Where each of these picks sits in `superset`."""
        row = {pair: n for n, pair in enumerate(zip(superset.owner.tolist(), superset.index.tolist()))}
        return np.array([row[pair] for pair in zip(self.owner.tolist(), self.index.tolist())])


def provably_unoccluded(caster, receiver):
    """The bake's own test: these vertices get the exact transfer without rays, so zero error."""
    return estimator.provably_unoccluded(receiver.positions - caster.center, receiver.normals, caster.hull,
                                    caster.offset)


def inward_of(receiver):
    """The receiver's in-face tangents, zero when it has none (as bake_chunk treats None)."""
    return np.zeros_like(receiver.normals) if receiver.inward is None else receiver.inward


def pick_vertices(caster, receivers, count, names, occludable_only, rng):
    """A random sample of vertices with a surface from the named receivers; occludable_only keeps only
    those not provably unoccluded."""
    owners, indices = [], []
    for owner, receiver in enumerate(receivers):
        if names is not None and receiver.name not in names:
            continue
        keep = np.abs(receiver.normals).sum(1) > 0
        if occludable_only:
            keep &= ~provably_unoccluded(caster, receiver)
        found = np.flatnonzero(keep)
        owners.append(np.full(len(found), owner))
        indices.append(found)
    owners, indices = np.concatenate(owners), np.concatenate(indices)
    chosen = np.sort(rng.choice(len(owners), size=min(count, len(owners)), replace=False))
    return Picks(owners[chosen], indices[chosen])


def subset_receivers(receivers, picks):
    """One receiver per owner holding its picked vertices with the rest of their ray groups (so each is baked as the
    bake bakes it: with its group's origin and rays), and the rows of each pick in the concatenated results."""
    subsets, rows, offset = [], np.empty(len(picks.owner), dtype=int), 0
    for owner in np.unique(picks.owner):
        mine = np.flatnonzero(picks.owner == owner)
        source = receivers[owner]
        groups = source.ray_groups
        chosen = (picks.index[mine] if groups is None
                  else np.flatnonzero(np.isin(groups, groups[picks.index[mine]])))
        subsets.append(source.subset(chosen))
        rows[mine] = offset + np.searchsorted(chosen, picks.index[mine])  # picks come sorted
        offset += len(chosen)
    return subsets, rows


def bake_picks(receivers, occluders, picks, settings, workers=1):
    """Our estimator on the picked vertices only → (transfer, std_error, rel_error) in pick order."""
    subsets, rows = subset_receivers(receivers, picks)
    results = job.TransferJob(subsets, occluders, settings, local_executor(workers)).run()
    stacked = [np.concatenate([getattr(r, name) for r in results])[rows]
               for name in ("transfer", "std_error", "rel_error")]
    return tuple(stacked)


# -- 1. ray-cast efficiency -------------------------------------------------------------------------------
class RecordingTree:
    """Stands in for the BVHTree engine's tree while a chunk is recorded: keeps every ray the engine casts through
    it, whatever the engine's own methods take, and casts it."""

    def __init__(self, tree):
        self.tree = tree
        self.origins, self.directions = [], []

    def __getattr__(self, name):
        return getattr(self.tree, name)

    def ray_cast(self, origin, direction, distance):
        self.origins.append(list(origin))
        self.directions.append(list(direction))
        return self.tree.ray_cast(origin, direction, distance)


def drain(work):
    """Runs a bake_chunk generator to the end; returns the rays it cast."""
    rays = 0
    try:
        while True:
            rays += next(work)
    except StopIteration:
        return rays


def cast_benchmark_receiver(receivers, count):
    """Evenly spread vertices, half from the floor and half from the torus, as one receiver."""
    parts = []
    for name in ("Floor", "Torus"):
        source = next(r for r in receivers if r.name == name)
        chosen = np.linspace(0, len(source.positions) - 1, count // 2).round().astype(int)
        parts.append((source.positions[chosen], source.normals[chosen], inward_of(source)[chosen]))
    positions, normals, inward = (np.concatenate(column) for column in zip(*parts))
    return bake.Receiver("CastBenchmark", positions, normals, bake.Receiver.key_for("CastBenchmark"), inward)


def recorded_rays(caster, receiver, rows, settings):
    """The rays the bake of one chunk casts, as Python lists: one origin and one direction per ray."""
    recorder = copy.copy(caster)
    recorder.engine = copy.copy(caster.engine)
    recorder.engine.tree = RecordingTree(caster.engine.tree)
    drain(estimator.bake_chunk(recorder, receiver, rows, settings))
    return recorder.engine.tree.origins, recorder.engine.tree.directions


def time_bare_loop(engine, origins, directions):
    """Seconds of a bare Python loop of BVHTree.ray_cast calls over the rays (one origin and one direction per ray)
    through the BVHTree engine's tree, to its reach."""
    cast, distance = engine.tree.ray_cast, engine.max_distance
    start = time.perf_counter()
    for o, d in zip(origins, directions):
        cast(o, d, distance)
    return time.perf_counter() - start


def time_bake_chunk(caster, receiver, rows, settings):
    began = time.perf_counter()
    rays = drain(estimator.bake_chunk(caster, receiver, rows, settings))
    return time.perf_counter() - began, rays


def ray_cast_efficiency(caster, receivers, config):
    """Bake and bare loop alternate chunk by chunk (about 0.05 s each), so a slow or fast phase of the
    shared machine hits both alike. The figure is the median over passes of each pass's ratio: paired, so
    other tenants' load, which comes and goes within a run, cancels; the ratio of each side's best chunk
    times (luckiest moments of each, not necessarily the same moments) is printed as a cross-check."""
    receiver = cast_benchmark_receiver(receivers, config.cast_vertices)
    settings = bake.BakeSettings(order=ORDER, samples=COMPARED_SAMPLES)
    chunks = [rows for _, rows in scheduling.chunk_rows([receiver])]
    replays = [recorded_rays(caster, receiver, rows, settings) for rows in chunks]
    rays = sum(len(directions) for _, directions in replays)
    gc.collect()
    gc.freeze()  # the replayed rays are millions of lists: keep them out of the collector's way
    bake_times = np.empty((config.cast_repeats, len(chunks)))
    bare_times = np.empty((config.cast_repeats, len(chunks)))
    try:
        for repeat in range(config.cast_repeats):
            for n, (rows, (origins, directions)) in enumerate(zip(chunks, replays)):
                bake_times[repeat, n], cast = time_bake_chunk(caster, receiver, rows, settings)
                assert cast == len(directions), "the replay must cast exactly the bake's rays"
                bare_times[repeat, n] = time_bare_loop(caster.engine, origins, directions)
    finally:
        gc.unfreeze()
    best_bake, best_bare = bake_times.min(0).sum(), bare_times.min(0).sum()
    return {
        "vertices": len(receiver.positions), "rays": rays, "repeats": config.cast_repeats,
        "bake_rays_per_s": rays / best_bake, "bare_rays_per_s": rays / best_bare,
        "bake_times_s": bake_times.sum(1).tolist(), "bare_times_s": bare_times.sum(1).tolist(),
        "ray_cast_efficiency": float(np.median(bare_times.sum(1) / bake_times.sum(1))),
        "best_chunks_ratio": best_bare / best_bake,
    }


# -- 2. estimator error -----------------------------------------------------------------------------------
def seed_estimator(caster, positions, normals, inward, rays, rng):
    """The original program's SHBuilder: uniform random directions over the whole sphere, weight 4π/N, here in our
    convention T_k = (1/π)(4π/N) Σ V·max(n·ω, 0)·Y_k. V is the bake's own (its ray engine's), from the
    origins shadowed_chunk uses, so only the estimators differ."""
    count = len(positions)
    directions = rng.normal(size=(count, rays, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    cosines = np.maximum(np.einsum("vrk,vk->vr", directions, normals), 0.0)
    origins = positions - caster.center + caster.offset * (normals + inward)
    visible = np.zeros((count, rays))
    for v in range(count):
        up = np.flatnonzero(cosines[v] > 0)  # rays below the horizon weigh zero: not cast
        visible[v, up] = ~caster.engine.occluded(origins[v:v + 1], directions[v:v + 1, up])[0]
    basis = sh.evaluate(ORDER, directions)
    return (4.0 / rays) * np.einsum("vr,vrk->vk", visible * cosines, basis)


def rms(values):
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else 0.0


def rms_error(estimate, reference):
    """RMS over vertices of the norm of the coefficient error (the bake's std_error is such a norm)."""
    return rms(np.linalg.norm(estimate - reference, axis=1))


def reference_transfer(receivers, occluders, picks, config):
    settings = bake.BakeSettings(order=ORDER, samples=config.reference_samples,
                                 max_samples=config.reference_samples, seed=REFERENCE_SEED)
    start = time.perf_counter()
    transfer, std_error, rel_error = bake_picks(receivers, occluders, picks, settings, workers=2)
    return {"transfer": transfer, "std_error": std_error, "rel_error": rel_error,
            "vertices": len(picks.owner), "time_s": time.perf_counter() - start}


def estimator_error(caster, receivers, occluders, sample_sets, all_picks, reference):
    ours_settings = bake.BakeSettings(order=ORDER, samples=COMPARED_SAMPLES)
    ours, ours_std, _ = bake_picks(receivers, occluders, all_picks, ours_settings)
    seeds = seed_estimator(caster, all_picks.positions(receivers), all_picks.normals(receivers),
                           all_picks.inward(receivers), COMPARED_SAMPLES, np.random.default_rng(PICK_SEED + 1))
    out = {"reference_vertices": reference["vertices"], "reference_time_s": reference["time_s"], "samples": {}}
    for label, picks in sample_sets.items():
        rows = picks.rows_in(all_picks)
        truth = reference["transfer"][rows]
        ours_error, seed_error = rms_error(ours[rows], truth), rms_error(seeds[rows], truth)
        out["samples"][label] = {
            "vertices": len(rows),
            "ours_rms_error": ours_error, "ours_estimated_rms_error": rms(ours_std[rows]),
            "seed_rms_error": seed_error,
            "reference_estimated_rms_error": rms(reference["std_error"][rows]),
            "error_ratio_ours_to_seed": ours_error / seed_error,
        }
    return out


# -- 3. the demo bake with a target error -----------------------------------------------------------------
def scene_bake(settings, objects, workers):
    """A bake of a freshly built demo scene → (wall seconds, SceneBake); wall time counts gathering the
    geometry, baking and storing, what a user waits for."""
    fresh_demo_scene()
    start = time.perf_counter()
    run = SceneBake(bpy.context, settings, objects, workers)
    run.run(log=lambda line: None)
    return time.perf_counter() - start, run


def results_by_name(run):
    return dict(zip(run.results.names, run.results.results))


def demo_bake(receivers, sample_sets, all_picks, reference, config):
    settings = bake.BakeSettings(order=ORDER, samples=COMPARED_SAMPLES, target_error=0.01,
                                 max_samples=config.max_samples)
    wall, run = scene_bake(settings, config.bake_objects, workers=2)
    by_name = results_by_name(run)
    baked = {owner: by_name[r.name] for owner, r in enumerate(receivers) if r.name in by_name}
    transfer = {owner: result.transfer for owner, result in baked.items()}
    estimated = {owner: result.rel_error for owner, result in baked.items()}
    out = {"wall_s": wall, "job_s": run.summary.time_s, "rays": run.summary.rays,
           "mean_rays_per_vertex": run.summary.rays / run.summary.vertices,
           "rays_per_s": run.summary.rays_per_s, "summary": run.summary.line(),
           "est_rms_rel_error_all": run.summary.est_rms_rel_error,
           "est_max_rel_error_all": run.summary.est_max_rel_error, "samples": {}}
    for label, picks in sample_sets.items():
        rows = picks.rows_in(all_picks)
        # As the bake defines it: ÷ the norm of the unshadowed transfer (the same for every unit normal).
        coefficient_error = np.linalg.norm(picks.of(transfer) - reference["transfer"][rows], axis=1)
        error = coefficient_error / lobes.unshadowed_norm(ORDER)
        out["samples"][label] = {
            "vertices": len(rows), "actual_rms_rel_error": rms(error),
            "estimated_rms_rel_error": rms(picks.of(estimated)),
            "reference_estimated_rms_rel_error": rms(reference["rel_error"][rows]),
        }
    return out


# -- 4. workers -------------------------------------------------------------------------------------------
def bit_identical(a, b):
    names = ("transfer", "std_error", "rays", "skipped")
    return all(np.array_equal(getattr(a[k], n), getattr(b[k], n)) for k in a for n in names)


# A fixed amount of pure-Python work, run alone and as two processes at once: what two processes can
# gain on this machine right now (two free cores: the pair takes as long as one alone).
CPU_SPIN = "x = 0\nfor i in range({iterations}):\n    x += i\n"


def cpu_spin_wall_s(processes, iterations):
    start = time.perf_counter()
    spinners = [subprocess.Popen([sys.executable, "-c", CPU_SPIN.format(iterations=iterations)])
                for _ in range(processes)]
    for spinner in spinners:
        spinner.wait()
    return time.perf_counter() - start


def workers_benchmark(config):
    settings = bake.BakeSettings(order=ORDER, samples=config.worker_samples)
    times, spins, results = {1: [], 2: []}, {1: [], 2: []}, {}
    for _ in range(config.worker_repeats):  # alternated, so all see the same machine load
        for workers in (1, 2):
            spins[workers].append(cpu_spin_wall_s(workers, config.spin_iterations))
            wall, run = scene_bake(settings, config.bake_objects, workers)
            times[workers].append(wall)
            results.setdefault(workers, results_by_name(run))
    # Two workers each doing half the work: their time ÷ one worker's is (pair ÷ single) / 2 at best.
    # Medians of back-to-back ratios: other sessions' load comes and goes within a run.
    attainable = float(np.median(np.array(spins[2]) / np.array(spins[1]))) / 2.0
    return {"samples": config.worker_samples, "one_worker_s": min(times[1]), "two_workers_s": min(times[2]),
            "times_s": times, "workers_2_to_1_time": float(np.median(np.array(times[2]) / np.array(times[1]))),
            "best_2_to_1_time": min(times[2]) / min(times[1]),
            "cpu_spin_s": spins, "attainable_2_to_1_time": attainable,
            "workers_bit_identical": bit_identical(results[1], results[2])}


# -- printing ---------------------------------------------------------------------------------------------
def verdict(key, value):
    return result_files.verdict(value, *GOALS[key])


def goal_text(key):
    relation, goal = GOALS[key]
    return f"{relation} {goal}"


def print_ray_cast(r):
    print(f"\n1. Ray-cast efficiency ({r['vertices']} floor and torus vertices, {r['rays']} rays; bake and bare "
          f"loop alternate chunk by chunk, {r['repeats']} passes, median of the passes' ratios)")
    print(f"   bake            {r['bake_rays_per_s'] / 1e3:8.0f} k rays/s   passes {fmt_times(r['bake_times_s'])} s")
    print(f"   bare ray_cast   {r['bare_rays_per_s'] / 1e3:8.0f} k rays/s   passes {fmt_times(r['bare_times_s'])} s")
    print(f"   bake ÷ bare  {r['ray_cast_efficiency']:.3f}   goal {goal_text('ray_cast_efficiency')}   "
          f"{verdict('ray_cast_efficiency', r['ray_cast_efficiency'])}")
    print(f"   (ratio of each side's best chunk times: {r['best_chunks_ratio']:.3f})")


def print_estimator(r, config):
    print(f"\n2. Estimator error, order {ORDER} shadowed, {COMPARED_SAMPLES} rays per vertex, against our "
          f"estimator at {config.reference_samples} rays (seed {REFERENCE_SEED})")
    print(f"   (reference: {r['reference_vertices']} vertices × {config.reference_samples} rays, 2 workers, "
          f"{r['reference_time_s']:.1f} s)")
    print("   RMS over vertices of the norm of the coefficient error")
    print(f"   {'sample':<28}{'ours':>10}{'(est.)':>10}{'seed':>10}{'reference':>11}{'ours÷seed':>11}")
    for label, s in r["samples"].items():
        print(f"   {label + ' (' + str(s['vertices']) + ')':<28}{s['ours_rms_error']:10.5f}"
              f"{s['ours_estimated_rms_error']:10.5f}{s['seed_rms_error']:10.5f}"
              f"{s['reference_estimated_rms_error']:11.5f}{s['error_ratio_ours_to_seed']:11.3f}")
    ratio = r["samples"]["occludable"]["error_ratio_ours_to_seed"]
    print("   (est.) is our bake's own estimate; reference is the reference's own estimated error")
    print(f"   ours ÷ seed (occludable)  {ratio:.3f}   goal {goal_text('error_ratio_ours_to_seed')}   "
          f"{verdict('error_ratio_ours_to_seed', ratio)}")


def print_demo_bake(r):
    print("\n3. Demo scene, order 4, shadowed, target error 0.01, 2 workers")
    print(f"   {r['summary']}")
    print(f"   wall {r['wall_s']:.1f} s (job {r['job_s']:.1f} s), {r['mean_rays_per_vertex']:.0f} rays per vertex "
          f"on average   goal {goal_text('demo_bake_wall_s')} s   {verdict('demo_bake_wall_s', r['wall_s'])}")
    print(f"   {'sample':<28}{'actual RMS rel.':>16}{'bake est.':>11}{'reference est.':>16}")
    for label, s in r["samples"].items():
        print(f"   {label + ' (' + str(s['vertices']) + ')':<28}{s['actual_rms_rel_error']:16.5f}"
              f"{s['estimated_rms_rel_error']:11.5f}{s['reference_estimated_rms_rel_error']:16.5f}")
    actual = r["samples"]["occludable"]["actual_rms_rel_error"]
    print(f"   actual RMS rel. error (occludable) {actual:.5f}   goal {goal_text('demo_bake_actual_rms_rel_error')}"
          f"   {verdict('demo_bake_actual_rms_rel_error', actual)}")


def print_workers(r):
    print(f"\n4. Workers, demo scene, order 4 shadowed, {r['samples']} rays per vertex ({len(r['times_s'][1])} "
          f"alternations, median of the back-to-back ratios)")
    print(f"   1 worker  best {r['one_worker_s']:.2f} s   times {fmt_times(r['times_s'][1])}")
    print(f"   2 workers best {r['two_workers_s']:.2f} s   times {fmt_times(r['times_s'][2])}")
    print(f"   2 ÷ 1  {r['workers_2_to_1_time']:.3f}   goal {goal_text('workers_2_to_1_time')}   "
          f"{verdict('workers_2_to_1_time', r['workers_2_to_1_time'])}")
    print(f"   (ratio of each side's best time: {r['best_2_to_1_time']:.3f})")
    print(f"   machine check: two CPU-bound processes at once take {2 * r['attainable_2_to_1_time']:.2f}× "
          f"as long as one alone (median; 1.00 on two free cores),")
    print(f"   so a perfectly parallel 2 ÷ 1 could reach {r['attainable_2_to_1_time']:.2f} here "
          f"(0.50 on two free cores); single {fmt_times(r['cpu_spin_s'][1])} s, pair {fmt_times(r['cpu_spin_s'][2])} s")
    print(f"   results bit-identical: {r['workers_bit_identical']}   "
          f"{verdict('workers_bit_identical', r['workers_bit_identical'])}")


def fmt_times(times):
    return " ".join(f"{t:.2f}" for t in times)


def summary_rows(results):
    return [
        ("ray-cast efficiency (bake ÷ bare)", "ray_cast_efficiency", results["ray_cast"]["ray_cast_efficiency"]),
        ("error ours ÷ seed at 256 rays", "error_ratio_ours_to_seed",
         results["estimator"]["samples"]["occludable"]["error_ratio_ours_to_seed"]),
        ("demo bake wall time, s", "demo_bake_wall_s", results["demo_bake"]["wall_s"]),
        ("demo bake actual RMS rel. error", "demo_bake_actual_rms_rel_error",
         results["demo_bake"]["samples"]["occludable"]["actual_rms_rel_error"]),
        ("time 2 workers ÷ 1 worker", "workers_2_to_1_time", results["workers"]["workers_2_to_1_time"]),
        ("2 workers bit-identical to 1", "workers_bit_identical", results["workers"]["workers_bit_identical"]),
    ]


def print_summary(results, quick):
    print("\nSummary" + ("  (quick run: shrunk sizes, the goals are for the full run)" if quick else ""))
    print(f"   {'measure':<38}{'value':>10}  {'goal':<10}")
    for label, key, value in summary_rows(results):
        shown = str(value) if isinstance(value, bool) else f"{value:.4g}"
        print(f"   {label:<38}{shown:>10}  {goal_text(key):<10}{verdict(key, value)}")


# -- main -------------------------------------------------------------------------------------------------
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shrink everything for a smoke run")
    result_files.add_argument(parser)
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    config = QUICK if args.quick else FULL
    started = time.perf_counter()
    print(f"bake benchmarks{' (quick)' if args.quick else ''}: bpy {bpy.app.version_string}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")

    receivers, occluders = scene_geometry()
    caster = ray_caster.RayCaster(occluders)
    exact = sum(int(provably_unoccluded(caster, r).sum()) for r in receivers)
    print(f"demo scene: {len(receivers)} receivers, {sum(len(r.positions) for r in receivers)} vertices, "
          f"{len(occluders.triangles)} occluder triangles, {exact} vertices provably unoccluded")
    results = {"quick": args.quick, "config": config.__dict__, "provably_unoccluded_vertices": exact}
    results["ray_cast"] = ray_cast_efficiency(caster, receivers, config)
    print_ray_cast(results["ray_cast"])

    rng = np.random.default_rng(PICK_SEED)
    sample_sets = {
        "occludable": pick_vertices(caster, receivers, config.error_vertices, config.bake_objects, True, rng),
        "all vertices": pick_vertices(caster, receivers, config.error_vertices, config.bake_objects, False, rng),
    }
    all_picks = sample_sets["occludable"].union(sample_sets["all vertices"])
    reference = reference_transfer(receivers, occluders, all_picks, config)
    results["estimator"] = estimator_error(caster, receivers, occluders, sample_sets, all_picks, reference)
    print_estimator(results["estimator"], config)

    results["demo_bake"] = demo_bake(receivers, sample_sets, all_picks, reference, config)
    print_demo_bake(results["demo_bake"])

    results["workers"] = workers_benchmark(config)
    print_workers(results["workers"])

    print_summary(results, args.quick)
    print(f"\n(total {time.perf_counter() - started:.0f} s)")
    if args.json:
        goals = [result_files.goal(label, value, *GOALS[key]) for label, key, value in summary_rows(results)]
        result_files.write("bake", args, results, goals, argv)
    return 0


if __name__ == "__main__":
    with schema_registered():  # each object's storage choice, which the bake reads, is a schema property
        sys.exit(main())
