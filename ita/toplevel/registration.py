"""The Top Level registers the part on its datums before it measures it (kb/tasks.pl:
``register_part`` opens the jobs that measure the part), and records every registration,
its own or a recovery's (a part found displaced is registered again, ita.diagnosis), as
an ``alignment`` event: the report and the QIF export state it from there.

    reg = PartRegistration(session, archive, run_id, plans)
    state = reg.register(state)          # the SLRA fetched if need be; an alignment event
    reg.note_change(before, "recovery")  # after a handler: an event when it registered again
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ita.archive import Event
from ita.devices.injection import paused
from ita.logic.json_value import JsonObject
from ita.logic.world import WorldModel
from ita.task.align import AlignDone, Alignment, adopt_alignment, register_part
from ita.toplevel.events import PlanNumbers, plan_events

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.planning.state import WorldState
    from ita.task.session import Session

__all__ = ["PartRegistration", "alignment_payload"]


def alignment_payload(done: AlignDone | None, alignment: Alignment | None, why: str) -> JsonObject:
    """An ``alignment`` event's payload."""
    if alignment is None:
        return {"registered": False, "why": why, "reason": done.reason if done is not None else ""}
    return {"why": why, **alignment.to_dict()}


class PartRegistration:
    """The run's registrations (module docstring)."""

    def __init__(self, session: Session, archive: Archive, run_id: str, plans: PlanNumbers) -> None:
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.plans = plans
        #: the last registration's event payload (None: none made in this process)
        self.last: JsonObject | None = None

    def register(self, state: WorldState) -> WorldState:
        """Register the part with a working SLRA (its first look and measuring steps, no
        new fault injected meanwhile); the arm's state after."""
        s = self.session
        if s.alignment is not None:
            # an earlier run of this session registered the part (one arm of a two-arm
            # run, now measuring what the other left): it has not moved since, or the
            # Exception Handler would have registered it again
            self.last = alignment_payload(None, s.alignment, "this session's registration, made before this run")
            self.archive.record_event(self.run_id, Event("alignment", "top", s.clock.now, self.last))
            return state
        if s.peer is not None and not s.registers:
            return self._taken(state)
        state, done = self._register_now(state, "the run's start")
        if s.peer is not None:                 # the other arm measures in this registration too
            s.peer.post(s.clock.now, "alignment", done.alignment if done is not None else None)
        return state

    def again(self, state: WorldState, why: str) -> tuple[WorldState, Alignment | None]:
        """Register the part once more (the other arm of a two-arm run found it displaced
        and asks for it); the arm's state after and the registration (None: not made)."""
        state, done = self._register_now(state, why)
        return state, done.alignment if done is not None else None

    def _register_now(self, state: WorldState, why: str) -> tuple[WorldState, AlignDone | None]:
        s = self.session
        tool = WorldModel(s.kb).registering_slra(state.arm, s.held)
        if tool is None:
            self.last = alignment_payload(None, None, why) | {
                "reason": "no working slra_tool to register the part with: measured at its nominal placement"}
            self.archive.record_event(self.run_id, Event("alignment", "top", s.clock.now, self.last))
            return state, None
        with paused(s.arm.injector):
            done = register_part(s, state, tool)
        for out in done.outcomes:
            if out.plan is not None and out.report is not None:
                self.archive.record_events(self.run_id, plan_events(out.plan, out.report, None, "registration",
                                                                    self.plans.next(), tool=out.tool))
        if done.alignment is not None:
            s.alignment = done.alignment
        self.last = alignment_payload(done, done.alignment, why)
        self.archive.record_event(self.run_id, Event("alignment", "top", s.clock.now, self.last))
        return done.state, done

    def _taken(self, state: WorldState) -> WorldState:
        """The other arm's registration of the part (a two-arm run): waited for in simulated
        time until it was made, then measured in; the nominal placement if it made none."""
        s = self.session
        assert s.peer is not None
        s.arm.controller.give_way()                # folded while it waits: the other arm may need where it stands
        wait, found = s.peer.take(s.clock.now, "alignment")
        s.clock.advance(wait)
        if isinstance(found, Alignment):
            adopt_alignment(s, found)
            self.last = alignment_payload(None, found, "the other arm's registration") | {"waited_s": round(wait, 3)}
        else:
            self.last = alignment_payload(None, None, "the run's start") | {
                "reason": "the other arm made no registration: measured at the nominal placement"}
        self.archive.record_event(self.run_id, Event("alignment", "top", s.clock.now, self.last))
        return state

    def note_change(self, before: Alignment | None, why: str) -> None:
        """An ``alignment`` event when the session's registration is no longer `before`
        (the Exception Handler registered the part again)."""
        now = self.session.alignment
        if now is not None and now is not before:
            self.archive.record_event(self.run_id, Event("alignment", "top", self.session.clock.now,
                                                         alignment_payload(None, now, why)))
