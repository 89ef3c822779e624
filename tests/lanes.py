"""A lane of its own for the light work units.

Some units keep a core only partly busy: flights on the wall clock, MAVProxy's start, commands that
wait (their processes under ``LIGHT_CORES`` cores over their wall time, in the CPU record). Beside
any other unit one of them leaves the rest of its core idle: about 210 core-seconds of every run on
two cores (2026-11-27), however the units were ordered. So, with a CPU record, ``-n auto`` starts
one worker more than xdist would (tests/conftest.py), and that worker, the lane, takes only light
units; the others take the rest first and the light units only once nothing else is left. As many
units bound by their CPU run at once as before: one a core. Three workers taking any unit had
filled the cores but put three such units on two cores, slowed the flights beside them and cost
11 % more CPU (docs/suite-time.md, 13:45 and 18:56).

The order of the queue (``work_order``) is kept: each worker takes the first unit of its kind.
"""

from __future__ import annotations

from collections.abc import Callable

from xdist.scheduler import LoadGroupScheduling
from xdist.workermanage import WorkerController


class LaneScheduling(LoadGroupScheduling):
    """xdist's ``loadgroup`` with the last worker (highest ``gw`` number) kept for the units
    ``light`` says are light (it gets each unit's test ids). With fewer than three workers, or no
    light unit, it hands out as ``loadgroup`` does."""

    def __init__(self, config, log, light: Callable[[list[str]], bool]) -> None:
        super().__init__(config, log)
        self._is_light = light
        self.light: set[str] = set()  # the light units' scopes
        self.lane: WorkerController | None = None

    def schedule(self) -> None:
        if self.collection is None and self.collection_is_completed and len(self.nodes) >= 3:
            units: dict[str, list[str]] = {}
            for nodeid in next(iter(self.registered_collections.values())):
                units.setdefault(self._split_scope(nodeid), []).append(nodeid)
            self.light = {scope for scope, ids in units.items() if self._is_light(ids)}
            if self.light:
                self.lane = max(self.nodes, key=lambda n: int(n.gateway.id.lstrip("gw") or 0))
        super().schedule()

    def pick(self, node: WorkerController) -> str | None:
        """The unit ``node`` takes next: the first of its kind in the queue; a worker outside the
        lane takes a light one when no other is left, the lane nothing else."""
        in_lane = node is self.lane
        for scope in self.workqueue:
            if (scope in self.light) == in_lane:
                return scope
        return None if in_lane else next(iter(self.workqueue), None)

    def _assign_work_unit(self, node: WorkerController) -> None:
        scope = self.pick(node)
        if scope is None:
            return
        self.workqueue.move_to_end(scope, last=False)  # xdist's own step takes the first unit
        super()._assign_work_unit(node)

    def _reschedule(self, node: WorkerController) -> None:
        if node is self.lane and not node.shutting_down and self.workqueue and self.pick(node) is None:
            if self._pending_of(self.assigned_work[node]) == 0:
                node.shutdown()  # no light unit left: the other workers finish the rest
            return
        super()._reschedule(node)
