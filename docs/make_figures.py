"""The manual's figures, made in one command from scenes built here, baked and rendered as a user would: through the
extension's commands and the functions its panels call.

    .venv/bin/python docs/make_figures.py [--quick] [--out docs/figures] [--only NAME[,NAME]]

Each figure is one module, docs/figures_*.py, whose docstring says what it shows and what it prints; the demo scene
(`prt demo`'s) is baked once for all that show it. Each figure's numbers are printed, and tests/test_figures.py
reads them back. --quick renders small with few samples: the same scenes and commands, for that smoke test.
"""

import argparse
import os
import sys
import tempfile
import time

DOCS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(DOCS)
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests")]  # the add-on; tests/browser.py, which drives Chromium

import bpy  # noqa: E402,F401  (before mathutils, which the add-on imports)

import figures_common  # noqa: E402
import figures_convergence  # noqa: E402
import figures_dynamic  # noqa: E402
import figures_heatmap  # noqa: E402
import figures_light_report  # noqa: E402
import figures_relight  # noqa: E402
import figures_validation  # noqa: E402
import figures_viewer  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402

FIGURES = {module.NAME.removesuffix(".png"): module for module in (
    figures_relight, figures_heatmap, figures_validation, figures_convergence, figures_light_report,
    figures_viewer, figures_dynamic)}


def figure_names(text: str) -> list[str]:
    names = [name.strip().removesuffix(".png") for name in text.split(",") if name.strip()]
    unknown = [name for name in names if name not in FIGURES]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown figure {', '.join(unknown) or repr(text)}: expected some of "
                                         f"{', '.join(FIGURES)}")
    return names


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small renders, few samples: a smoke run")
    parser.add_argument("--out", default=os.path.join(DOCS, "figures"), help="folder for the PNGs")
    parser.add_argument("--only", type=figure_names, metavar="NAME[,NAME]",
                        help=f"make only these figures (of {', '.join(FIGURES)})")
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="prt_figures_") as scratch, schema_registered(relighting=True):
        run = figures_common.Run(os.path.abspath(args.out), args.quick, scratch)
        for name in args.only or FIGURES:
            start = time.perf_counter()
            path = FIGURES[name].make(run)
            print(f"wrote {path} ({os.path.getsize(path) // 1024} KB) in {time.perf_counter() - start:.0f} s",
                  flush=True)
    print(f"made {len(args.only or FIGURES)} figures in {time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
