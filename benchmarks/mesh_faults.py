"""Checks before any ray on a large messy scene: how long finding crossing parts, parts inside others and thin
faces (core.mesh_faults) takes on about 100 k triangles of spheres scattered so that some cross and some nest.

    .venv/bin/python benchmarks/mesh_faults.py [--quick] [--json [DIR]]

Goal: about a second for 100 k triangles (the Check button is pressed before every bake). Prints the scene, the
faults found and each step's seconds, then the total against the goal. --quick: the two nested spheres alone.
"""

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from benchmarks import results as result_files  # noqa: E402
from prt_addon.core import mesh_faults  # noqa: E402

GOAL_S = 1.0
SEED = 0


def uv_sphere(rings: int, center, radius):
    """A closed UV sphere wound outward: 2·rings segments, rings − 1 rings of vertices and the two poles."""
    polar, azimuth = np.meshgrid(np.linspace(0, np.pi, rings + 1)[1:-1],
                                 np.linspace(0, 2 * np.pi, 2 * rings, endpoint=False), indexing="ij")
    ring_points = np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], -1)
    positions = np.vstack([ring_points.reshape(-1, 3), [[0, 0, 1], [0, 0, -1]]]) * radius + center
    segments, top, bottom = 2 * rings, len(positions) - 2, len(positions) - 1
    ring, segment = np.meshgrid(np.arange(rings - 2), np.arange(segments), indexing="ij")
    a = ring * segments + segment
    b = ring * segments + (segment + 1) % segments
    quads = np.stack([np.stack([a, a + segments, b], -1), np.stack([b, a + segments, b + segments], -1)], 2)
    last = (rings - 2) * segments
    caps = [[top, s, (s + 1) % segments] for s in range(segments)]
    caps += [[bottom, last + (s + 1) % segments, last + s] for s in range(segments)]
    return positions, np.vstack([quads.reshape(-1, 3), caps])


def scene(triangles: int):
    """Spheres of 6,240 triangles each, scattered in a box so that some cross and a small one sits in a large one."""
    random = np.random.default_rng(SEED)
    positions, faces, offset = [], [], 0
    spheres = [((5.0, 5.0, 5.0), 2.0), ((5.0, 5.0, 5.0), 0.5)]  # one inside the other
    while sum(len(f) for f in faces) < triangles:
        center, radius = spheres.pop(0) if spheres else (random.uniform(0, 10, 3), random.uniform(0.5, 1.5))
        points, triangulated = uv_sphere(40, np.asarray(center), radius)
        positions.append(points)
        faces.append(triangulated + offset)
        offset += len(points)
    return np.vstack(positions), np.vstack(faces)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the two nested spheres alone (12 k triangles)")
    result_files.add_argument(parser)
    arguments = parser.parse_args()
    result_files.check_folder(parser, arguments)
    positions, triangles = scene(10_000 if arguments.quick else 100_000)
    times = {}
    start = time.perf_counter()
    parts = mesh_faults.parts_of(triangles, len(positions))
    times["parts"] = time.perf_counter() - start
    crossing = mesh_faults.crossing_pairs(positions, triangles, parts)
    times["crossing"] = time.perf_counter() - start - sum(times.values())
    inside = mesh_faults.inside_parts(positions, triangles, parts)
    times["inside"] = time.perf_counter() - start - sum(times.values())
    degenerate, sliver = mesh_faults.thin_triangles(positions, triangles)
    times["thin"] = time.perf_counter() - start - sum(times.values())
    total = sum(times.values())
    print(f"scene: {len(triangles):,} triangles in {parts.max() + 1} parts")
    print(f"found: {len(crossing)} crossing triangle pairs, {len(inside)} parts inside others, "
          f"{int(degenerate.sum())} zero-area and {int(sliver.sum())} sliver triangles")
    print("seconds: " + ", ".join(f"{name} {seconds:.3f}" for name, seconds in times.items()))
    goal = result_files.goal(f"checks of {len(triangles):,} triangles", total, "<=", GOAL_S, "s")
    print(f"checks of {len(triangles):,} triangles: {total:.3f} s   goal <= {GOAL_S:g} s   {goal['verdict']}")
    if arguments.json:
        result_files.write("mesh_faults", arguments, {
            "triangles": len(triangles), "parts": int(parts.max() + 1), "crossing_pairs": len(crossing),
            "inside_parts": len(inside), "zero_area": int(degenerate.sum()), "slivers": int(sliver.sum()),
            "seconds": times}, [goal])


if __name__ == "__main__":
    main()
