"""Farm shards: one bake split over N processes or machines (`prt bake --shard K/N --out PART.npz`), each leaving a
part file, then merged (`prt merge`) into the bake one process would make, bit for bit. The chunks are fixed by the
receivers alone (bake.chunk_rows); shard K bakes workers.shard_chunks' share of them; the merge stores every
chunk's result where a one-process bake does, and bounces interreflections from the parts' hit records.

A part file is an .npz: its chunks' results as job_file saves a worker's (transfer, standard error, rays, which
vertices were exact without rays, and in interreflected bakes the blocked rays' hit records), and `part`, a JSON
string (PartInfo): the shard K/N, the bake's number of chunks, the scene file's name, the solved surfaces and the
receivers, the settings, each receiver's fingerprint, and the shard's seconds (wall and CPU) and rays.
"""

from collections import Counter
from dataclasses import asdict, dataclass, field
import json
import os
import tempfile
import time
import zipfile

import numpy as np

from . import fingerprint, job_file
from .errors import InputError
from .workers import shard_chunks

# Also names how chunks are cut: 4 parts a split vertex's points about their mean normal, 5 gives chunks of shared
# ray groups twice the groups (bake.SHARED_CHUNK_FACTOR).
PART_FORMAT = "prt-part-5"
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
    rays: int = 0

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
    """Writes the part atomically (a temporary file in the same folder, renamed over `path`), creating the folder:
    a farm that kills a shard midway, or retries it, never leaves half a part. The chunks' arrays go first and
    the description last, so its seconds (info.time_s, cpu_s, read from `stopwatch`) include writing them."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=".prt_part_", suffix=".partial", dir=folder)
    try:
        with os.fdopen(handle, "wb") as out, zipfile.ZipFile(out, "w") as archive:  # np.savez's layout
            arrays = {**job_file.result_arrays(sorted(chunk_results.items())),
                      **job_file.result_arrays(sorted(probe_results.items()), PROBES)}
            for name, array in arrays.items():
                _write_array(archive, name, array)
            info.time_s, info.cpu_s = stopwatch.elapsed()
            _write_array(archive, "part", np.array(json.dumps({"format": PART_FORMAT, **asdict(info)})))
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise


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


def read_part(path: str) -> tuple[PartInfo, tuple[list[int], list[int]]]:
    """A part's description and the chunks it holds: the vertices', and the probes'."""
    try:
        with np.load(path) as data:
            meta = json.loads(str(data["part"]))
            chunks = tuple([int(index) for index in data[prefix + "chunks"]] for prefix in ("", PROBES))
    except FileNotFoundError:
        raise InputError(f"no such part file: {path}") from None
    except (OSError, ValueError, KeyError):
        raise InputError(f"{path} is not a PRT part file (written by prt bake --shard)") from None
    if meta.pop("format", None) != PART_FORMAT:
        raise InputError(f"{path} is a part file of another format than {PART_FORMAT}")
    return PartInfo(**meta), chunks


def load_chunks(path: str, prefix: str = ""):
    """(chunk index, ChunkResult) for every chunk the part holds (the probes' with prefix PROBES)."""
    return job_file.load_results(path, prefix)


def chosen_bake(infos: list[PartInfo]) -> PartInfo:
    """The bake most parts belong to: its settings and receivers are what the merge bakes."""
    counts = Counter(json.dumps(info.same_bake(), sort_keys=True) for info in infos)
    wanted = counts.most_common(1)[0][0]
    return next(info for info in infos if json.dumps(info.same_bake(), sort_keys=True) == wanted)


def refusals(parts: list[tuple[str, PartInfo, tuple[list[int], list[int]]]], current: PartInfo) -> list[str]:
    """Why these parts (path, description, chunks) do not make the bake of `current` (the scene as it is now, the chosen bake's
    settings): each foreign, stale, misnumbered or duplicate part and each missing shard, by name. [] when they
    cover every chunk exactly once."""
    found, good = [], {}
    for path, info, chunks in parts:
        problem = _part_problem(info, chunks, current)
        if problem:
            found.append(f"{path} {problem}")
        else:
            good.setdefault(info.shard, []).append(path)
    found += [f"duplicate shard {shard}/{current.shards}: {', '.join(paths)}"
              for shard, paths in sorted(good.items()) if len(paths) > 1]
    missing = [f"{shard}/{current.shards}" for shard in range(1, current.shards + 1) if shard not in good]
    if missing:
        found.append(f"missing shard{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
    return found


def _part_problem(info: PartInfo, chunks: tuple[list[int], list[int]], current: PartInfo) -> str | None:
    if not 1 <= info.shard <= info.shards:
        return f"is shard {info.shard}/{info.shards}: K must be from 1 to N"
    if (info.receivers, info.surfaces, info.chunks, info.probe_chunks) != (
            current.receivers, current.surfaces, current.chunks, current.probe_chunks):
        return f"is from another scene or selection ({info.scene}: {', '.join(info.receivers)})"
    changed = sorted({word for name, stored in info.fingerprints.items()
                      for word in fingerprint.changes(stored, current.fingerprints[name])})
    if changed:
        return f"is stale ({', '.join(changed)} since it was baked)"
    if info.shards != current.shards:
        return f"is shard {info.shard}/{info.shards}, the others are of {current.shards}"
    if chunks != tuple(shard_chunks(total, info.shard, info.shards) for total in (info.chunks, info.probe_chunks)):
        return f"does not hold shard {info.shard}/{info.shards}'s chunks"
    return None
