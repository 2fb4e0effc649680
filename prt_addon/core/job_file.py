"""A worker's side of a bake and the files it shares with the baking process: the job file a spawned worker
loads, the results file every worker leaves, the worker's chunk loop, and the command that starts a spawned
worker on `worker_main`."""

import json
import os
import sys

import numpy as np

from . import bake, estimator, interreflect, ray_caster, scheduling

# bake.Receiver's optional arrays and bake.ChunkResult's but its records, each in order
OPTIONAL_RECEIVER_ARRAYS = ("inward", "ray_groups", "surface_step", "against", "clip")
RESULT_ARRAYS = ("transfer", "std_error", "rays", "skipped", "rules", "rule_error", "curve")


def worker_process_command(python_prefix, job_file, out_file, chunk_indices):
    """`python_prefix` runs a Python snippet with mathutils importable (for the BVHTree engine): [python, '-c'] with
    the bpy module, [blender, '--background', '--factory-startup', '--python-expr'] in a real Blender."""
    package_parent = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    package = __name__.rsplit(".", 2)[0].rsplit(".", 1)[-1]
    snippet = (
        "import sys\n"
        "try:\n    import bpy\nexcept ImportError:\n    pass\n"
        f"sys.path.insert(0, {package_parent!r})\n"
        f"from {package}.core import job_file\n"
        f"job_file.worker_main({job_file!r}, {out_file!r}, {list(chunk_indices)!r})\n"
    )
    return [*python_prefix, snippet]


def save_job(path, receivers, occluders, settings: bake.BakeSettings):
    arrays = {"occluder_vertices": occluders.vertices, "occluder_triangles": occluders.triangles,
              "occluder_hull": occluders.hull}
    arrays.update({f"polygon_{index}": polygon for index, polygon in enumerate(occluders.polygons)})
    if occluders.against is not None:
        arrays["occluder_against"] = occluders.against
    for index, receiver in enumerate(receivers):
        arrays[f"positions_{index}"] = receiver.positions
        arrays[f"normals_{index}"] = receiver.normals
        for name in OPTIONAL_RECEIVER_ARRAYS:
            if getattr(receiver, name) is not None:
                arrays[f"{name}_{index}"] = getattr(receiver, name)
    meta = {"settings": settings.__dict__, "receivers": [[r.name, r.key] for r in receivers],
            "solved_vertices": occluders.solved_vertices, "engine": occluders.engine}
    np.savez(path, meta=np.array(json.dumps(meta)), **arrays)


def load_job(path):
    with np.load(path) as data:
        meta = json.loads(str(data["meta"]))
        flat = [data[f"polygon_{index}"] for index in range(sum(name.startswith("polygon_") for name in data.files))]
        occluders = bake.Occluders(data["occluder_vertices"], data["occluder_triangles"], data["occluder_hull"], flat,
                                   meta["solved_vertices"], meta["engine"],
                                   data["occluder_against"] if "occluder_against" in data else None)
        receivers = [bake.Receiver(name, data[f"positions_{i}"], data[f"normals_{i}"], key,
                                   *(data[f"{part}_{i}"] if f"{part}_{i}" in data else None
                                     for part in OPTIONAL_RECEIVER_ARRAYS))
                     for i, (name, key) in enumerate(meta["receivers"])]
    return receivers, occluders, bake.BakeSettings(**meta["settings"])


def save_results(out_file, results, **extra):
    """Saves (chunk index, ChunkResult) pairs, and `extra` arrays, where load_results reads them: a path, or an
    open binary file (np.savez adds no '.npz' to it)."""
    np.savez(out_file, **result_arrays(results), **extra)


def result_arrays(results, prefix: str = "") -> dict:
    """The arrays save_results saves for (chunk index, ChunkResult) pairs, by name (each name after `prefix`)."""
    arrays = {"chunks": np.array([chunk_index for chunk_index, _ in results], dtype=np.int64)}
    for slot, (_, result) in enumerate(results):
        for name in RESULT_ARRAYS:
            arrays[f"{name}_{slot}"] = getattr(result, name)
        if result.records is not None:
            for name in interreflect.HitRecords.FIELDS:
                arrays[f"records_{name}_{slot}"] = getattr(result.records, name)
    return {prefix + name: array for name, array in arrays.items()}


def load_results(path, prefix: str = "") -> list[tuple[int, bake.ChunkResult]]:
    """(chunk index, result) for every chunk a worker baked (saved under `prefix`, as result_arrays names them)."""
    with np.load(path) as data:
        return [(int(chunk_index), bake.ChunkResult(
                    *(data[f"{prefix}{name}_{i}"] for name in RESULT_ARRAYS),
                    _load_records(data, prefix, i)))
                for i, chunk_index in enumerate(data[prefix + "chunks"])]


def _load_records(data, prefix, slot):
    if f"{prefix}records_vertex_{slot}" not in data:
        return None
    return interreflect.HitRecords(*(data[f"{prefix}records_{name}_{slot}"]
                                     for name in interreflect.HitRecords.FIELDS))


def bake_chunks(caster, receivers, settings, chunk_indices, out_file, stream):
    """A worker's work: bakes the chunks it is given (a list, or a shared queue it takes them from) with a
    progress line on `stream` after each, then saves the results and which chunks they are."""
    chunks = scheduling.chunk_rows(receivers)
    results = []
    for chunk_index in chunk_indices:
        receiver_index, rows = chunks[chunk_index]
        work = estimator.bake_chunk(caster, receivers[receiver_index], rows, settings)
        rays = 0
        while True:
            try:
                rays += next(work)
            except StopIteration as finished:
                results.append((chunk_index, finished.value))
                break
        print(f"PRT-PROGRESS {len(rows)} {rays}", file=stream, flush=True)
    save_results(out_file, results)


def worker_main(job_file, out_file, chunk_indices):
    """Runs in a spawned worker process: loads the job, builds its own ray caster (the job's engine), bakes its
    chunks."""
    receivers, occluders, settings = load_job(job_file)
    bake_chunks(ray_caster.RayCaster(occluders), receivers, settings, chunk_indices, out_file, sys.stdout)
