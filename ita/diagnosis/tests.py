"""The Exception Handler's tests, run for real in the simulated cell.

    bench = TestBench(session, neighbours=lambda spec_id: [...])
    cost = bench.cost("read_cal_block", situation)      # seconds with the set-up, or None
    run = bench.run("read_cal_block", situation)        # TestRun: outcome, plan, report, times

Each test of kb/faults.pl is a small plan of operators planned by the Operation Planner
from the arm's state (so a test that needs the probe at the calibration block moves
there, and changes tools first when the arm holds the SLRA) and run by the Plan
Executive on the devices; its outcome is read from the replies:

    read_cal_block            goal calibrated(Probe): ok | doubled | no_echo | no_couplant | garbage | misaligned | silent
    check_couplant_station    goal couplant_checked(couplant_station): ok | empty | silent
    query_controller          goal controller_checked(Arm): ok | silent
    scan_cal_block            goal calibrated(Slra): ok | too_few_pixels | garbage | silent
    clean_and_scan_cal_block  window_clean(Slra), then calibrated(Slra): the same outcomes
    rescan_second_standoff    goal rescanned(Slra, meas(Id)): ok | fails_again | silent
    retry_reading             the measurement once more (its round trip): ok | fails_again | silent
    measure_reference_feature a tooling hole's diameter (REFERENCE_FRAMES frames averaged), its centre against
                              the reference reading of the run (`baseline`; DRIFT_MM), else its nominal place
                              (DISPLACED_MM): ok | displaced | unclear
    recalibrate_and_measure_reference  goal arm_calibrated(Arm) (the arm touched off on the
                              block: a drift gone), then measure_reference_feature
    compare_neighbours        no motion: the reading against its neighbours' readings: ok | outlier

A test whose own move runs into something has the outcome ``bump`` (an obstacle
against the stopped arm: kb/faults.pl's obstacle_at_arm).

A test that cannot be made (no plan, a path that fails, a precondition the cell cannot
meet) has the outcome ``not_run`` and rules nothing out.  The cost of a test is its own
seconds (kb/faults.pl) plus the set-up its preconditions need from the arm's state: a
tool change (ita.sequence.cost.rack_seconds) and the joint-space move to the test's place.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ita.devices.data import MeasuredValue
from ita.devices.stations import CAL_STEP_MM
from ita.diagnosis.classify import classify_reply
from ita.kinematics import move_time
from ita.logic.json_value import JsonObject
from ita.logic.terms import Term, TermValue
from ita.logic.world import WorldModel
from ita.part.model import Hole, HoleRole
from ita.planning.state import WorldState
from ita.sequence.cost import rack_seconds
from ita.specs.model import Tool, is_ultrasonic
from ita.task.measure import MeasureOutcome, MeasureStatus, execute_goals, measure_one
from ita.vision.context import VisionResult

if TYPE_CHECKING:
    from ita.executive import ExecutionFailure, ExecutionReport
    from ita.planning import OperationPlan
    from ita.task.session import Session

__all__ = ["Situation", "TestBench", "TestRun"]

#: the tests made with an SLRA at a station
_SLRA_TESTS = ("scan_cal_block", "clean_and_scan_cal_block")
#: a calibration-block reading within this share of the block's thickness is good
CAL_TOLERANCE = 0.02
#: a tooling hole whose centre is further than this (mm) from nominal is displaced
DISPLACED_MM = 1.0
#: a tooling hole whose centre is further than this (mm) from where the run's reference
#: reading saw it has moved (against the arm): the frames' mean centre scatters 0.04 mm per
#: axis (the arm's repeatability / 3 over REFERENCE_FRAMES approaches), so the difference of
#: two readings stays within 0.22 mm 999 times in 1000
DRIFT_MM = 0.25
#: frames of the reference feature averaged for its centre, each after its own approach
REFERENCE_FRAMES = 4
#: a reading further than this many tolerances from its neighbours' median is an outlier
OUTLIER_TOLERANCES = 4.0


@dataclass(frozen=True)
class Situation:
    """Where a diagnosis stands: the measurement that failed (`spec_id`, its `tool` of
    `tool_class`), the exception, the failed reading if there was one, and the arm's
    state now."""

    spec_id: str
    tool: str
    tool_class: str
    exception: str
    state: WorldState
    reading: MeasuredValue | None = None
    device: str = ""            # what failed: gauge, an SLRA unit, controller (classify's context)


@dataclass(frozen=True, eq=False)
class TestRun:
    """A test made: its outcome, its estimated and real cost, its plan and execution,
    the arm's state after, and a measurement it made on the way (a retry that worked)."""

    test: str
    outcome: str
    estimated_s: float
    t0: float
    t1: float
    state: WorldState
    plan: OperationPlan | None = None
    report: ExecutionReport | None = None
    note: str = ""
    measured: MeasureOutcome | None = None
    posterior: tuple[tuple[str, float], ...] = ()   # over the causes when the test was chosen (its node)

    @property
    def seconds(self) -> float:
        return self.t1 - self.t0

    def to_dict(self) -> JsonObject:
        return {"test": self.test, "outcome": self.outcome, "estimated_s": round(self.estimated_s, 2),
                "seconds": round(self.seconds, 2), "note": self.note,
                "posterior": [[c, round(p, 4)] for c, p in self.posterior],
                "plan": [s.text for s in self.plan.steps] if self.plan is not None else []}


def _bumped(report: ExecutionReport | None) -> bool:
    """Whether a test's plan stopped on a BUMP of its own motion."""
    if report is None or report.failure is None:
        return False
    payload = report.failure.reply.payload
    return isinstance(payload, Term) and payload.name == "BUMP"


def _timed_out(failure: ExecutionFailure) -> bool:
    """Whether a failed step is the controller not answering (a time-out, a TIMEOUT reply,
    or a device's reply that its motion timed out, REAPPROACH(timeout))."""
    payload = failure.reply.payload
    name = payload.name if isinstance(payload, Term) else str(payload)
    return failure.kind.value == "timeout" or name == "TIMEOUT" or (
        isinstance(payload, Term) and bool(payload.args) and str(payload.args[0]) == "timeout")


def _gauge_outcome(payload: TermValue | None) -> str:
    exc = classify_reply("exception", payload)
    return {"no_echo": "no_echo", "no_couplant_film": "no_couplant", "doubled_thickness": "doubled",
            "corrupt_reply": "garbage", "misaligned": "misaligned", "no_contact": "misaligned",
            "implausible_thickness": "garbage"}.get(exc or "", "not_run")


def _failed_on(device: str, situation: Situation) -> bool:
    """Whether the situation's measurement failed on `device` (``gauge``, ``slra``)."""
    if not situation.device:
        return True                 # not known: the tool class decides
    if device == "slra":
        return situation.device not in ("gauge", "controller")
    return situation.device == device


class TestBench:
    """Runs the tests of kb/faults.pl on a session's cell (see the module docstring).

    neighbours: spec id -> the values already measured of its neighbours (same kind,
    nearest first), for compare_neighbours."""

    def __init__(self, session: Session, neighbours: Callable[[str], Sequence[float]] | None = None,
                 seconds: dict[str, float] | None = None, needs: dict[str, tuple[str, ...]] | None = None) -> None:
        self.session = session
        self.neighbours = neighbours or (lambda _id: ())
        self.seconds = seconds or {}
        self.needs = needs or {}
        self.reference_spec = self._reference_spec()
        #: tooling hole B's centre (part frame, mm) as the run's reference reading saw it
        self.baseline: tuple[float, float] | None = None

    # -- which tests apply, and what they cost ------------------------------------------------
    def _reference_spec(self) -> str | None:
        features = {f.id: f for f in self.session.part.features}
        for spec in self.session.ctx.specs:
            f = features.get(spec.feature)
            if spec.kind.value == "hole_diameter" and isinstance(f, Hole) and f.role is HoleRole.TOOLING:
                return spec.id
        return None

    def _tool_of(self, tool_class: str, situation: Situation) -> str | None:
        """The tool of `tool_class` a test uses: the measurement's own when it is of that
        class or a kind of it (the bent probe for ``us_tool``: the same gauge), else the
        first usable one (world:usable/3)."""
        if situation.tool_class == tool_class or (tool_class == Tool.ULTRASONIC.value
                                                  and is_ultrasonic(situation.tool_class)):
            return situation.tool
        usable = WorldModel(self.session.kb).usable(situation.state.arm, tool_class)
        return usable[0] if usable else None

    def slra_for(self, situation: Situation) -> str | None:
        """The SLRA a registration of the part takes (the one in hand, else a usable one)."""
        return self._tool_of("slra_tool", situation)

    def applicable(self, test: str, situation: Situation) -> bool:
        """Whether `test` can be made for this situation at all."""
        for need in self.needs.get(test, ()):
            if need.startswith("failed_reading(") and not _failed_on(need[len("failed_reading("):-1], situation):
                return False
            if need.startswith("failed_") and not situation.spec_id:   # a check's finding: no measurement failed
                return False
        if not situation.spec_id and test in ("retry_reading", "rescan_second_standoff", "compare_neighbours"):
            return False
        if test == "retry_reading":
            return is_ultrasonic(situation.tool_class)
        if test == "rescan_second_standoff":
            return situation.tool_class == "slra_tool"
        if test == "compare_neighbours":
            return situation.reading is not None and situation.reading.source is not None \
                and len(self.neighbours(situation.spec_id)) >= 2
        if test == "read_cal_block":
            return self._tool_of("us_tool", situation) is not None
        if test in ("scan_cal_block", "clean_and_scan_cal_block"):
            return self._tool_of("slra_tool", situation) is not None
        if test in ("measure_reference_feature", "recalibrate_and_measure_reference"):
            return self.reference_spec is not None and self._tool_of("slra_tool", situation) is not None
        return test in ("check_couplant_station", "query_controller")

    def cost(self, test: str, situation: Situation) -> float | None:
        """The test's seconds with its set-up from the arm's state now, or None when it
        does not apply."""
        if not self.applicable(test, situation):
            return None
        base = self.seconds.get(test, 5.0)
        need_class = {"read_cal_block": "us_tool", "retry_reading": "us_tool", "scan_cal_block": "slra_tool",
                      "clean_and_scan_cal_block": "slra_tool", "rescan_second_standoff": "slra_tool",
                      "measure_reference_feature": "slra_tool",
                      "recalibrate_and_measure_reference": "slra_tool"}.get(test)
        places = {"read_cal_block": ("cal_block",), "scan_cal_block": ("cal_block",),
                  "recalibrate_and_measure_reference": ("cal_block",),
                  "clean_and_scan_cal_block": ("couplant_station", "cal_block"),
                  "check_couplant_station": ("couplant_station",)}.get(test, ())
        held = self.session.held
        setup = 0.0
        tool = held
        if need_class is not None:
            tool = self._tool_of(need_class, situation)
            if tool != held:
                setup += rack_seconds(self.session.ctx.workcell, held, tool) + 2 * self._move_to_rack(held or tool)
        for place in places:
            setup += self._move_s(place, tool)
        return base + setup

    def _move_to_rack(self, tool: str | None) -> float:
        if tool is None:
            return 0.0
        slot = self.session.ctx.workcell.slot_of(tool).name
        q = self.session.mkb.rack.get(slot)
        return 0.0 if q is None else float(move_time(self.session.arm_model, self.session.joints, q))

    def _move_s(self, place: str, tool: str | None) -> float:
        try:
            q = self.session.reasoner.station(place, tool).q
        except KeyError:
            return math.inf
        return 2.0 * float(move_time(self.session.arm_model, self.session.joints, q))

    # -- running ----------------------------------------------------------------------------
    def run(self, test: str, situation: Situation, estimated_s: float = 0.0) -> TestRun:
        """Make `test` in the cell now; its outcome (see the module docstring)."""
        clock = self.session.clock
        t0 = clock.now
        if test == "compare_neighbours":
            return self._compare(situation, estimated_s, t0)
        if test in ("retry_reading", "measure_reference_feature"):
            return self._measure_again(test, situation, estimated_s, t0)
        if test == "recalibrate_and_measure_reference":
            plan, report, state, note = self.execute_goals([Term("arm_calibrated", (situation.state.arm,))],
                                                           situation.state, name=test)
            if report is None or report.failure is not None:
                outcome = "not_run" if report is None else self._outcome(test, report)
                return TestRun(test, outcome, estimated_s, t0, clock.now, state, plan, report,
                               note or ("" if report is None or report.failure is None else report.failure.reason))
            return self._measure_again(test, replace(situation, state=state), estimated_s, t0)
        arm = situation.state.arm
        slra = self._tool_of("slra_tool", situation) if test in _SLRA_TESTS else None
        goals = {
            "read_cal_block": lambda: [Term("calibrated", (self._tool_of("us_tool", situation),))],
            "check_couplant_station": lambda: [Term("couplant_checked", ("couplant_station",))],
            "query_controller": lambda: [Term("controller_checked", (arm,))],
            "scan_cal_block": lambda: [Term("calibrated", (slra,))],
            "clean_and_scan_cal_block": lambda: [Term("window_clean", (slra,)), Term("calibrated", (slra,))],
            "rescan_second_standoff": lambda: [Term("rescanned", (situation.tool, Term("meas", (situation.spec_id,))))],
        }.get(test)
        if goals is None:
            return TestRun(test, "not_run", estimated_s, t0, t0, situation.state, note="not a test of this cell")
        state = situation.state
        if test == "clean_and_scan_cal_block":      # the window wiped first, then the block scanned
            *first, last = goals()
            plan, report, state, note = self.execute_goals(first, state, name=test)
            if report is None or report.failure is not None:
                outcome = "not_run" if report is None else self._outcome(test, report)
                return TestRun(test, outcome, estimated_s, t0, clock.now, state, plan, report,
                               note or ("" if report is None or report.failure is None else report.failure.reason))
            plan, report, state, note = self.execute_goals([last], state, name=test)
        else:
            plan, report, state, note = self.execute_goals(goals(), state, name=test)
        outcome = "not_run" if report is None else self._outcome(test, report)
        return TestRun(test, outcome, estimated_s, t0, clock.now, state, plan, report,
                       note or ("" if report is None or report.failure is None else report.failure.reason))

    def execute_goals(self, goals: Sequence[TermValue], state: WorldState, *, name: str = ""
                      ) -> tuple[OperationPlan | None, ExecutionReport | None, WorldState, str]:
        """Plan `goals` from `state` and run the plan (ita.task.measure.execute_goals)."""
        return execute_goals(self.session, goals, state, name=name)

    def _outcome(self, test: str, report: ExecutionReport) -> str:
        if report.failure is not None:
            failure = report.failure
            payload = failure.reply.payload
            name = payload.name if isinstance(payload, Term) else str(payload)
            if _timed_out(failure):
                return "silent"
            if name == "BUMP":                   # the test's own move ran into something
                return "bump"
            if test == "read_cal_block" and name == "GAUGE" and failure.command.name == "CALIBRATE":
                return _gauge_outcome(payload)
            if test in ("scan_cal_block", "clean_and_scan_cal_block") and name == "VISION" \
                    and failure.command.name == "CALIBRATE":
                assert isinstance(payload, Term)  # VISION(Reason)
                return "too_few_pixels" if payload.args and payload.args[0] == "too_few_pixels" else "garbage"
            if test == "rescan_second_standoff" and failure.command.name == "RESCAN":
                return "fails_again"
            return "not_run"                     # the test's own moves failed: nothing learnt
        last = report.outcomes[-1]
        payload = last.reply.payload
        if test == "read_cal_block":
            assert isinstance(payload, Term)  # the block's reading: VALUE(V)
            value = float(payload.args[0])
            block = CAL_STEP_MM
            if abs(value - block) <= CAL_TOLERANCE * block:
                return "ok"
            if abs(value - 2 * block) <= 2 * CAL_TOLERANCE * block:
                return "doubled"
            return "garbage"
        if test == "check_couplant_station":
            assert isinstance(payload, Term)  # the station's level: LEVEL(Percent)
            return "empty" if float(payload.args[0]) < 5.0 else "ok"
        return "ok"

    def _measure_again(self, test: str, situation: Situation, estimated_s: float, t0: float) -> TestRun:
        s = self.session
        spec_id: str | None
        tool: str | None
        if test == "retry_reading":
            spec_id, tool = situation.spec_id, situation.tool
        else:
            spec_id, tool = self.reference_spec, self._tool_of("slra_tool", situation)
        if spec_id is None or tool is None:
            return TestRun(test, "not_run", estimated_s, t0, t0, situation.state, note="no tool or feature for it")
        if test == "retry_reading":
            out = measure_one(s, spec_id, situation.state, tool)
        else:
            out = self.reference_reading(spec_id, situation.state, tool)
        silent = out.report is not None and out.report.failure is not None and _timed_out(out.report.failure)
        if silent:
            return TestRun(test, "silent", estimated_s, t0, out.t1, out.state, out.plan, out.report, out.reason or "")
        if _bumped(out.report):
            return TestRun(test, "bump", estimated_s, t0, out.t1, out.state, out.plan, out.report, out.reason or "")
        if test == "retry_reading":
            if out.status is MeasureStatus.MEASURED:
                outcome = "ok"
            elif out.report is not None and out.report.failure is not None \
                    and out.report.failure.command.name in ("MEASURE", "COUPLANT"):
                outcome = "fails_again"
            else:
                outcome = "not_run"
            return TestRun(test, outcome, estimated_s, t0, out.t1, out.state, out.plan, out.report,
                           out.reason or "", out if outcome == "ok" else None)
        outcome, note = self.reference_outcome(out)
        return TestRun(test, outcome, estimated_s, t0, out.t1, out.state, out.plan, out.report,
                       "; ".join(x for x in (out.reason or "", note) if x))

    def reference_reading(self, spec_id: str, state: WorldState, tool: str) -> MeasureOutcome:
        """The reference feature measured from REFERENCE_FRAMES frames, each after its own
        approach (asked of the SLRA for this reading only)."""
        with self.session.slra.frames_for_reading(spec_id, REFERENCE_FRAMES):
            return measure_one(self.session, spec_id, state, tool)

    def reference_centre(self, out: MeasureOutcome) -> tuple[float, float] | None:
        """The reference feature's centre (part frame, mm) in a measurement of it."""
        if out.status is not MeasureStatus.MEASURED or out.value is None \
                or not isinstance(out.value.source, VisionResult):
            return None
        centre = out.value.source.diagnostics.get("center")
        return None if centre is None else (float(centre[0]), float(centre[1]))

    def reference_outcome(self, out: MeasureOutcome) -> tuple[str, str]:
        """(outcome, note) of a reading of the reference feature: ``displaced`` when its
        centre moved by more than DRIFT_MM from the run's reference reading (`baseline`),
        or, without one, lies more than DISPLACED_MM from its nominal place; ``unclear``
        when it was not measured."""
        centre = self.reference_centre(out)
        if centre is None:
            displaced = out.value is not None and "out_of_view" in (out.reason or "")
            return ("displaced" if displaced else "unclear"), ""
        c = np.asarray(centre, dtype=np.float64)
        if self.baseline is not None:
            off = float(np.linalg.norm(c - np.asarray(self.baseline, dtype=np.float64)))
            return ("displaced" if off > DRIFT_MM else "ok"), f"centre {off:.3f} mm from the reference reading"
        spec = self.session.specs[out.spec_id]
        off = float(np.linalg.norm(c - np.asarray(spec.point[:2], dtype=float)))
        return ("displaced" if off > DISPLACED_MM else "ok"), f"centre {off:.3f} mm from its nominal place"

    def _compare(self, situation: Situation, estimated_s: float, t0: float) -> TestRun:
        clock = self.session.clock
        clock.advance(self.seconds.get("compare_neighbours", 0.1))
        values = list(self.neighbours(situation.spec_id))
        reading = situation.reading
        spec = self.session.specs[situation.spec_id]
        raw = getattr(reading.source, "thickness_mm", None) if reading is not None else None
        if raw is None or len(values) < 2:
            return TestRun("compare_neighbours", "not_run", estimated_s, t0, clock.now, situation.state,
                           note="no reading or no neighbours")
        tolerance = max(abs(spec.upper), abs(spec.lower))
        median = statistics.median(values)
        outcome = "outlier" if abs(raw - median) > OUTLIER_TOLERANCES * tolerance else "ok"
        return TestRun("compare_neighbours", outcome, estimated_s, t0, clock.now, situation.state,
                       note=f"reading {raw:.3f}, neighbours' median {median:.3f} ({len(values)})")
