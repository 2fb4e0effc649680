"""Progress of jobs run one after another (core.progress.JobSequence), on a clock the test moves."""

from prt_addon.core.progress import Job, JobSequence, Progress


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


class Waiting(Job):
    """Takes `steps` steps of one second each on the clock."""

    def __init__(self, clock, steps):
        self.clock, self.left = clock, steps
        self.progress = Progress("waiting", clock=clock)

    def step(self, budget_s):
        self.clock.now += 1.0
        self.left -= 1
        self.progress.fraction = 1.0 if self.left <= 0 else 0.5
        return self.left <= 0


def test_a_sequence_and_each_of_its_jobs_are_timed_from_their_first_step_and_weighed_by_their_share():
    clock = Clock()
    first, second = Waiting(clock, 3), Waiting(clock, 2)  # both made now, as a bake makes its jobs up front
    sequence = JobSequence([first, second], [3, 1], "both", clock)
    clock.now += 10.0  # made long before it runs, as a farm bake's merge
    assert not sequence.step(1.0)
    assert sequence.progress.fraction == 0.75 * 0.5
    while not sequence.step(1.0):
        pass
    assert second.progress.elapsed == 2.0  # its own two steps, not the 15 s since it was made
    assert sequence.progress.elapsed == 5.0
    assert sequence.progress.fraction == 1.0
