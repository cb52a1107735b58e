"""Results the Top Level holds PENDING until it can decide them, and their settling.

    pending = PendingDecisions.resume(session, archive, run_id, todo, results, network=True)
    if not pending.hold(spec_id, value, tool, t0, t1, events, attached):   # held: nothing to record yet
        results.record(...)
    pending.settle()                      # after each measurement: decide what can be decided
    pending.settle(final=True)            # at a completed run's end: decide everything left

Two kinds (the decisions themselves are :mod:`ita.toplevel.network` and
:mod:`ita.toplevel.heights`):

- a fastener hole's position (the run's setting ``network``): held for its face's network
  (:class:`HeldPositions`), decided with the others when the last of them has been
  measured or given up;
- a flange or rib height referenced to webs whose thickness the run still has to measure
  (:class:`HeldHeights`), decided with their measured thickness when the last of them is
  done.

A held result's events (its plan's, and the pending value as a ``network_frame`` or
``height_web`` event), details and range frames go to the archive at once, in one
transaction: a run killed meanwhile loses none of them, and `ita continue` reads the
pending values back from their events (:meth:`PendingDecisions.resume`) and does not
measure them again.  Each result is recorded once, when it is decided.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ita.archive import Event, Result
from ita.devices.data import MeasuredValue
from ita.toplevel.events import network_event
from ita.toplevel.heights import EVENT_KIND as HEIGHT_EVENT
from ita.toplevel.heights import HEIGHT_KINDS, HeightPending, decide_height, web_specs
from ita.toplevel.network import EVENT_KIND as NETWORK_EVENT
from ita.toplevel.network import Pending, decide, network_key
from ita.toplevel.recording import NOTHING_ATTACHED, Attached, Recorder, why_uncertain

if TYPE_CHECKING:
    from ita.archive import Archive
    from ita.task.session import Session

__all__ = ["HeldHeights", "HeldPositions", "PendingDecisions"]

#: the archive event that puts measurements back in the plan; its ``released`` names the
#: held ones let go (a continued run does not hold them again)
REMEASURE_EVENT = "remeasure"


def _taken_at(t0: float | None, t1: float | None) -> float:
    """When a held result was measured (its end, else its start; unknown: the run's start)."""
    return t1 if t1 is not None else (t0 if t0 is not None else 0.0)


def _released(event: Event) -> set[str]:
    return {str(i) for i in event.payload.get("released") or []} if event.kind == REMEASURE_EVENT else set()


class HeldPositions:
    """Fastener hole positions held for their face's network (:mod:`ita.toplevel.network`).

    networks: network key -> the run's specs it decides (empty with the network off);
    pending: spec id -> its measured frame's sightings, waiting."""

    def __init__(self, session: Session, archive: Archive, run_id: str, results: Recorder,
                 networks: dict[str, set[str]], pending: dict[str, Pending]) -> None:
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.results = results
        self.networks = networks
        self.pending = pending
        self.kept: dict[str, Attached] = {}      # a pending result's details and frames (this process)

    @classmethod
    def resume(cls, session: Session, archive: Archive, run_id: str, results: Recorder, todo: Sequence[str], *,
               network: bool) -> HeldPositions:
        """The networks of the run's specs `todo` and the positions the archive holds
        pending for them (none: the network is off)."""
        networks: dict[str, set[str]] = {}
        pending: dict[str, Pending] = {}
        if network:
            features, specs = session.slra.vctx.features, session.specs
            for spec_id in todo:
                key = network_key(specs[spec_id], features) if spec_id in specs else None
                if key is not None:
                    networks.setdefault(key, set()).add(spec_id)
            for event in archive.events(run_id, kinds=[NETWORK_EVENT, REMEASURE_EVENT]):
                for i in _released(event):          # let go after it was held: measured again
                    pending.pop(i, None)
                if event.kind != NETWORK_EVENT:
                    continue
                p = Pending.from_event(event)
                if p.spec_id not in results.done:
                    pending[p.spec_id] = p
        return cls(session, archive, run_id, results, networks, pending)

    def hold(self, spec_id: str, value: MeasuredValue, tool: str | None, t0: float | None, t1: float | None,
             events: Sequence[Event], attached: Attached) -> bool:
        """Keep a measured position pending for its network (its sightings, the plan's
        `events` and what is attached to the archive now, in one transaction); False when
        the network does not decide it."""
        if not any(spec_id in members for members in self.networks.values()):
            return False
        p = Pending.from_value(spec_id, value, tool, t0, t1)
        if p is None:
            return False
        self.archive.record_pending(self.run_id, spec_id, [*events, p.to_event()], details=attached.details,
                                    frames=attached.frames)
        self.pending[spec_id] = p
        self.kept[spec_id] = attached
        return True

    def release(self, since_s: float) -> list[str]:
        """Let go of the positions held whose frames were taken at `since_s` or later (the
        arm or the part found off since): their spec ids, to measure again."""
        gone = [i for i, p in self.pending.items() if _taken_at(p.t0, p.t1) >= since_s]
        for i in gone:
            self.pending.pop(i)
            self.kept.pop(i, None)
        return gone

    def solve(self, *, final: bool = False) -> None:
        """Decide every network whose members are all measured or given up (final: every
        network with a pending member) and record its results."""
        ctx = self.session.slra.vctx
        done = self.results.done
        for key, members in self.networks.items():
            waiting = [self.pending[i] for i in sorted(members) if i in self.pending]
            if not waiting or (not final and any(i not in done and i not in self.pending for i in members)):
                continue
            try:
                a = self.session.alignment
                decided, solution = decide(waiting, self.session.specs, ctx.features,
                                           ctx.pose_sigma_m / ctx.placement.scale,
                                           None if a is None else a.u_at)
            except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:   # never lose the frames
                for p in waiting:
                    self.pending.pop(p.spec_id, None)
                    self.results.record(Result.measured(
                        self.session.specs[p.spec_id], p.frame_value, p.frame_u, tool=p.tool, sim_time_start=p.t0,
                        sim_time_end=p.t1, reason=f"from its own frame: the network was not solved ({exc})"),
                        [], self.kept.pop(p.spec_id, NOTHING_ATTACHED))
                continue
            self.archive.record_event(self.run_id, network_event(key, solution, self.session.clock.now))
            for r in decided:
                self.pending.pop(r.spec_id, None)
                self.results.record(r, [], self.kept.pop(r.spec_id, NOTHING_ATTACHED))


class HeldHeights:
    """Flange and rib heights held for their webs' measured thickness
    (:mod:`ita.toplevel.heights`).  pending: spec id -> the height waiting; todo: the
    run's specs (their web thickness specs stand for the floors)."""

    def __init__(self, session: Session, archive: Archive, run_id: str, results: Recorder, todo: set[str],
                 pending: dict[str, HeightPending]) -> None:
        self.session = session
        self.archive = archive
        self.run_id = run_id
        self.results = results
        self.todo = todo
        self.pending = pending
        self.kept: dict[str, Attached] = {}      # a pending result's details and frames (this process)
        self._floors: dict[str, tuple[str, ...]] | None = None

    @classmethod
    def resume(cls, session: Session, archive: Archive, run_id: str, results: Recorder, todo: set[str]
               ) -> HeldHeights:
        """The heights the archive holds pending for the run."""
        pending: dict[str, HeightPending] = {}
        for event in archive.events(run_id, kinds=[HEIGHT_EVENT, REMEASURE_EVENT]):
            for i in _released(event):
                pending.pop(i, None)
            if event.kind != HEIGHT_EVENT:
                continue
            h = HeightPending.from_event(event)
            if h.spec_id not in results.done:
                pending[h.spec_id] = h
        return cls(session, archive, run_id, results, todo, pending)

    def floors(self) -> dict[str, tuple[str, ...]]:
        """Floor region -> the run's web thickness specs that measure it (made once)."""
        if self._floors is None:
            self._floors = web_specs([s for s in self.session.ctx.specs if s.id in self.todo],
                                     self.session.slra.vctx)
        return self._floors

    def hold(self, spec_id: str, value: MeasuredValue, tool: str | None, t0: float | None, t1: float | None,
             events: Sequence[Event], attached: Attached, *, why: str = "") -> bool:
        """A height referenced to webs whose thickness the run measures: decided now when
        those are all done, else kept pending (its `events` and what is attached to the
        archive now); False when it is no such height.  why: how it was measured, when not
        in its own frame."""
        if self.session.specs[spec_id].kind not in HEIGHT_KINDS:
            return False
        p = HeightPending.from_value(spec_id, value, tool, t0, t1, self.floors(), self.session.slra.vctx)
        if p is None:
            return False
        if why:
            p = replace(p, why=why)
        if any(s not in self.results.done for s in p.waits_for):
            self.archive.record_pending(self.run_id, spec_id, [*events, p.to_event()], details=attached.details,
                                        frames=attached.frames)
            self.pending[spec_id] = p
            self.kept[spec_id] = attached
            return True
        self.results.record(self._decided(p), events, attached)
        return True

    def release(self, since_s: float) -> list[str]:
        """Let go of the heights held that were measured at `since_s` or later: their spec
        ids, to measure again."""
        gone = [i for i, p in self.pending.items() if _taken_at(p.t0, p.t1) >= since_s]
        for i in gone:
            self.pending.pop(i)
            self.kept.pop(i, None)
        return gone

    def settle(self, *, final: bool = False) -> None:
        """Decide the pending heights whose webs' thicknesses are all done (final: every
        one; a web whose thickness was not measured keeps its nominal)."""
        for spec_id, p in list(self.pending.items()):
            if final or all(s in self.results.done for s in p.waits_for):
                self.pending.pop(spec_id)
                self.results.record(self._decided(p), [], self.kept.pop(spec_id, NOTHING_ATTACHED))

    def _decided(self, p: HeightPending) -> Result:
        measured: dict[str, tuple[float, float]] = {}
        for sid in p.waits_for:
            r = self.archive.result(self.run_id, sid)
            if r is not None and r.value is not None and r.u is not None:
                measured[sid] = (float(r.value), float(r.u))
        specs = self.session.specs
        return why_uncertain(decide_height(p, specs[p.spec_id], measured, {k: specs[k].point for k in p.waits_for},
                                           self.session.slra.vctx.web_tolerance), None)


class PendingDecisions:
    """The run's results held pending: hole positions for their networks, heights for
    their webs (module docstring)."""

    def __init__(self, positions: HeldPositions, heights: HeldHeights) -> None:
        self.positions = positions
        self.heights = heights

    @classmethod
    def resume(cls, session: Session, archive: Archive, run_id: str, todo: Sequence[str], results: Recorder, *,
               network: bool) -> PendingDecisions:
        """What run `run_id` holds pending in the archive (nothing for a new run)."""
        return cls(HeldPositions.resume(session, archive, run_id, results, todo, network=network),
                   HeldHeights.resume(session, archive, run_id, results, set(todo)))

    def waiting(self, spec_id: str) -> bool:
        """Whether the spec's result waits: for its network, or for its webs' thicknesses."""
        return spec_id in self.positions.pending or spec_id in self.heights.pending

    def hold(self, spec_id: str, value: MeasuredValue, tool: str | None, t0: float | None, t1: float | None,
             events: Sequence[Event], attached: Attached, *, why: str = "") -> bool:
        """Hold a measured value whose result waits (recorded at once when a height's webs
        are all done already); False when it is recorded as it is.  why: how it was
        measured, when not in its own frame."""
        return (self.positions.hold(spec_id, value, tool, t0, t1, events, attached)
                or self.heights.hold(spec_id, value, tool, t0, t1, events, attached, why=why))

    def release(self, since_s: float) -> list[str]:
        """Let go of what is held that was measured at `since_s` or later (the arm or the
        part found off since then: ita.toplevel.loop's remeasuring); their spec ids."""
        return self.positions.release(since_s) + self.heights.release(since_s)

    def settle(self, *, final: bool = False) -> None:
        """Decide what can be decided (final: everything held)."""
        self.positions.solve(final=final)
        self.heights.settle(final=final)
