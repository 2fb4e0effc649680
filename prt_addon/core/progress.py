"""Long operations: progress with time left, and the one protocol every job follows.

A job (a bake, a validation, a study) works in bounded steps: `step(budget_s)` works for about that long and says
whether it is done, `progress` has the fraction and the time left, `cancel()` stops it, leaving nothing half
written, and `outcome()` is what it produced. Two drivers run jobs: `Job.run` here (background and command line:
a log line every 5 % of the work, as the original program refreshed its bar every 1 %) and the interface's modal
operator (a progress bar, the status bar, Esc cancels).
"""

from contextlib import contextmanager
import gc
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


@contextmanager
def old_objects_frozen():
    """Within the block (or the function it decorates), Python's cyclic garbage collector leaves alone every object
    made before it (gc.freeze). A job makes and drops many containers (ray casts' results, lists handed to Blender),
    and they start collections; every full one traversed all the objects Blender's Python holds, none of which a
    job's step turns into garbage: about 30 ms each, in most of the flat-shaded cow's bakes. Objects made in the
    block are collected as usual. A caller that froze objects already keeps them frozen (blocks nest)."""
    if gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


class Progress:
    """Fraction done and time left, estimated from the elapsed time (as the original program's progress bar did)."""

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
    """Says when a background log line is due: every `step` of the work (the original program refreshed every 1 %)."""

    def __init__(self, step: float = 0.05):
        self.step = step
        self.next_mark = 0.0

    def due(self, fraction: float) -> bool:
        if fraction + 1e-12 >= self.next_mark:
            self.next_mark = (int(fraction / self.step) + 1) * self.step
            return True
        return False


class Job:
    """Base of every long operation; subclasses define step(), progress and outcome(), and cancel() if they hold
    anything to release."""
    progress: Progress

    def step(self, budget_s: float) -> bool:
        raise NotImplementedError

    def cancel(self):
        pass

    def outcome(self):
        return None

    @old_objects_frozen()
    def run(self, log=None, budget_s: float = 0.5, every: float = 0.05):
        """Steps to the end, with `log(line)` of the progress and time left every `every` of the work and at the
        end; returns the outcome. Anything that stops it on the way (an error, Ctrl+C, SIGTERM) cancels it first,
        so its worker processes and temporary files are gone before the caller hears of it."""
        throttle = LogThrottle(every)
        try:
            while not self.step(budget_s):
                if log and throttle.due(self.progress.fraction):
                    log(self.progress.line())
        except BaseException:
            self.cancel()
            raise
        if log:
            log(self.progress.line())
        return self.outcome()


class WrappingJob(Job):
    """A job whose work is another job's (`inner()`): it steps, reports and cancels through it and adds what it
    makes of the outcome (a scene bake stores the bake job's results; a validation compares Cycles' passes)."""

    def inner(self) -> Job:
        raise NotImplementedError

    @property
    def progress(self) -> Progress:
        return self.inner().progress

    def step(self, budget_s: float) -> bool:
        return self.inner().step(budget_s)

    def cancel(self):
        self.inner().cancel()


class JobSequence(Job):
    """Jobs run one after another as one job: its progress weighs each by its share of the work. A job that depends
    on those before it is given as a function that makes it, called when its turn comes. The sequence and each of
    its jobs are timed from their first step, not from when they were made (a farm bake's scene is gathered
    before its cluster has baked the parts it merges)."""

    def __init__(self, jobs: list, shares: list, label: str, clock=time.perf_counter):
        self.jobs = jobs
        self.shares = [share / sum(shares) for share in shares]
        self.current = 0
        self._started = 0  # jobs begun
        self.progress = Progress(label, clock)

    def step(self, budget_s: float) -> bool:
        if self.current < len(self.jobs):
            if not isinstance(self.jobs[self.current], Job):
                self.jobs[self.current] = self.jobs[self.current]()
            job = self.jobs[self.current]
            if self.current == self._started:
                if not self._started:
                    self.progress.start = self.progress.clock()
                job.progress.start = job.progress.clock()
                self._started += 1
            if job.step(budget_s):
                self.current += 1
        upcoming = self.jobs[self.current] if self.current < len(self.jobs) else None
        running = upcoming.progress.fraction if isinstance(upcoming, Job) else 0.0
        self.progress.fraction = sum(self.shares[:self.current]) + (
            self.shares[self.current] * running if upcoming is not None else 0.0)
        return self.current == len(self.jobs)

    def cancel(self):
        if self.current < len(self.jobs) and isinstance(self.jobs[self.current], Job):
            self.jobs[self.current].cancel()
