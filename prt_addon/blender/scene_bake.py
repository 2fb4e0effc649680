"""A bake of a Blender scene in four steps over plain values, the same for the operator, every command, the farm
and Dask:

    request = read_request(context, settings, names)    # blender.request: read from Blender once
    plan = plan_bake(request)                           # blender.plan: writes nothing, casts no ray; checks run on it
    results = execute(plan, executor).run()             # blender.execute: a job (progress, time left, cancel)
    report = store(plan, results)                       # blender.store: the only step that writes

SceneBake is those steps as one job, for a driver that steps it (the modal operator) or runs it. Nothing is written
until every receiver is baked: a cancelled or failed bake leaves the previous data as it was.
"""

import bpy

from ..core import settings as spec
from ..core.progress import WrappingJob
from .execute import execute, local_executor
from .plan import BakePlan, plan_bake
from .request import read_request
from .store import BakeReport, store


class SceneBake(WrappingJob):
    """The scene's bake as one job: requested and planned when made, executed step by step, stored as its outcome.
    `executor` may be replaced before the first step."""

    def __init__(self, context, settings, object_names=None, workers: int = 1, storage_options=None):
        """storage_options: blender.texel_bake.TexelOptions fields that override every receiver's own (the command
        line's)."""
        self.plan = plan_bake(read_request(context, settings, object_names, storage_options))
        self.executor = local_executor(spec.worker_count(workers))
        self.execution, self.results, self.bake_report = None, None, None

    @classmethod
    def of_plan(cls, plan: BakePlan, executor) -> "SceneBake":
        """The job of a plan already made (and checked)."""
        scene_bake = cls.__new__(cls)
        scene_bake.plan, scene_bake.executor = plan, executor
        scene_bake.execution, scene_bake.results, scene_bake.bake_report = None, None, None
        return scene_bake

    def inner(self):
        if self.execution is None:
            self.execution = execute(self.plan, self.executor)
        return self.execution

    def outcome(self):
        """Stores the bake, once, and returns its summary."""
        return self.store().summary

    def store(self) -> BakeReport:
        """Stores the bake once it is executed (once); its report."""
        if self.bake_report is None:
            self.results = self.inner().outcome()
            self.bake_report = store(self.plan, self.results)
        return self.bake_report

    def report(self) -> BakeReport:
        return self.store()

    @property
    def summary(self):
        """The stored bake's summary; None before."""
        return self.bake_report.summary if self.bake_report else None

    @property
    def objects(self) -> list:
        """The receivers, looked up by name."""
        return [bpy.data.objects[(name, None)] for name in self.plan.names]

    @property
    def problems(self) -> list:
        """The objects not baked, one sentence each: so far, or once stored."""
        return self.bake_report.problems if self.bake_report else self.plan.problems

    @property
    def notes(self) -> list:
        """What the user should know of the bake: so far, or once stored."""
        return self.bake_report.notes if self.bake_report else self.plan.notes()
