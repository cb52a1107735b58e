"""The fault injector says only what it does: targets it cannot hit are refused, and a
scripted fault that cannot land on a command waits for one where it can."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from ita.errors import InputError
from ita.sim.faults import Fault, FaultSet
from ita.sim.inject import FaultInjector, InjectionPlan

PROBES, SLRAS = ["us_probe_1", "us_probe_2"], ["slra_1", "slra_2"]


def test_targets_the_simulator_cannot_hit_are_refused_with_the_valid_pairs():
    InjectionPlan.parse(0.0, None, ["broken_probe@us_probe_2", "dirty_window@slra_1", "transient@controller",
                                    "worn_probe", "obstacle@box_1", "slra_failed@slra_2"]).check_targets(PROBES, SLRAS)
    for text in ("broken_probe@slra_1", "transient@gauge", "dirty_window@us_probe_1", "broken_probe@no_such_tool",
                 "slra_failed@us_probe_1"):
        with pytest.raises(InputError) as err:
            InjectionPlan.parse(0.0, None, [text]).check_targets(PROBES, SLRAS)
        message = str(err.value)
        assert "--inject" in message and "cannot inject" in message and "dirty_window@slra_1|slra_2" in message


def _world(held: str | None) -> SimpleNamespace:
    tool = None if held is None else SimpleNamespace(tool_class=SimpleNamespace(ultrasonic=held.startswith("us_"),
                                                                                value="us_tool"))
    return SimpleNamespace(clock=SimpleNamespace(now=10.0), held=held, held_tool=tool, faults=FaultSet())


def test_a_scripted_fault_waits_for_a_command_it_can_land_on(tmp_path):
    log = tmp_path / "faults.jsonl"
    world = _world(None)              # nothing in hand: a probe's fault without a target has no probe to hit
    injector = FaultInjector(world, InjectionPlan.parse(0.0, None, ["worn_probe:after=5"]), log)
    move = SimpleNamespace(name="MOVE", text="MOVE(a, b)")
    injector.before(move, "arm")
    assert not world.faults.has(Fault.WORN_PROBE, "us_probe_1") and not log.exists()
    world.held, world.held_tool = "us_probe_1", _world("us_probe_1").held_tool
    injector.before(SimpleNamespace(name="MEASURE", text="MEASURE(x)"), "arm")
    assert world.faults.has(Fault.WORN_PROBE, "us_probe_1")
    assert [json.loads(line)["target"] for line in log.read_text().splitlines()] == ["us_probe_1"]
