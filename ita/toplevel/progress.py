"""What a run shows while it goes (:class:`Progress`) and how it ended (:class:`RunSummary`).

    started = Started(wall_s=time.perf_counter(), sim_s=clock.now, done=len(done))
    show(progress(run_id, started, done=12, total=40, step=step, status="measuring", sim_s=clock.now,
                  exceptions=1, counts={"conforms": 11, "not_done": 1}))
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ita.archive.exceptions import ExceptionCounts
from ita.logic.json_value import JsonObject

if TYPE_CHECKING:
    from ita.sequence.next_step import Step

__all__ = ["Progress", "RunSummary", "Started", "progress"]


@dataclass(frozen=True)
class Progress:
    """What the live view shows after each measurement."""

    run_id: str
    done: int
    total: int
    group: int | None
    tool: str | None
    spec_id: str | None
    status: str
    sim_s: float
    wall_s: float
    eta_wall_s: float | None
    eta_sim_s: float | None
    exceptions: int
    counts: dict[str, int]


@dataclass(frozen=True)
class Started:
    """Where this process took the run up: the wall clock (time.perf_counter), the
    simulated time, and how many results the run had."""

    wall_s: float
    sim_s: float
    done: int


def progress(run_id: str, started: Started, *, done: int, total: int, step: Step | None, status: str,
             sim_s: float, exceptions: int, counts: Mapping[str, int]) -> Progress:
    """The run's progress now: `done` of `total` results, the step measured last (None:
    none yet), the time to go at the pace of this process (None: nothing done yet)."""
    wall = time.perf_counter() - started.wall_s
    made = done - started.done
    left = total - done
    eta_wall = wall / made * left if made else None
    eta_sim = (sim_s - started.sim_s) / made * left if made else None
    return Progress(run_id, done, total, step.group if step else None, step.tool if step else None,
                    step.spec_id if step else None, status, sim_s, wall, eta_wall, eta_sim, exceptions, dict(counts))


@dataclass(frozen=True)
class RunSummary:
    """How a run (or this part of a continued run) ended."""

    run_id: str
    status: str
    done: int
    total: int
    counts: dict[str, int]
    sim_start_s: float
    sim_end_s: float
    wall_s: float
    measured_now: int
    exceptions: ExceptionCounts
    frames: int
    breakdown: dict[str, float] = field(default_factory=dict)
    devices: dict[str, float] = field(default_factory=dict)
    continue_hint: str | None = None
    alarm: str = ""             # why the Top Level stopped the run itself (failures in a row)
    cell: JsonObject | None = None   # a cell check's report (the job cell_check)
    planner: dict[str, float] = field(default_factory=dict)   # the HTN plan's figures (plan_s, replans, ...)
    alignment: JsonObject | None = None   # where the part was registered (ita.task.align), last

    @property
    def cycle_s(self) -> float:
        return self.sim_end_s - self.sim_start_s

    def to_dict(self) -> JsonObject:
        unmeasured = self.counts.get("not_done", 0) + self.counts.get("cannot_be_done", 0)
        return {"run_id": self.run_id, "status": self.status, "done": self.done, "total": self.total,
                "measured": self.done - unmeasured,
                "counts": dict(self.counts), "simulated_cycle_s": round(self.sim_end_s, 3),
                "simulated_this_session_s": round(self.cycle_s, 3), "wall_s": round(self.wall_s, 3),
                "wall_s_per_measurement": round(self.wall_s / self.measured_now, 4) if self.measured_now else None,
                "recorded_now": self.measured_now, "exceptions": self.exceptions.total,
                "exception_counts": self.exceptions.to_dict(), "slra_scans": self.frames,
                "breakdown_s": {k: round(v, 2) for k, v in self.breakdown.items()},
                "devices": {k: round(v, 3) for k, v in self.devices.items()},
                "continue": self.continue_hint, "alarm": self.alarm or None,
                "planner": {k: round(v, 4) for k, v in self.planner.items()},
                "alignment": self.alignment,
                **({"cell": self.cell} if self.cell is not None else {})}
