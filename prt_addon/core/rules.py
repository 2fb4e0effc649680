"""Where a bake decides a point by rule instead of measuring it with rays: one code per point, carried in every
chunk's result (core.bake.ChunkResult), farm part and receiver result, counted per object in the report and shown
as the "Decided by rule" heatmap, so an artist sees where to look when a bake disagrees with Cycles.

The rules (docs/design/contact.md, docs/cycles_conventions.md):
- LYING: in contact, lying on a surface it faces (core.contact): black, every direction enters that surface;
- TOUCHING: in contact with a surface at an angle (core.contact): rays measure it, but start in front of both
  surfaces, where the rule puts them;
- AGAINST: its normal N points against its face (core.corners): rays measure it as Cycles shades it, from behind,
  with the normal −N and its sky clipped by its face reversed (−Ng); the code only marks where normals are against
  their faces.
A point is decided by one rule at most: an AGAINST point is shaded from behind its own face, so contact never
judges it (core.estimator).

A rule that sets a point black may be wrong by the sky it leaves out, and that doubt joins the bake's error estimate
(estimate): a LYING point faces the surface it lies on within 8°, and may see past it the lune of its normal in front
of that surface, (1 + n·n_s)/2 ≤ 0.5 % of the sky, whose unshadowed transfer (core.polygons.lune_transfer) is its
doubt: the error the rule makes where nothing covers it. TOUCHING and AGAINST points are measured by rays, which the
rules only start elsewhere or turn round: no doubt.
"""

import numpy as np

from . import polygons, sampling
from .statistics import rms

MEASURED, LYING, TOUCHING, AGAINST = 0, 1, 2, 3
# The report's key and the words of each rule, in the order the summary lists them.
KEYS = {LYING: "lying", TOUCHING: "touching", AGAINST: "against"}
WORDS = {LYING: "lying on a surface (black)", TOUCHING: "touching a surface at an angle",
         AGAINST: "normal against their face (shaded from behind, as Cycles)"}
LARGEST = max(KEYS)
DTYPE = np.uint8


def measured(count: int) -> np.ndarray:
    """(count,) codes of points no rule decided."""
    return np.zeros(count, dtype=DTYPE)


def doubt(order: int, normals: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """(c,) the norm of the unshadowed transfer of each normal (c, 3) in front of its plane (c, 3; normals, not
    necessarily unit) through the point: what a rule that made the point black leaves out."""
    return np.linalg.norm(polygons.lune_transfer(order, sampling.unit_or_zero(normals), sampling.unit_or_zero(planes)),
                          axis=1)


def point_errors(rel_error: np.ndarray, rule_error: np.ndarray) -> np.ndarray:
    """Each point's estimated error: its noise (`rel_error`, relative) and its rule's doubt (`rule_error`, relative
    alike) as independent errors, added in quadrature."""
    return np.hypot(rel_error, rule_error)


def estimate(rel_error: np.ndarray, rule_error: np.ndarray) -> dict:
    """A report's error estimate over points (point_errors): their RMS and largest, and the doubt's own RMS, the part
    of the estimate the rules make (its square the part of the RMS's square)."""
    total = point_errors(rel_error, rule_error)
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
    """"12 lying on a surface (black), 3 normal against their face (shaded from behind, as Cycles)" for counts' dict
    ("" for none)."""
    by_key = {key: code for code, key in KEYS.items()}
    return ", ".join(f"{n} {WORDS[by_key[key]]}" for key, n in found.items())
