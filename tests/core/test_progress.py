"""Progress of jobs run one after another (core.progress.JobSequence), on a clock the test moves."""

import gc
import weakref

from prt_addon.core.progress import Job, JobSequence, Progress, old_objects_frozen


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


def test_a_job_given_as_a_function_is_made_when_its_turn_comes():
    """A bake's later jobs depend on its earlier ones (Auto's probes decide what the bake is): the sequence makes
    them when the jobs before them are done, times them from their first step, and cancels only what it made."""
    clock = Clock()
    first, made = Waiting(clock, 2), []

    def second():
        made.append(first.left)  # what was left of the first job when this one was made
        return Waiting(clock, 1)
    sequence = JobSequence([first, second], [1, 1], "both", clock)
    assert not sequence.step(1.0) and made == []
    sequence.cancel()  # the first job's turn: the second is not made to be cancelled
    assert made == []
    assert not sequence.step(1.0)  # the first job ends; the second is made at its first step
    assert made == [] and sequence.progress.fraction == 0.5
    assert sequence.step(1.0)
    assert made == [0] and sequence.jobs[1].progress.elapsed == 1.0 and sequence.progress.fraction == 1.0


class Node:
    """Something that can sit in a reference cycle and be watched."""


class Cycling(Job):
    """Each step drops a reference cycle, collects, and notes what the collector saw."""

    def __init__(self, steps):
        self.left = steps
        self.progress = Progress("cycling")
        self.seen = []  # per step: (objects frozen, its cycle collected)

    def step(self, budget_s):
        node = Node()
        node.me = node
        watched = weakref.ref(node)
        del node
        gc.collect()
        self.seen.append((gc.get_freeze_count(), watched() is None))
        self.left -= 1
        self.progress.fraction = 1.0 - self.left / 2
        return self.left <= 0


def test_a_run_leaves_older_objects_to_the_collector_and_still_collects_what_it_drops():
    assert gc.get_freeze_count() == 0
    older = len(gc.get_objects())
    job = Cycling(2)
    job.run()
    assert [collected for _, collected in job.seen] == [True, True]
    assert all(frozen >= older // 2 for frozen, _ in job.seen)  # Python and pytest's own objects, at least
    assert gc.get_freeze_count() == 0  # all given back


def test_frozen_blocks_nest_and_the_outermost_gives_the_objects_back():
    with old_objects_frozen():
        frozen = gc.get_freeze_count()
        job = Cycling(1)
        job.run()
        assert job.seen == [(frozen, True)] and gc.get_freeze_count() == frozen
    assert gc.get_freeze_count() == 0
