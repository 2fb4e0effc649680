"""The goals benchmarks/assets.py and benchmarks/messy_assets.py judge their cases by: each case's misses (the
table's last column), the goal lines printed after the table and the goals their `--json` records."""

from dataclasses import dataclass
import math
from typing import Callable

from benchmarks import results as result_files

DEMO = "demo"


def spread(ratio: float) -> float:
    """How far a ratio is from 1 either way: 1.5 for 1.5 and for 1/1.5."""
    return max(ratio, 1.0 / ratio) if ratio > 0 else math.inf


@dataclass(frozen=True)
class Goal:
    what: str                       # the goal line's words
    name: str                       # the results table's name for its figure, the worst case's
    short: str                      # the table's goals column when a case misses it
    judges: Callable                # row → whether the goal judges the case
    figure: Callable                # row → the figure the bound is for
    bound: float
    unit: str
    shown: Callable                 # row → its figure as a miss prints it


GOALS = {
    "asset_rms": Goal("RMS ≤ 2 % against Cycles, every asset", "RMS against Cycles, worst asset", "RMS",
                      lambda r: r.case != DEMO, lambda r: 100 * r.rel_rms_error, 2.0, "%",
                      lambda r: f"{100 * r.rel_rms_error:.2f} %"),
    "asset_p99": Goal("p99 ≤ 10 % against Cycles, every asset", "p99 against Cycles, worst asset", "p99",
                      lambda r: r.case != DEMO, lambda r: 100 * r.rel_p99_error, 10.0, "%",
                      lambda r: f"{100 * r.rel_p99_error:.1f} %"),
    "demo_rms": Goal("RMS ≤ 1 % against Cycles, the demo scene", "RMS against Cycles, the demo scene", "RMS",
                     lambda r: r.case == DEMO, lambda r: 100 * r.rel_rms_error, 1.0, "%",
                     lambda r: f"{100 * r.rel_rms_error:.2f} %"),
    "honest": Goal("actual ÷ estimated error within 1/1.5..1.5, every case",
                   "actual ÷ estimated error, farthest from 1 either way", "estimate",
                   lambda r: True, lambda r: spread(r.honesty), 1.5, "",
                   lambda r: "exact, but the reference differs" if r.est_at_reference == 0 else f"{r.honesty:.2f}"),
}


def missed(goal: Goal, row) -> bool:
    return not goal.figure(row) <= goal.bound  # a NaN figure misses


def missed_goals(row) -> list:
    """The goals a case misses, as the table's last column names them."""
    return [goal.short for goal in GOALS.values() if goal.judges(row) and missed(goal, row)]


def goal_lines(rows) -> list[str]:
    """One line per goal judging any of the rows: PASS, or MISS with the cases and their figures."""
    lines = []
    for goal in GOALS.values():
        judged = [row for row in rows if goal.judges(row)]
        if judged:
            misses = [f"{row.case} {goal.shown(row)}" for row in judged if missed(goal, row)]
            lines.append(f"goal {goal.what}: " + ("MISS: " + ", ".join(misses) if misses else "PASS"))
    return lines


def goals(rows) -> list[dict]:
    """Each goal judging any of the rows at its worst case, as benchmarks/results.py records it."""
    found = []
    for goal in GOALS.values():
        judged = [row for row in rows if goal.judges(row)]
        if judged:
            worst = max((goal.figure(row) for row in judged), key=lambda v: math.inf if math.isnan(v) else v)
            found.append(result_files.goal(goal.name, worst, "<=", goal.bound, goal.unit))
    return found
