"""Farm shards: one bake split over N processes or machines (`prt bake --shard K/N --out PART.npz`), each leaving a
part file, then merged (`prt merge`) into the bake one process would make, bit for bit. The chunks are fixed by the
receivers alone (scheduling.chunk_rows); shard K bakes workers.shard_chunks' share of them; the merge stores every
chunk's result where a one-process bake does, and bounces interreflections from the parts' hit records.

A part file is an .npz: its chunks' results as job_file saves a worker's (transfer, standard error, rays, which
vertices were exact without rays, the rule that decided each, and in interreflected bakes the blocked rays' hit
records), and `part`, a JSON string (PartInfo): the shard K/N, the bake's number of chunks, the scene file's name,
the solved surfaces and the receivers, the settings (the ray engine among them: parts of one bake share it), each
receiver's fingerprint, the shard's seconds (wall and CPU), rays, seconds baking and workers, and its engine as a
report names it. A part is read as untrusted input (core.part_file).
"""

from collections import Counter
from dataclasses import asdict, dataclass, field
from itertools import islice
import json
import os
import time
import zipfile

import numpy as np

from . import fingerprint, job_file, outputs
from .errors import InputError

# Also names how chunks are cut and what the description holds: 4 parts a split vertex's points about their mean
# normal, 5 gives chunks of shared ray groups twice the groups (scheduling.SHARED_CHUNK_FACTOR), 6 has each shard's
# seconds baking and workers (rays_s, workers: a merged bake's rays per second), 7 the ray engine (in the settings,
# and as the report names it), 8 the rule that decided each point (core.rules), 9 each chunk's error curve
# (core.error_curve), 10 each rule's doubt (rule_error), 11 the points against their faces measured, one per face
# plane (core.corners.clip_planes).
PART_FORMAT = "prt-part-11"
PROBES = "probe_"  # the prefix of the probes' arrays


@dataclass
class PartInfo:
    shard: int
    shards: int
    chunks: int            # the whole bake's chunks
    probe_chunks: int      # the whole bake's chunks of points between vertices (core.interpolation)
    scene: str             # the .blend file's name
    surfaces: list         # every solved surface's name, in the job's order
    receivers: list        # the surfaces stored on their objects
    settings: dict         # core.bake.BakeSettings' fields
    fingerprints: dict     # receiver → part → digest (blender.fingerprint)
    time_s: float = 0.0    # the bake command's seconds, from its start to the part written (Stopwatch)
    cpu_s: float = 0.0     # the same span's CPU seconds: this process and its workers
    rays: int = 0          # the vertices' and the probes'
    rays_s: float = 0.0    # seconds baking: the span a one-process bake's rays per second are over (its job's)
    workers: int = 1       # the processes the shard's bake asked for, as a one-process bake's report counts them
    ray_engine: str = ""   # the engine that cast its rays, with its version, as a report names it

    def same_bake(self) -> tuple:
        """What must match between parts of one bake, and the scene they are merged into, besides shard K."""
        return (self.shards, self.chunks, self.probe_chunks, self.surfaces, self.receivers, self.settings,
                self.fingerprints)


def shard_of(text: str) -> tuple[int, int]:
    """'K/N' → (K, N), K from 1 to N."""
    try:
        shard, shards = (int(number) for number in text.split("/"))
    except ValueError:
        raise InputError(f"--shard must be K/N (two whole numbers, as 2/8), not {text!r}") from None
    if not 1 <= shard <= shards:
        raise InputError(f"--shard {text}: K must be from 1 to N")
    return shard, shards


def cpu_seconds() -> float:
    """CPU time of this process and its finished children (forked bake workers)."""
    times = os.times()
    return times.user + times.system + times.children_user + times.children_system


@dataclass
class Stopwatch:
    """Started with a shard's command (before its file is opened); a part's seconds are read from it."""
    wall_s: float = field(default_factory=time.perf_counter)
    cpu_s: float = field(default_factory=cpu_seconds)

    def elapsed(self) -> tuple[float, float]:
        return time.perf_counter() - self.wall_s, cpu_seconds() - self.cpu_s


def write_part(path: str, info: PartInfo, chunk_results, probe_results, stopwatch: Stopwatch) -> None:
    """Writes the part whole or not at all (outputs.replacing), creating the folder: a farm that kills a shard
    midway, or retries it, never leaves half a part. The chunks' arrays go first and the description last, so its
    seconds (info.time_s, cpu_s, read from `stopwatch`) include writing them. The file gets the mode any new file
    gets (0666 less the umask), so a merge run as another user on shared storage reads it."""
    with outputs.replacing(path) as temporary, open(temporary, "wb") as out, \
            zipfile.ZipFile(out, "w") as archive:  # np.savez's layout
        arrays = {**job_file.result_arrays(sorted(chunk_results.items())),
                  **job_file.result_arrays(sorted(probe_results.items()), PROBES)}
        for name, array in arrays.items():
            _write_array(archive, name, array)
        info.time_s, info.cpu_s = stopwatch.elapsed()
        _write_array(archive, "part", np.array(json.dumps({"format": PART_FORMAT, **asdict(info)})))


def _write_array(archive: zipfile.ZipFile, name: str, array: np.ndarray):
    with archive.open(name + ".npy", "w", force_zip64=True) as entry:
        np.lib.format.write_array(entry, np.asanyarray(array), allow_pickle=False)


def part_paths(given) -> list[str]:
    """The part files: each path given, or every .npz file in a folder given (a farm's parts folder)."""
    paths = []
    for path in given:
        if not os.path.isdir(path):
            paths.append(path)
            continue
        found = sorted(os.path.join(path, name) for name in os.listdir(path) if name.endswith(".npz"))
        if not found:
            raise InputError(f"no part files (.npz) in the folder {path}")
        paths += found
    return paths


def chosen_bake(infos: list[PartInfo]) -> PartInfo:
    """The bake most parts belong to: its settings and receivers are what the merge bakes."""
    counts = Counter(json.dumps(info.same_bake(), sort_keys=True) for info in infos)
    wanted = counts.most_common(1)[0][0]
    return next(info for info in infos if json.dumps(info.same_bake(), sort_keys=True) == wanted)


def refusals(parts: list[tuple[str, PartInfo]], current: PartInfo) -> list[str]:
    """Why these parts (path, description) do not make the bake of `current` (the scene as it is now, the chosen
    bake's settings): each foreign, stale, misnumbered or duplicate part and each missing shard, by name. [] when
    there is one part of each shard; what each holds is checked as it is read (part_file.load_part)."""
    found, good = [], {}
    for path, info in parts:
        problem = _part_problem(info, current)
        if problem:
            found.append(f"{path} {problem}")
        else:
            good.setdefault(info.shard, []).append(path)
    found += [f"duplicate shard {shard}/{current.shards}: {', '.join(paths)}"
              for shard, paths in sorted(good.items()) if len(paths) > 1]
    missing = _missing_shards(set(good), current.shards, [path for paths in good.values() for path in paths])
    if missing:
        found.append(missing)
    return found


def _missing_shards(present: set, shards: int, claiming: list[str], listed: int = 8) -> str | None:
    """'missing shards 2/9, 5/9' for the shards of 1..N not `present` (a subset of them). N comes from the parts
    (`claiming`: those of N shards), and may be any number: past `listed` shards, the rest are counted and the
    parts that say N named."""
    count = shards - len(present)
    if not count:
        return None
    first = list(islice((shard for shard in range(1, shards + 1) if shard not in present), listed))
    named = ", ".join(f"{shard}/{shards}" for shard in first)
    if count > len(first):
        others = f" and {len(claiming) - 1} other part{'s' if len(claiming) > 2 else ''}" if len(claiming) > 1 else ""
        named += f" and {count - len(first)} more (N = {shards} in {claiming[0] if claiming else 'the parts'}{others})"
    return f"missing shard{'s' if count > 1 else ''} {named}"


def _part_problem(info: PartInfo, current: PartInfo) -> str | None:
    if not 1 <= info.shard <= info.shards:
        return f"is shard {info.shard}/{info.shards}: K must be from 1 to N"
    if (info.receivers, info.surfaces, info.chunks, info.probe_chunks) != (
            current.receivers, current.surfaces, current.chunks, current.probe_chunks):
        return (f"is from another scene or selection ({shown(info.scene)}: "
                f"{', '.join(map(shown, info.receivers[:8]))}{', ...' if len(info.receivers) > 8 else ''})")
    changed = sorted({word for name, stored in info.fingerprints.items()
                      for word in fingerprint.changes(stored, current.fingerprints[name])})
    if changed:
        return f"is stale ({', '.join(changed)} since it was baked)"
    if info.shards != current.shards:
        return f"is shard {info.shard}/{info.shards}, the others are of {current.shards}"
    engine, wanted = info.settings.get("ray_engine"), current.settings.get("ray_engine")
    if engine != wanted:  # the engines' bakes agree, but not bit for bit
        return (f"was baked with the ray engine {shown(str(engine))}, the others with {wanted}: bake every shard with "
                f"one (--ray-engine)")
    return None


def shown(text: str, most: int = 60) -> str:
    """A name read from a part, as a refusal tells it: on one line (control characters as '?'), at most `most`
    characters."""
    text = "".join(character if character.isprintable() else "?" for character in text[: most + 1])
    return text if len(text) <= most else text[: most - 1] + "…"
