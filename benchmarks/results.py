"""Benchmark results: what a benchmark's `--json` writes, and the current table generated from them.

A run with `--json` writes benchmarks/results/<YYYY-MM-DD>-<benchmark>.json (or the same name in the folder given
after `--json`): when and where it ran (UTC time, git commit, cores and load average, Blender), its command line,
the rows it measured and each goal with its figure, bound and PASS or MISS. A file is written whole or not at all,
and never over another: a later run of a benchmark on the same day is <YYYY-MM-DD>-<benchmark>-2.json, -3, .... Smoke runs (`--quick`) measure nothing a goal is
for: they may write only into a folder given to them, and the table leaves them out.

    .venv/bin/python benchmarks/results.py --table   # writes docs/reference/benchmarks.md from the results
    .venv/bin/python benchmarks/results.py --check   # exit 1 if that page is not what the results give

The table takes each goal's figure from the latest result that measured it (a run of some sections of a benchmark
leaves the others' figures as they were), so a goal missed stays in it, marked MISS, until a run meets it.
"""

import argparse
from datetime import datetime, timezone
import importlib.metadata
import json
import os
from pathlib import Path
import shlex
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from prt_addon.core.outputs import replacing, write_json  # noqa: E402  (the repository root on the path first)

RESULTS = ROOT / "benchmarks" / "results"
TABLE = ROOT / "docs" / "reference" / "benchmarks.md"
RELATIONS = {
    "<=": lambda figure, bound: figure <= bound,
    ">=": lambda figure, bound: figure >= bound,
    "==": lambda figure, bound: figure == bound,
    "within": lambda figure, bound: abs(figure - 1.0) <= bound,  # a ratio within ± bound of 1
}
SHOWN = {"<=": "≤", ">=": "≥", "==": "="}  # "within" is shown as its own words (bound_text)


def add_argument(parser: argparse.ArgumentParser):
    """The `--json [DIR]` option every benchmark takes."""
    parser.add_argument("--json", nargs="?", const=str(RESULTS), metavar="DIR",
                        help="write the figures and goals to DIR/<date>-<benchmark>.json (default DIR: "
                             "benchmarks/results; a --quick run needs a DIR of its own)")


def check_folder(parser: argparse.ArgumentParser, args):
    """Refuses, before any work, a smoke run's results in the folder the table is generated from."""
    if args.json and getattr(args, "quick", False) and Path(args.json).resolve() == RESULTS:
        parser.error("--quick figures are not results: give --json a folder of their own (--json DIR)")


def verdict(figure, relation: str, bound) -> str:
    """PASS or MISS: whether `figure relation bound` holds."""
    return "PASS" if RELATIONS[relation](figure, bound) else "MISS"


def goal(name: str, figure, relation: str, bound, unit: str = "") -> dict:
    """One goal as a result records it; `name` is what the table calls it, the same in every run."""
    return {"name": name, "figure": plain(figure), "relation": relation, "bound": bound, "unit": unit,
            "verdict": verdict(figure, relation, bound)}


def plain(value):
    """`value` with numpy's scalars and arrays, tuples and paths made what JSON writes."""
    return json.loads(json.dumps(value, default=lambda v: v.tolist() if hasattr(v, "tolist") else str(v)))


def commit() -> str:
    """The checkout's commit, with `+changes` when its tracked files differ from it (results written since are not
    changes to what is measured)."""
    def git(*arguments):
        return subprocess.run(["git", *arguments], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    head = git("rev-parse", "--short=12", "HEAD") or "unknown"
    changed = git("status", "--porcelain", "--untracked-files=no", "--", ".", ":!benchmarks/results")
    return head + ("+changes" if changed else "")


def blender_version() -> str:
    """The Blender the benchmark ran: the bpy module's version (read without importing it where it is not)."""
    if "bpy" in sys.modules:
        return sys.modules["bpy"].app.version_string
    try:
        return importlib.metadata.version("bpy")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def write(benchmark: str, args, rows, goals: list, argv=None) -> Path:
    """Writes one run's result where `--json` asked; returns its path."""
    now = datetime.now(timezone.utc)
    record = {
        "benchmark": benchmark,
        "date": now.isoformat(timespec="seconds"),
        "commit": commit(),
        "machine": {"cores": os.cpu_count(), "load_average": [round(v, 2) for v in os.getloadavg()]},
        "blender": blender_version(),
        "command": shlex.join(["benchmarks/" + benchmark + ".py", *(sys.argv[1:] if argv is None else argv)]),
        "quick": bool(getattr(args, "quick", False)),
        "rows": plain(rows),
        "goals": goals,
    }
    folder, name = Path(args.json), f"{now:%Y-%m-%d}-{benchmark}"
    path, count = folder / f"{name}.json", 1
    while path.exists():  # a run of other sections the same day keeps the first one's figures
        count += 1
        path = folder / f"{name}-{count}.json"
    write_json(str(path), record)
    print(f"wrote {path}")
    return path


# -- the current table ------------------------------------------------------------------------------------
def read_results(folder: Path = RESULTS) -> list[dict]:
    """Every full run's result in `folder`, oldest first."""
    records = [json.loads(path.read_text(encoding="utf-8")) for path in sorted(folder.glob("*.json"))]
    return sorted((r for r in records if not r["quick"]), key=lambda r: (r["date"], r["benchmark"]))


def current_goals(records: list[dict]) -> dict:
    """{benchmark: {goal name: (goal, the result it came from)}}, each from the latest result measuring it."""
    table = {}
    for record in records:
        for entry in record["goals"]:
            table.setdefault(record["benchmark"], {})[entry["name"]] = (entry, record)
    return table


def figure_text(value, unit: str, bound=None) -> str:
    """A figure to 4 significant digits, or 6 within 1 % of its bound (99.9999 against 99.99 is not 100)."""
    digits = 6 if isinstance(bound, (int, float)) and abs(value - bound) <= 0.01 * abs(bound) else 4
    shown = f"{value:.{digits}g}" if isinstance(value, float) else str(value)
    return shown + (f" {unit}" if unit else "")


def bound_text(entry: dict) -> str:
    bound = entry["bound"]
    if entry["relation"] == "within":
        return f"within ±{bound:g} of 1"
    return f"{SHOWN[entry['relation']]} {figure_text(bound, entry['unit'])}"


def table(records: list[dict]) -> str:
    """The page docs/reference/benchmarks.md: one row per goal, its latest figure and where it was measured."""
    lines = ["# Benchmark results", "",
             "Generated by `.venv/bin/python benchmarks/results.py --table` from the latest result of each goal in "
             "`benchmarks/results/`; do not edit it by hand. What each benchmark measures and how to run it: "
             "`benchmarks/README.md`. Figures are from machines shared with other work: ratios measured side by "
             "side in one run, each with its load average.", "",
             "| benchmark | goal | figure | bound | verdict | measured |", "| --- | --- | ---: | --- | --- | --- |"]
    sources, goals = {}, current_goals(records)
    latest = {record["benchmark"]: record for record in records}
    for benchmark in sorted(set(goals) | set(latest)):
        if benchmark not in goals:  # a study without goals: its figures are its rows
            record = latest[benchmark]
            number = sources.setdefault((benchmark, record["date"]), (len(sources) + 1, record))[0]
            lines.append(f"| `{benchmark}.py` | no goal: its rows in `benchmarks/results/{record['date'][:10]}-"
                         f"{benchmark}.json` | | | | {record['date'][:10]} [{number}] |")
        for name, (entry, record) in goals.get(benchmark, {}).items():
            number = sources.setdefault((benchmark, record["date"]), (len(sources) + 1, record))[0]
            mark = "**MISS**" if entry["verdict"] == "MISS" else "PASS"
            figure = figure_text(entry["figure"], entry["unit"], entry["bound"])
            lines.append(f"| `{benchmark}.py` | {name} | {figure} | {bound_text(entry)} | {mark} | "
                         f"{record['date'][:10]} [{number}] |")
    lines += ["", "## Where each figure was measured", ""]
    for number, record in sources.values():
        machine = record["machine"]
        load = (f"load average {', '.join(f'{value:g}' for value in machine['load_average'])}"
                if machine["load_average"]  # a transcribed result has the load as it was described, if it was
                else f"load: {machine.get('load', 'not recorded')}")
        origin = f"; {record['source']}" if record.get("source") else ""
        lines.append(f"{number}. `{record['command']}`: {record['date']}, commit `{record['commit']}`, Blender "
                     f"{record['blender']}, {machine['cores']} cores, {load}{origin}.")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="the current table of benchmark results")
    parser.add_argument("--results", default=str(RESULTS), help="the folder of results (default benchmarks/results)")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--table", action="store_true", help=f"write {TABLE.relative_to(ROOT)}")
    which.add_argument("--check", action="store_true", help=f"exit 1 if {TABLE.relative_to(ROOT)} is stale")
    args = parser.parse_args(argv)
    page = table(read_results(Path(args.results)))
    if args.check:
        if not TABLE.exists() or TABLE.read_text(encoding="utf-8") != page:
            print(f"{TABLE.relative_to(ROOT)} is stale: run .venv/bin/python benchmarks/results.py --table",
                  file=sys.stderr)
            return 1
        print(f"{TABLE.relative_to(ROOT)} is current")
        return 0
    with replacing(str(TABLE)) as temporary:
        Path(temporary).write_text(page, encoding="utf-8")
    print(f"wrote {TABLE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
