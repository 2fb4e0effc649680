"""Progress with time left, shared by the panel, the status bar and background logs."""

import time


def format_duration(seconds: float) -> str:
    """'1h02m', '3m05s' or '12.3s': short enough for a status bar."""
    if seconds != seconds or seconds == float("inf"):
        return "?"
    seconds = max(0.0, seconds)
    if seconds >= 3600:
        return f"{int(seconds // 3600)}h{int(seconds % 3600 // 60):02d}m"
    if seconds >= 60:
        return f"{int(seconds // 60)}m{int(seconds % 60):02d}s"
    return f"{seconds:.1f}s"


class Progress:
    """Fraction done and time left, estimated from the elapsed time (as the seed's progress bar did)."""

    def __init__(self, label: str, clock=time.perf_counter):
        self.label = label
        self.clock = clock
        self.start = clock()
        self.fraction = 0.0

    @property
    def elapsed(self) -> float:
        return self.clock() - self.start

    @property
    def remaining(self) -> float:
        if self.fraction <= 0.0:
            return float("inf")
        return self.elapsed * (1.0 - self.fraction) / self.fraction

    def line(self) -> str:
        return (f"{self.label}: {100.0 * self.fraction:5.1f} %  elapsed {format_duration(self.elapsed)}"
                f"  left {format_duration(self.remaining)}")


class LogThrottle:
    """Says when a background log line is due: every `step` of the work (the seed refreshed every 1 %)."""

    def __init__(self, step: float = 0.05):
        self.step = step
        self.next_mark = 0.0

    def due(self, fraction: float) -> bool:
        if fraction + 1e-12 >= self.next_mark:
            self.next_mark = (int(fraction / self.step) + 1) * self.step
            return True
        return False
