"""Where a bake decides a point by rule instead of measuring it with rays: one code per point, carried in every
chunk's result (core.bake.ChunkResult), farm part and receiver result, counted per object in the report and shown
as the "Decided by rule" heatmap, so an artist sees where to look when a bake disagrees with Cycles.

The rules (README, "Messy models: what Cycles decides"):
- LYING: in contact, lying on a surface it faces (core.contact): black, every direction enters that surface;
- TOUCHING: in contact with a surface at an angle (core.contact): rays measure it, but start in front of both
  surfaces, where the rule puts them;
- AGAINST: its normal points against its face (core.corners): black, as Cycles shades it from behind.
A point is decided by one rule at most: an AGAINST point has no surface of its own, so contact never judges it.

A rule that sets a point black may be wrong by the sky it leaves out, and that doubt joins the bake's error estimate
(estimate): Cycles gathers an AGAINST corner over the directions behind its face and away from its normal, the lune
of −N in front of −Ng, (1 + N·Ng)/2 of the sky, which the part usually covers; a LYING point faces the surface it lies
on within 8°, and may see past it the lune of its normal in front of that surface, (1 + n·n_s)/2 ≤ 0.5 % of the
sky. Either doubt is that lune's unshadowed transfer (core.polygons.lune_transfer): the error the rule makes where
nothing covers it. A TOUCHING point is measured by rays, which the rule only starts elsewhere: no doubt.
"""

import numpy as np

from . import polygons
from .statistics import rms

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


def doubt(order: int, normals: np.ndarray, planes: np.ndarray | None) -> np.ndarray:
    """(c,) the norm of the unshadowed transfer of each normal (c, 3) in front of its plane (c, 3; normals, not
    necessarily unit) through the point: what a rule that made the point black leaves out. None: no plane known,
    and the doubt is its widest a rule allows, a plane through the normal (half the sky; the norm is the same for
    every such plane, by symmetry about the normal)."""
    normals = np.asarray(normals, dtype=np.float64)
    if planes is None:
        widest = polygons.lune_transfer(order, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
        return np.full(len(normals), float(np.linalg.norm(widest)))
    lengths = [np.linalg.norm(vectors, axis=1, keepdims=True) for vectors in (normals, planes)]
    unit = [np.divide(vectors, length, out=np.zeros_like(vectors, dtype=np.float64), where=length > 0)
            for vectors, length in zip((normals, planes), lengths)]
    return np.linalg.norm(polygons.lune_transfer(order, *unit), axis=1)


def estimate(rel_error: np.ndarray, rule_error: np.ndarray) -> dict:
    """A report's error estimate over points: each point's noise (`rel_error`, relative) and its rule's doubt
    (`rule_error`, relative alike) as independent errors, added in quadrature; their RMS and largest, and the
    doubt's own RMS, the part of the estimate the rules make (its square the part of the RMS's square)."""
    total = np.hypot(rel_error, rule_error)
    return {"est_rms_rel_error": rms(total), "est_max_rel_error": float(total.max(initial=0.0)),
            "est_rule_rms_rel_error": rms(rule_error)}


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
