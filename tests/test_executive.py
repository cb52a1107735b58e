"""The Plan Executive/Monitor: streams, WAIT/CONTINUE, concurrency, time-outs, exceptions."""

from __future__ import annotations

import pytest
from doubles import FakeDevice

from ita.errors import PrologError
from ita.executive import (
    Command,
    ExecutiveError,
    FailureKind,
    LogKind,
    PlanExecutive,
    ReplyKind,
    StreamId,
    Wait,
    plan_commands,
    split,
)
from ita.logic.terms import Term, Var
from ita.planning import (
    OperationPlanner,
    Place,
    PlanStep,
    PoseKind,
    QualitativePose,
    WorldState,
)
from ita.sim.world import SimClock
from ita.specs.model import MeasurementKind, MeasurementSpec

ARM = StreamId("path_planner", "t3")
SLRA = StreamId("vision", "slra_1")
AT_A = QualitativePose(PoseKind.CONTACT, Place.meas("a"))


def meas(i: str) -> Term:
    return Term("meas", (i,))


def spec(mid: str, kind: MeasurementKind) -> MeasurementSpec:
    return MeasurementSpec(mid, kind, "f1", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 2.5, -0.1, 0.1)


@pytest.fixture
def planner(knowledge_base, tmp_path):
    with OperationPlanner(knowledge_base, tmp_path / "macrops" / "part.pl") as p:
        yield p


@pytest.fixture
def figure_4_plan(planner):
    """The Figure 4 plan: ultrasonic measurement b, probe in hand, in contact at a."""
    return planner.plan_measurement(spec("b", MeasurementKind.WEB_THICKNESS),
                                    WorldState(pose=AT_A, holding="us_probe_1"), "us_probe_1")


@pytest.fixture
def slra_plan(planner):
    """retract, move, move_view (arm); slra_scan, slra_measure (vision)."""
    return planner.plan_measurement(spec("b", MeasurementKind.HOLE_DIAMETER),
                                    WorldState(pose=AT_A, holding="slra_1"), "slra_1")


# A hand-made plan where the arm leaves the view pose once the scan is taken, while
# vision measures from the image: WAITs on both streams.
SCAN_AND_LEAVE = (
    PlanStep(1, "move_view", ("t3", "a"), ()),
    PlanStep(2, "slra_scan", ("slra_1", "t3", "a"), (1,)),
    PlanStep(3, "leave_view", ("t3", "a"), (2,)),
    PlanStep(4, "slra_measure", ("slra_1", "t3", "a"), (2,)),
    PlanStep(5, "move", ("t3", meas("a"), meas("b")), (3,)),
)

# Two independent streams: vision measures a's image while the arm moves on to b.
INDEPENDENT = (
    PlanStep(1, "slra_measure", ("slra_1", "t3", "a"), ()),
    PlanStep(2, "move", ("t3", meas("a"), meas("b")), ()),
    PlanStep(3, "move_view", ("t3", "b"), (2,)),
)


def devices(**vision_options):
    arm = FakeDevice(lookahead=True, durations={"MOVE": 2.0, "RETRACT": 1.0, "CONTACT": 1.5})
    vision = FakeDevice(durations={"SCAN": 3.0, "MEASURE": 0.5}, **vision_options)
    return arm, vision


def executive(kb, arm, vision, **options):
    return PlanExecutive(kb, {"path_planner": arm, "vision": vision}, **options)


def events(report, kind):
    return [(e.sim_time, str(e.stream), e.step, e.payload) for e in report.events if e.kind is kind]


# -- commands ------------------------------------------------------------------------


def test_commands_come_from_the_operators_patterns(knowledge_base, figure_4_plan):
    commands = plan_commands(knowledge_base, figure_4_plan.steps)
    measure = commands[-1]
    assert measure.stream == ARM and measure.step == 5
    assert measure.message == Term("MEASURE", (Term("min_value", (meas("b"),)), Term("max_value", (meas("b"),))))
    assert measure.reply == Term("VALUE", (Var("V0"),))
    assert measure.result_of(Term("VALUE", (2.51,))) == Term("dimension", ("b", "us_probe_1", 2.51, 0.0))
    assert measure.result_of(Term("VALUE", (2.51, 0.01))) is None
    assert measure.timeout_s == 30.0


def test_an_action_that_is_no_operator_is_refused(knowledge_base):
    with pytest.raises(PrologError, match="operator"):
        plan_commands(knowledge_base, [PlanStep(1, "fly", ("t3",), ())])


# -- splitting -----------------------------------------------------------------------


def test_figure_4_plan_is_one_arm_stream_without_waits(knowledge_base, figure_4_plan):
    streams = executive(knowledge_base, *devices()).prepare(figure_4_plan)
    assert [s.stream for s in streams.streams] == [ARM]
    assert streams.streams[0].steps == (1, 2, 3, 4, 5)
    assert streams.waits == ()


def test_slra_plan_waits_only_where_a_predecessor_is_on_another_stream(knowledge_base, slra_plan):
    assert [s.action for s in slra_plan.steps] == [
        "move_retract", "move", "move_view", "slra_scan", "slra_measure"]
    streams = executive(knowledge_base, *devices()).prepare(slra_plan)
    assert streams.stream(ARM).items == streams.stream(ARM).commands  # no WAIT on the arm
    vision = streams.stream(SLRA).items
    assert [type(i) for i in vision] == [Wait, Command, Command]
    assert vision[0] == Wait(SLRA, 4, (3,))      # the scan waits for the view pose
    assert [c.step for c in vision[1:]] == [4, 5]  # the measurement follows the scan: same stream


def test_hand_made_plan_gets_waits_on_both_streams(knowledge_base):
    streams = executive(knowledge_base, *devices()).prepare(SCAN_AND_LEAVE)
    arm, vision = streams.stream(ARM).items, streams.stream(SLRA).items
    assert [(type(i).__name__, i.step) for i in arm] == [
        ("Command", 1), ("Wait", 3), ("Command", 3), ("Command", 5)]
    assert arm[1].waits_for == (2,)
    assert [(type(i).__name__, i.step) for i in vision] == [("Wait", 2), ("Command", 2), ("Command", 4)]
    assert vision[0].waits_for == (1,)
    # exactly the commands with a predecessor on another stream have a WAIT
    stream_of = {c.step: c.stream for s in streams.streams for c in s.commands}
    crossing = {s.number for s in SCAN_AND_LEAVE if any(stream_of[p] != stream_of[s.number] for p in s.predecessors)}
    assert {w.step for w in streams.waits} == crossing == {2, 3}


def test_steps_out_of_number_order_are_run_in_their_partial_order(knowledge_base):
    steps = (PlanStep(1, "move_view", ("t3", "a"), (2,)), PlanStep(2, "move", ("t3", "home", meas("a")), ()))
    streams = executive(knowledge_base, *devices()).prepare(steps)
    assert streams.stream(ARM).steps == (2, 1)


def test_a_cyclic_plan_is_refused(knowledge_base):
    steps = (PlanStep(1, "move_view", ("t3", "a"), (2,)), PlanStep(2, "leave_view", ("t3", "a"), (1,)))
    with pytest.raises(ExecutiveError, match="cycle"):
        executive(knowledge_base, *devices()).prepare(steps)


def test_commands_must_match_the_steps(knowledge_base, figure_4_plan):
    commands = plan_commands(knowledge_base, figure_4_plan.steps)
    with pytest.raises(ExecutiveError, match="do not match"):
        split(figure_4_plan.steps, commands[:-1])


# -- running -------------------------------------------------------------------------


def test_figure_4_plan_runs_and_reports_the_thickness(knowledge_base, figure_4_plan):
    arm = FakeDevice(lookahead=True, durations={"MOVE": 2.0, "RETRACT": 1.0}, values={"MEASURE": 2.51})
    report = executive(knowledge_base, arm, FakeDevice()).execute(figure_4_plan)
    assert report.ok and report.failure is None
    assert report.results[-1] == Term("dimension", ("b", "us_probe_1", 2.51, 0.0))
    assert [o.step for o in report.outcomes] == [1, 2, 3, 4, 5]
    assert report.makespan == pytest.approx(1.0 + 2.0 + 1.0 + 1.0 + 1.0)
    assert events(report, LogKind.WAIT) == [] and events(report, LogKind.CONTINUE) == []


def test_continue_is_sent_when_the_predecessor_on_the_other_stream_completes(knowledge_base, slra_plan):
    arm, vision = devices()
    report = executive(knowledge_base, arm, vision).execute(slra_plan)
    assert report.ok
    # arm: retract 0-1, move 1-3, move_view 3-5; the scan waits from 0 and goes on at 5
    assert events(report, LogKind.WAIT) == [(0.0, str(SLRA), 4, (3,))]
    assert events(report, LogKind.CONTINUE) == [(5.0, str(SLRA), 4, (3,))]
    assert vision.started == [(5.0, 4), (8.0, 5)]
    # the measure (8-8.5) is the vision stream's trailing command: the plan holds the arm
    # until the scan's end only, and the measure's reply is its step's
    assert report.makespan == pytest.approx(8.0)
    assert report.outcomes[-1].step == 5 and report.outcomes[-1].finished_s == pytest.approx(8.5)


def test_a_plan_without_overlap_waits_for_every_reply(knowledge_base, slra_plan):
    arm, vision = devices()
    report = executive(knowledge_base, arm, vision, overlap=False).execute(slra_plan)
    assert report.ok and report.makespan == pytest.approx(8.5)


def test_vision_measures_while_the_next_plan_moves_the_arm(knowledge_base, slra_plan):
    """The trailing measure of one plan overlaps the next plan's arm moves; the next scan
    waits for the vision stream to be free as well as for the arm at the view."""
    arm = FakeDevice(lookahead=True, durations={"MOVE": 2.0, "RETRACT": 0.1})
    vision = FakeDevice(durations={"SCAN": 3.0, "MEASURE": 4.0})
    ex = executive(knowledge_base, arm, vision)
    first = ex.execute(slra_plan, start_s=0.0)
    assert first.finished_s == pytest.approx(7.1) and ex.settled() == pytest.approx(11.1)
    second = ex.execute(slra_plan, start_s=first.finished_s)
    # arm: retract 7.1-7.2, moves to 11.2; the scan: the arm is at the view at 11.2, vision free at 11.1
    assert arm.started[3][0] == pytest.approx(7.1)
    assert vision.started[2][0] == pytest.approx(11.2) and second.ok
    slow = FakeDevice(durations={"SCAN": 3.0, "MEASURE": 9.0})
    ex = executive(knowledge_base, FakeDevice(lookahead=True, durations={"MOVE": 2.0, "RETRACT": 0.1}), slow)
    first = ex.execute(slra_plan, start_s=0.0)
    ex.execute(slra_plan, start_s=first.finished_s)
    assert slow.started[2][0] == pytest.approx(16.1)      # waits for the vision stream (7.1 + 9)


def test_a_plan_that_fails_while_another_stream_finishes_the_plan_before_reports_where_each_stood(
        knowledge_base, slra_plan):
    """Vision still measures the first plan's image when the second plan's first arm step
    fails: the failure says where each stream of the second plan stood (vision: nothing of
    it started), and the executive goes on to the next plan."""
    arm = FakeDevice(lookahead=True, durations={"MOVE": 2.0, "RETRACT": 0.1})
    vision = FakeDevice(durations={"SCAN": 3.0, "MEASURE": 9.0})
    ex = executive(knowledge_base, arm, vision)
    first = ex.execute(slra_plan, start_s=0.0)
    assert first.ok and ex.settled() == pytest.approx(16.1)
    arm.exceptions[1] = Term("BUMP", ("link_3", "bulkhead"))
    second = ex.execute(slra_plan, start_s=first.finished_s)
    failure = second.failure
    assert failure is not None and failure.step.number == 1 and failure.at_s == pytest.approx(7.2)
    positions = {p.stream: p for p in failure.streams}
    assert positions[SLRA].running is None and positions[SLRA].done == ()
    assert positions[SLRA].pending == (4, 5) and failure.cancelled == (2, 3, 4, 5)
    assert ex.execute(slra_plan, start_s=second.finished_s).failure is not None   # step 1 still bumps


def test_a_failing_measure_is_no_trailing_command(knowledge_base, slra_plan):
    arm, vision = devices(exceptions={5: Term("VISION", ("out_of_view",))})
    ex = executive(knowledge_base, arm, vision)
    report = ex.execute(slra_plan)
    assert not report.ok and report.failure.at_s == pytest.approx(8.5) and ex.settled() == -float("inf")


def test_waits_on_both_streams_continue_at_the_right_times(knowledge_base):
    arm, vision = devices()
    report = executive(knowledge_base, arm, vision).execute(SCAN_AND_LEAVE)
    assert report.ok
    # move_view 0-2 | scan 2-5 | leave_view 5-7 and measure 5-5.5 together | move 7-9
    assert events(report, LogKind.CONTINUE) == [(2.0, str(SLRA), 2, (1,)), (5.0, str(ARM), 3, (2,))]
    assert arm.started == [(0.0, 1), (5.0, 3), (7.0, 5)]
    assert vision.started == [(2.0, 2), (5.0, 4)]
    assert report.makespan == pytest.approx(9.0)


def test_independent_streams_overlap_in_simulated_time(knowledge_base):
    arm, vision = FakeDevice(lookahead=True, durations={"MOVE": 4.0}), FakeDevice(durations={"MEASURE": 3.0})
    report = executive(knowledge_base, arm, vision).execute(INDEPENDENT)
    assert report.ok
    assert [(t, step) for t, _, step, _ in events(report, LogKind.SEND)] == [(0.0, 1), (0.0, 2), (4.0, 3)]
    assert report.makespan == pytest.approx(8.0)
    assert report.makespan < sum(o.finished_s - o.started_s for o in report.outcomes)


def test_the_arm_stream_receives_all_its_commands_at_plan_start(knowledge_base):
    arm, vision = devices()
    streams = executive(knowledge_base, arm, vision).prepare(SCAN_AND_LEAVE)
    report = executive(knowledge_base, arm, vision).execute(SCAN_AND_LEAVE)
    assert arm.queued == [(0.0, streams.stream(ARM).items)]  # WAIT included: the planner rests there
    assert vision.queued == []                                # vision: one by one
    assert events(report, LogKind.QUEUED) == [(0.0, str(ARM), None, (1, 3, 5))]
    first_send = next(e for e in report.events if e.kind is LogKind.SEND)
    queued = next(e for e in report.events if e.kind is LogKind.QUEUED)
    assert report.events.index(queued) < report.events.index(first_send)


def test_same_seed_same_log(knowledge_base):
    def run(seed):
        arm = FakeDevice(lookahead=True, jitter_s=1.0, seed=seed)
        vision = FakeDevice(jitter_s=1.0, seed=seed + 1)
        return executive(knowledge_base, arm, vision).execute(SCAN_AND_LEAVE).events

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_the_simulated_clock_follows_the_events(knowledge_base, slra_plan):
    clock = SimClock()
    clock.advance(100.0)
    report = executive(knowledge_base, *devices(), clock=clock, overlap=False).execute(slra_plan)
    assert report.started_s == 100.0 and clock.now == pytest.approx(108.5) == report.finished_s


def test_a_qualitative_parameter_is_resolved_by_the_geometric_reasoner_callback(knowledge_base, figure_4_plan):
    class Reasoner:
        def resolve(self, term):
            return ("pose of", term)

    arm = FakeDevice(lookahead=True, resolver=Reasoner())
    executive(knowledge_base, arm, FakeDevice()).execute(figure_4_plan)
    contact = Term("in_contact_point", (meas("b"),))
    assert (4, contact, ("pose of", contact)) in arm.resolved


def test_a_stream_without_a_device_is_refused_before_anything_is_sent(knowledge_base, slra_plan):
    arm = FakeDevice(lookahead=True)
    with pytest.raises(ExecutiveError, match="vision"):
        PlanExecutive(knowledge_base, {"path_planner": arm}).execute(slra_plan)
    assert arm.started == [] and arm.queued == []


# -- time-outs and exceptions -----------------------------------------------------------


def test_a_silent_device_times_out_and_stops_the_plan(knowledge_base, slra_plan):
    arm, vision = devices(silent=[4])
    report = executive(knowledge_base, arm, vision).execute(slra_plan)
    failure = report.failure
    assert not report.ok and failure.kind is FailureKind.TIMEOUT
    assert failure.step == slra_plan.steps[3] and failure.command.step == 4
    assert failure.command.name == "SCAN" and failure.command.stream == SLRA
    assert failure.reply.kind is ReplyKind.TIMEOUT and failure.reply.payload is None
    assert failure.at_s == pytest.approx(5.0 + 60.0)  # sent at the CONTINUE, time-out 60 s
    assert events(report, LogKind.TIMEOUT) == [(65.0, str(SLRA), 4, 60.0)]
    assert failure.completed == (1, 2, 3) and failure.cancelled == (5,)
    assert events(report, LogKind.CANCELLED) == [(65.0, str(SLRA), 5, "not sent")]
    assert "time-out" in failure.reason and "slra_scan(slra_1, t3, b)" in failure.reason
    assert failure.plan is slra_plan and failure.events == report.events
    assert report.events[-1].kind is LogKind.PLAN_STOPPED


def test_a_late_reply_is_a_time_out_at_the_deadline(knowledge_base, figure_4_plan):
    arm = FakeDevice(lookahead=True, durations={5: 45.0})
    report = executive(knowledge_base, arm, FakeDevice(), timeouts={"MEASURE": 40.0}).execute(figure_4_plan)
    assert report.failure.kind is FailureKind.TIMEOUT and report.failure.step.number == 5
    assert report.failure.at_s == pytest.approx(4.0 + 40.0)
    assert [o.step for o in report.outcomes] == [1, 2, 3, 4]


def test_a_wait_for_the_other_arm_s_zones_before_the_device_begins_is_not_timed(knowledge_base, figure_4_plan):
    """45 s from start to reply against a 40 s time-out: a time-out when the device was
    busy all along, a reply when it first waited 10 s for the other arm's zones."""
    late = FakeDevice(lookahead=True, durations={5: 45.0})
    assert executive(knowledge_base, late, FakeDevice(), timeouts={"MEASURE": 40.0}).execute(
        figure_4_plan).failure.kind is FailureKind.TIMEOUT
    held = FakeDevice(lookahead=True, durations={5: 45.0}, held_up={5: 10.0})
    report = executive(knowledge_base, held, FakeDevice(), timeouts={"MEASURE": 40.0}).execute(figure_4_plan)
    assert report.failure is None and 5 in [o.step for o in report.outcomes]


def test_an_exception_reply_stops_the_plan_and_cancels_the_rest(knowledge_base):
    bump = Term("BUMP", ("link_3", "bulkhead"))
    arm = FakeDevice(lookahead=True, durations={"MOVE": 2.0}, exceptions={3: bump})
    vision = FakeDevice(durations={"SCAN": 3.0, "MEASURE": 10.0})
    report = executive(knowledge_base, arm, vision).execute(SCAN_AND_LEAVE)
    failure = report.failure
    assert failure.kind is FailureKind.EXCEPTION and failure.step.number == 3
    assert failure.reply.payload == bump and failure.at_s == pytest.approx(7.0)
    # vision was measuring (5-15): aborted; the arm's last move never sent
    assert events(report, LogKind.CANCELLED) == [
        (7.0, str(ARM), 5, "not sent"), (7.0, str(SLRA), 4, "aborted")]
    assert failure.cancelled == (4, 5) and failure.completed == (1, 2)
    assert arm.stopped == [7.0] and vision.stopped == [7.0]
    positions = {p.stream: p for p in failure.streams}
    assert positions[ARM].running == 3 and positions[ARM].pending == (5,)
    assert positions[SLRA].running == 4 and positions[SLRA].done == (2,)
    assert failure.world == {str(ARM): {"done": (1,)}, str(SLRA): {"done": (2, 4)}}
    assert "BUMP(link_3, bulkhead)" in failure.reason
    assert failure.to_dict()["stream"] == str(ARM)


def test_a_reply_at_the_moment_of_an_exception_still_counts(knowledge_base):
    arm = FakeDevice(lookahead=True, durations={"MOVE": 4.0}, exceptions={2: "JOINT_LIMIT"})
    vision = FakeDevice(durations={"MEASURE": 4.0})
    report = executive(knowledge_base, arm, vision).execute(INDEPENDENT)
    assert report.failure.step.number == 2 and report.failure.at_s == 4.0
    assert report.failure.completed == (1,) and report.failure.cancelled == (3,)
    assert [o.step for o in report.outcomes] == [1]


def test_a_normal_reply_that_does_not_match_the_pattern_is_an_exception(knowledge_base, figure_4_plan):
    arm = FakeDevice(lookahead=True, replies={"MEASURE": Term("VALUE", (2.5, 0.1))})
    report = executive(knowledge_base, arm, FakeDevice()).execute(figure_4_plan)
    assert report.failure.kind is FailureKind.UNEXPECTED_REPLY and report.failure.step.number == 5
    assert "expected VALUE(V0)" in report.failure.reason


def test_the_log_is_plain_values_for_the_archive(knowledge_base, slra_plan):
    import json

    report = executive(knowledge_base, *devices(silent=[5])).execute(slra_plan)
    text = json.dumps([e.to_dict() for e in report.events] + [report.failure.to_dict()])
    assert "SCAN(patches(meas(b)))" in text and '"kind": "timeout"' in text
