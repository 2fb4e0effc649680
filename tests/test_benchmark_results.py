"""benchmarks/results.py: the result files benchmarks write with --json, and docs/reference/benchmarks.md, the
table generated from them, which must be what the files in benchmarks/results/ give."""

import argparse
import json
from pathlib import Path
import re

import pytest

from conftest import ROOT
from benchmarks import results

KEYS = {"benchmark", "date", "commit", "machine", "blender", "command", "quick", "rows", "goals"}


def record(benchmark: str, date: str, goals: list, quick=False) -> dict:
    return {"benchmark": benchmark, "date": date, "commit": "0123456789ab", "blender": "5.3.0", "quick": quick,
            "machine": {"cores": 2, "load_average": [1.0, 1.0, 1.0]}, "command": f"benchmarks/{benchmark}.py",
            "rows": {}, "goals": goals}


def save(folder: Path, entry: dict):
    (folder / f"{entry['date'][:10]}-{entry['benchmark']}.json").write_text(json.dumps(entry), encoding="utf-8")


def test_the_table_page_is_current():
    """Regenerate it with `.venv/bin/python benchmarks/results.py --table` after adding a result."""
    assert results.main(["--check"]) == 0


@pytest.mark.parametrize("path", sorted((ROOT / "benchmarks" / "results").glob("*.json")), ids=lambda p: p.name)
def test_each_stored_result_is_whole_and_its_verdicts_are_its_figures(path):
    entry = json.loads(path.read_text(encoding="utf-8"))
    assert KEYS <= set(entry) and not entry["quick"], path.name
    assert re.fullmatch(rf"{entry['date'][:10]}-{entry['benchmark']}(-[2-9]|-[1-9]\d+)?\.json", path.name)
    assert (ROOT / "benchmarks" / f"{entry['benchmark']}.py").is_file()
    names = [goal["name"] for goal in entry["goals"]]
    assert len(names) == len(set(names)), names
    for goal in entry["goals"]:  # a transcribed MISS stays a MISS: the verdict is recomputed from the figure
        assert goal["verdict"] == results.verdict(goal["figure"], goal["relation"], goal["bound"]), goal


def test_each_goal_comes_from_the_latest_full_run_measuring_it(tmp_path):
    """A later run of some sections leaves the other goals' figures as they were; a smoke run counts for nothing."""
    save(tmp_path, record("engines", "2026-01-01T10:00:00+00:00", [
        results.goal("casts", 12.6, ">=", 15.0, "×"), results.goal("agreement", 99.9999, ">=", 99.99, "%")]))
    save(tmp_path, record("engines", "2026-02-01T10:00:00+00:00", [results.goal("casts", 16.0, ">=", 15.0, "×")]))
    save(tmp_path, record("engines", "2026-03-01T10:00:00+00:00", [results.goal("casts", 1.0, ">=", 15.0, "×")],
                          quick=True))
    page = results.table(results.read_results(tmp_path))
    rows = [line for line in page.splitlines() if line.startswith("| `engines.py`")]
    assert rows == ["| `engines.py` | casts | 16 × | ≥ 15 × | PASS | 2026-02-01 [1] |",
                    "| `engines.py` | agreement | 99.9999 % | ≥ 99.99 % | PASS | 2026-01-01 [2] |"]
    assert "2. `benchmarks/engines.py`: 2026-01-01T10:00:00+00:00, commit `0123456789ab`" in page
    assert "2026-03-01" not in page


def test_a_missed_goal_is_marked():
    entry = results.goal("flat ÷ smooth", 1.52, "<=", 1.5)
    assert entry["verdict"] == "MISS"
    page = results.table([record("corners", "2026-01-01T00:00:00+00:00", [entry])])
    assert "| `corners.py` | flat ÷ smooth | 1.52 | ≤ 1.5 | **MISS** |" in page
    assert results.verdict(1.04, "within", 0.05) == "PASS" and results.verdict(0.94, "within", 0.05) == "MISS"


def test_a_result_is_written_whole_where_json_asks(tmp_path):
    args = argparse.Namespace(json=str(tmp_path), quick=True)
    path = results.write("relight", args, {"ms": (1.5, 2)}, [results.goal("ms", 1.5, "<=", 33.0, "ms")],
                         ["--quick", "--json", str(tmp_path)])
    assert path.parent == tmp_path and sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left
    entry = json.loads(path.read_text(encoding="utf-8"))
    assert KEYS <= set(entry) and entry["rows"] == {"ms": [1.5, 2]} and entry["quick"] is True
    assert entry["command"] == f"benchmarks/relight.py --quick --json {tmp_path}"
    assert path.name == f"{entry['date'][:10]}-relight.json"
    again = results.write("relight", args, {}, [], [])  # a second run the same day keeps the first one's file
    assert again.name == f"{entry['date'][:10]}-relight-2.json" and json.loads(path.read_text()) == entry


def test_a_smoke_run_may_not_write_into_the_results(capsys):
    parser = argparse.ArgumentParser(prog="relight.py")
    parser.add_argument("--quick", action="store_true")
    results.add_argument(parser)
    with pytest.raises(SystemExit):
        results.check_folder(parser, parser.parse_args(["--quick", "--json"]))
    assert "--quick figures are not results" in capsys.readouterr().err
    results.check_folder(parser, parser.parse_args(["--json"]))  # a full run writes there
