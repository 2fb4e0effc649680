"""convergence.png: the demo scene's estimated and actual RMS relative error against bake time, drawn by the
convergence study's own plot (benchmarks/convergence.py, write_plot) from its table in docs/figures/convergence.csv.

The table is the study's, committed rather than rerun here: its reference, a bake of 8192 samples, takes minutes
on two cores alone. To remake it, from the repository root (make_scenes.py saves the demo scene):

    .venv/bin/python sample_scenes/make_scenes.py
    .venv/bin/python benchmarks/convergence.py sample_scenes/demo_torus.blend --samples 16,32,64,128,256,512,1024 \\
        --reference-samples 8192 --csv docs/figures/convergence.csv --plot docs/figures/convergence.png

Printed, and read back by tests/test_figures.py: per sample count, the estimated error ÷ the actual one (an honest
estimate is near 1).
"""

import csv
from dataclasses import fields
import os

from benchmarks.convergence import Row, write_plot

NAME = "convergence.png"
TABLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "figures", "convergence.csv")
REFERENCE = "a bake of 8192 samples"


def make(run) -> str:
    rows = read_rows(TABLE)
    for row in rows:
        print(f"convergence: {row.samples} samples, {row.time_s:.2f} s: estimated ÷ actual "
              f"{row.est_rms_rel_error / row.actual_rms_rel_error:.3f}")
    path = run.path(NAME)
    write_plot(path, rows, "PRT error against bake time: the demo scene", REFERENCE)
    return path


def read_rows(path) -> list[Row]:
    """The rows benchmarks/convergence.py's write_csv wrote, each field as its Row type."""
    with open(path, newline="", encoding="utf-8") as handle:
        return [Row(**{field.name: field.type(line[field.name]) for field in fields(Row)})
                for line in csv.DictReader(handle)]
