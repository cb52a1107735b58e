"""The person's stream: someone called to the cell, a device like the arm and the SLRA.

    person = PersonDevice(SimPerson(world), world.clock)    # person(technician)
    PlanExecutive(kb, {"path_planner": arm, "vision": slra, "person": person}, clock=world.clock)

What the cell cannot do itself (an obstacle taken out, the part re-clamped, a tool
replaced from the stores, a probe straightened in its holder) is an operator of
kb/operators.pl on the stream ``command_stream(person, Person)``: the Operation Planner
plans it like any other step and the Plan Executive sends it here as ``CALL(Job)``; the
reply ``DONE`` comes when the job is done, and the run waits for it (a person is told the
whole job list at once: ``lookahead``, so no job of theirs is left running behind a plan).

Each job is answered by the person given (``jobs``: the job's name -> a callable taking
the job's arguments and returning a line for the reply); in simulation
:class:`ita.sim.person.SimPerson`, whose jobs take their time on the world's clock and
change the simulated world.  A new job is one entry here (and one operator).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Protocol

from ita.devices.arm import exception_reply
from ita.executive.adapters import Completion
from ita.executive.commands import Command, Reply, Wait
from ita.logic.json_value import JsonValue
from ita.logic.terms import Term

__all__ = ["Clock", "Job", "PersonDevice", "Person", "person_jobs"]

#: a job: its arguments (atoms as text) -> a line for the reply
Job = Callable[..., str]


class Clock(Protocol):
    """The simulated clock the jobs advance (ita.sim.world.SimClock)."""

    @property
    def now(self) -> float: ...


class Person(Protocol):
    """Whoever answers for the person called (ita.sim.person.SimPerson in simulation)."""

    def remove_obstacles(self) -> str: ...

    def reclamp_part(self) -> str: ...

    def replace_tool(self, tool: str) -> str: ...

    def straighten_probe(self, tool: str) -> str: ...


def person_jobs(person: Person) -> dict[str, Job]:
    """The jobs of the person operators of kb/operators.pl, by the name in ``CALL(Job)``."""
    return {"remove_obstacles": person.remove_obstacles, "reclamp_part": person.reclamp_part,
            "replace_tool": person.replace_tool, "straighten_probe": person.straighten_probe}


class PersonDevice:
    """The person's stream (see the module docstring): ``jobs`` by name, and the `clock`
    they take their time on."""

    lookahead = True

    def __init__(self, jobs: Person | Mapping[str, Job], clock: Clock) -> None:
        self.jobs: dict[str, Job] = dict(jobs) if isinstance(jobs, Mapping) else person_jobs(jobs)
        self.clock = clock
        self.done: list[str] = []          # the jobs done, in order (their reply lines)

    # -- the protocol ------------------------------------------------------------------
    def begin(self, items: Sequence[Command | Wait], now: float) -> None:
        pass

    def start(self, command: Command, now: float) -> Completion:
        job = command.args[0] if command.name == "CALL" and command.args else None
        name, args = (job.name, job.args) if isinstance(job, Term) else (str(job), ())
        answer = self.jobs.get(name) if job is not None else None
        if answer is None:
            return Completion(now, exception_reply("UNSUPPORTED", f"a person cannot {command.text}",
                                                   command.name.lower()))
        line = answer(*(str(a) for a in args))
        self.done.append(line)
        return Completion(max(self.clock.now, now), Reply.normal("DONE", line))

    def stop(self, now: float) -> None:
        pass

    def snapshot(self) -> Mapping[str, JsonValue]:
        return {"jobs_done": len(self.done)}
