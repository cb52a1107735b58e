"""What the two arms of a two-arm run tell each other of what they share
(ita.toplevel.shared): a tool a diagnosis found broken is broken in the other arm's world
model too; the part registered again reaches the other arm, which measures again what it
made since the part was last known in place; a registration asked for is answered with
one made after the asker saw the part displaced, never with an older one."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from ita.logic.bridge import KnowledgeBase
from ita.logic.world import WorldModel
from ita.task.align import Alignment
from ita.toplevel.shared import SharedCell
from ita.workcell import load_workcell


class Line:
    """Both ends of the conductor's line for one arm: what it told, the news it has heard."""

    def __init__(self) -> None:
        self.told: list[tuple[float, object]] = []
        self.news: list[tuple[float, object]] = []

    def tell(self, t, value) -> None:
        self.told.append((t, value))

    def heard(self):
        out, self.news = self.news, []
        return out

    def unread(self):
        return list(self.news)


@pytest.fixture()
def kb():
    kb = KnowledgeBase()
    WorldModel(kb).reset()
    yield kb
    WorldModel(kb).reset()


def session(kb, registers: bool, now: float = 100.0, alignment=None):
    return SimpleNamespace(kb=kb, peer=Line(), registers=registers, alignment=alignment,
                           clock=SimpleNamespace(now=now))


def alignment(shift: float, seconds: float = 40.0) -> Alignment:
    return Alignment(load_workcell().part, (shift, 0.0, 0.0), 0.0, 0.02, 0.001, {}, (), (), 2, seconds)


def test_a_tool_one_arm_found_broken_is_broken_in_the_other_arms_world_model(kb) -> None:
    first, second = session(kb, True), session(KnowledgeBase(), False)
    SharedCell(first).tell_tools({"us_probe_1": "broken"})
    assert first.peer.told == [(100.0, {"kind": "tools", "conditions": {"us_probe_1": "broken"}})]
    # what the conductor hands the other arm with its next claim
    second.peer.news = [*first.peer.told, (101.0, {"kind": "tools", "conditions": {"no_such_tool": "broken",
                                                                                 "slra_1": "melted"}})]
    heard = SharedCell(second).hear()
    assert heard.tools == (("us_probe_1", "broken"),)                  # an unknown tool or condition: ignored
    world = WorldModel(second.kb)
    assert world.condition("us_probe_1") == "broken" and "us_probe_1" not in world.usable("t3", "us_tool")
    assert world.condition("slra_1") == "ok"
    assert heard.changes_plan                                          # a tool it may take up: plan again
    assert SharedCell(second).hear().anything is False                 # heard once
    # a tool kept for the other arm (its own): said, but this arm's plan stands
    world.set_reserved("slra_1", "t3")
    second.peer.news = [(102.0, {"kind": "tools", "conditions": {"slra_1": "broken"}})]
    heard = SharedCell(second).hear()
    assert heard.tools == (("slra_1", "broken"),) and not heard.changes_plan


def test_the_part_registered_again_reaches_the_other_arm_with_when_it_was_last_in_place(kb, monkeypatch) -> None:
    import ita.toplevel.shared as shared

    adopted = []
    monkeypatch.setattr(shared, "adopt_alignment", lambda s, found: adopted.append(found))
    first, second = session(kb, True, now=220.0), session(kb, False, alignment=alignment(0.02))
    cell = SharedCell(first)
    new = alignment(3.4, seconds=50.0)
    cell.tell_registered(new, good_s=95.0)
    assert cell.registered_from_s == pytest.approx(170.0)               # it began measuring 50 s before
    second.peer.news = list(first.peer.told)
    heard = SharedCell(second).hear()
    assert adopted == [new] and heard.alignment == new and heard.since_s == 95.0
    # the other arm does not register the part: it never tells a registration of its own
    SharedCell(second).tell_registered(new, 0.0)
    assert second.peer.told == []


def test_a_registration_is_asked_of_the_arm_that_registers_and_answered_only_with_a_newer_one(kb) -> None:
    first, second = session(kb, True, now=220.0, alignment=alignment(3.4)), session(kb, False)
    cell = SharedCell(first)
    ask = {"kind": "register", "key": "registration@218.7", "found_s": 123.1}
    first.peer.news = [(218.7, ask)]
    assert cell.hear().asks == (("registration@218.7", 123.1),)
    second.peer.news = [(218.7, ask)]
    assert SharedCell(second).hear().asks == ()                         # only the arm that registers answers
    assert cell.still_good(123.1) is None                               # none told yet: register again
    cell.tell_registered(first.alignment, good_s=0.0)                   # measured from 180 s on
    assert cell.still_good(123.1) is first.alignment                    # began after it was seen displaced
    assert cell.still_good(200.0) is None                               # began before: not good enough
