"""Scheduling the bake's work: the fixed chunks of points it bakes (any split of chunks over workers does exactly
the same arithmetic per chunk), each point's random streams, and with a target error the rounds a point still needs
and how rounds combine into one estimate."""

import numpy as np

from .bake import BakeSettings, Receiver
from .lobes import unshadowed_norm

# Random streams per vertex (rounds × replicates): MAX_ROUNDS rounds of at most 40 lattice sizes each.
STREAMS_PER_VERTEX = 4096
MAX_ROUNDS = 6
# Target-error schedule: this estimator's error falls about as rays^-0.79 (benchmarks/estimator_study.py), and a
# round is sized for the target ÷ 1.15 so most vertices finish in one extra round.
CONVERGENCE_RATE = 0.79
TARGET_MARGIN = 1.15
# Fixed chunk size: any split of chunks over workers does exactly the same arithmetic per chunk. 128 vertices
# spread each chunk's fixed numpy work over 32 k rays at 256 samples.
CHUNK_VERTICES = 128
# A chunk of shared ray groups takes this many times the groups: it runs a round per group size (about 3.4 on the
# flat-shaded cow, against 1 for vertices), each with the same fixed numpy work, and its rows are several per group.
# Twice the groups makes the flat-shaded cow's bake up to 5 % faster; a smooth mesh gains nothing from larger chunks,
# so CHUNK_VERTICES stays as it is for them.
SHARED_CHUNK_FACTOR = 2


def vertex_keys(receiver: Receiver, rows: np.ndarray) -> np.ndarray:
    """Per-row random stream ids: 20 bits of the object's key above 30 bits of row index."""
    return stream_keys(receiver.key, rows)


def stream_keys(key: int, rows) -> np.ndarray:
    """Random stream ids of rows of something keyed `key` (core.bake.Receiver.key_for): 20 bits of the key above 30
    bits of row index, so they do not depend on what else is baked."""
    return (np.int64(key & 0xFFFFF) << np.int64(30)) + np.asarray(rows, dtype=np.int64)


def chunk_rows(receivers) -> list[tuple[int, np.ndarray]]:
    """(receiver index, rows) for chunks of CHUNK_VERTICES ray groups (rows, without groups) over every receiver,
    SHARED_CHUNK_FACTOR times as many where the groups are shared, fixed by the receivers alone: a group's rows
    share a chunk. Groups are taken in order of their size, so a chunk holds groups of one or two sizes and runs a
    round for each (core.ray_groups.ray_sets) rather than one for each of the many sizes a vertex's corners come in:
    fewer, larger rounds (the flat-shaded cow's are 138 of 25 groups on average), each paying the round's fixed numpy
    work once. The order does not change the results, which depend on the chunks' rows only."""
    chunks = []
    for index, receiver in enumerate(receivers):
        count = len(receiver.positions)
        if receiver.ray_groups is None:
            order, cuts = np.arange(count), np.arange(CHUNK_VERTICES, count, CHUNK_VERTICES)
        else:
            _, group, sizes = np.unique(receiver.ray_groups, return_inverse=True, return_counts=True)
            order = np.lexsort((receiver.ray_groups, sizes[group.ravel()]))
            labels = receiver.ray_groups[order]
            starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
            share = np.where(np.diff(np.r_[starts, count]) > 1, 1.0 / SHARED_CHUNK_FACTOR, 1.0)  # of a chunk's groups
            chunk_of_group = (np.cumsum(share) - share) // CHUNK_VERTICES  # exact for a power-of-two factor
            cuts = starts[np.flatnonzero(np.diff(chunk_of_group)) + 1]
        chunks.extend((index, rows) for rows in np.split(order, cuts))
    return chunks


def next_rounds(error, rays, settings: BakeSettings):
    """(points per replicate, vertices) for vertices still above the target: each gets one round sized so that
    its predicted combined error meets the target (error ∝ rays^-0.79, measured for this estimator), from a
    √2-spaced ladder of lattice sizes, capped by the ray budget: doubling instead would overshoot the rays needed by
    about 1.5×."""
    target = settings.target_error * unshadowed_norm(settings.order) / TARGET_MARGIN
    budget = settings.max_samples - rays
    missing = np.flatnonzero((error > target) & (budget >= settings.replicates))
    if not len(missing):
        return []
    base = settings.points_per_replicate
    ladder = np.unique(np.round(base * 2.0 ** (np.arange(1, 2 * 20) / 2)).astype(np.int64))
    now_rays, now_error = rays[missing][:, None], error[missing][:, None]
    new_rays = settings.replicates * ladder[None, :]
    new_error = now_error * (now_rays / new_rays) ** CONVERGENCE_RATE
    predicted = np.sqrt((now_rays * now_error) ** 2 + (new_rays * new_error) ** 2) / (now_rays + new_rays)
    fits = (predicted <= target) | (new_rays >= budget[missing][:, None])
    choice = np.minimum(np.argmax(fits, axis=1), np.searchsorted(ladder, budget[missing] // settings.replicates,
                                                                 side="right") - 1)
    valid = choice >= 0
    sizes = ladder[np.maximum(choice, 0)]
    return [(int(size), missing[valid & (sizes == size)]) for size in np.unique(sizes[valid])]


def combine(rounds, rays, count, order):
    """Weights rounds by their share of each vertex's rays: unbiased, optimal at the Monte Carlo rate."""
    estimate = np.zeros((count, order * order))
    variance = np.zeros((count, order * order))
    for vertices, round_rays, mean, var in rounds:
        weight = (round_rays / rays[vertices])[:, None]
        estimate[vertices] += weight * mean
        variance[vertices] += weight * weight * var
    return estimate, np.sqrt(variance.sum(1))
