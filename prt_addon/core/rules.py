"""Where a bake decides a point by rule instead of measuring it with rays: one code per point, carried in every
chunk's result (core.bake.ChunkResult), farm part and receiver result, counted per object in the report and shown
as the "Decided by rule" heatmap, so an artist sees where to look when a bake disagrees with Cycles.

The rules (README, "Messy models: what Cycles decides"):
- LYING: in contact, lying on a surface it faces (core.contact): black, every direction enters that surface;
- TOUCHING: in contact with a surface at an angle (core.contact): rays measure it, but start in front of both
  surfaces, where the rule puts them;
- AGAINST: its normal points against its face (core.corners): black, as Cycles shades it from behind.
A point is decided by one rule at most: an AGAINST point has no surface of its own, so contact never judges it.
"""

import numpy as np

MEASURED, LYING, TOUCHING, AGAINST = 0, 1, 2, 3
# The report's key and the words of each rule, in the order the summary lists them.
KEYS = {LYING: "lying", TOUCHING: "touching", AGAINST: "against"}
WORDS = {LYING: "lying on a surface (black)", TOUCHING: "touching a surface at an angle",
         AGAINST: "normal against their face (black)"}
LARGEST = max(KEYS)
DTYPE = np.uint8


def measured(count: int) -> np.ndarray:
    """(count,) codes of points no rule decided."""
    return np.zeros(count, dtype=DTYPE)


def counts(codes: np.ndarray) -> dict:
    """{key: points} of each rule that decided some of `codes`, in KEYS' order."""
    found = np.bincount(codes, minlength=LARGEST + 1)
    return {key: int(found[code]) for code, key in KEYS.items() if found[code]}


def total(per_object) -> dict:
    """The counts of several objects (counts' dicts) summed, in KEYS' order."""
    per_object = list(per_object)
    return {key: n for key in KEYS.values() if (n := sum(found.get(key, 0) for found in per_object))}


def words(found: dict) -> str:
    """"12 lying on a surface (black), 3 normal against their face (black)" for counts' dict ("" for none)."""
    by_key = {key: code for code, key in KEYS.items()}
    return ", ".join(f"{n} {WORDS[by_key[key]]}" for key, n in found.items())
