"""Each engine's error against run time on the demo, as the bakes report it (core.error_curve), in one figure:
the estimated RMS error after each round (and after the bounces) against the seconds the bake had spent, one line
per engine, so the seconds Embree saves at every error can be read off. benchmarks/engines.py runs the bakes."""

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from benchmarks.convergence import plain_log_ticks

NAMES = {"embree": "Embree", "bvhtree": "BVHTree"}


def printed(curves: dict) -> list[str]:
    """The curves as lines: the engine, then after each step its seconds, rays and estimated RMS error."""
    return [f"   {NAMES[name]:8} " + " | ".join(f"{row.after} {row.seconds:6.1f} s {row.rays / 1e6:5.2f} M rays RMS "
                                                f"{row.est_rms_rel_error:.4f}" for row in rows)
            for name, rows in curves.items()]


def plot(curves: dict, path: str, title: str):
    """A PNG at `path`: for each engine ({name: core.error_curve rows}), estimated RMS error (log) against seconds
    (log), each step marked, and named once where it cast rays or bounced."""
    figure = Figure(figsize=(7.0, 4.5), dpi=110, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    for name, rows in curves.items():
        seconds = [row.seconds for row in rows]
        errors = [100 * row.est_rms_rel_error for row in rows]
        axes.plot(seconds, errors, marker="o", label=f"{NAMES[name]} ({rows[-1].seconds:.0f} s)")
        if name == next(iter(curves)):
            for index, (row, x, y) in enumerate(zip(rows, seconds, errors)):
                if index == 0 or row.rays > rows[index - 1].rays or not row.after.startswith("round"):
                    axes.annotate(row.after, (x, y), textcoords="offset points", xytext=(6, 4), fontsize=8)
    axes.set_xscale("log")
    axes.set_yscale("log")
    for axis in (axes.xaxis, axes.yaxis):
        plain_log_ticks(axis)
    axes.set_xlabel("seconds into the bake (wall time, 2 workers)")
    axes.set_ylabel("estimated RMS relative error (%)")
    axes.set_title(title)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.savefig(path)
