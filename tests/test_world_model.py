"""The world model's facade (ita/logic/world.py): the cell's tools, conditions,
locations and arm as typed answers, and changes that the rules see."""

from __future__ import annotations

import pytest

from ita.logic.bridge import KnowledgeBase
from ita.logic.world import ToolLocation, WorldModel


@pytest.fixture()
def world():
    model = WorldModel(KnowledgeBase())
    model.reset()
    yield model
    model.reset()


def test_the_cell_as_built(world):
    assert set(world.tools()) == {"us_probe_1", "us_probe_2", "us_probe_90", "slra_1", "slra_2"}
    assert world.the_arm() == "t3"
    assert world.tool_type("us_probe_90") == "us_bent" and world.is_a("us_probe_90", "us_tool")
    assert world.condition("slra_2") == "ok" and world.available("slra_2")
    assert world.location("slra_1") == ToolLocation("in_rack", "slot_3")
    assert world.holding() is None
    assert world.usable("t3", "us_tool") == ("us_probe_1", "us_probe_2")


def test_changes_reach_the_rules_and_reset_forgets_them(world):
    world.set_condition("us_probe_1", "broken")
    world.set_location("us_probe_2", ToolLocation("missing"))
    assert world.usable("t3", "us_tool") == ()
    assert world.missing("us_probe_2") and not world.available("us_probe_1")
    world.set_location("slra_1", ToolLocation("on_arm", "t3"))
    assert world.holding() == ("t3", "slra_1")
    world.reset()
    assert world.usable("t3", "us_tool") == ("us_probe_1", "us_probe_2") and world.holding() is None


def test_a_bad_condition_is_refused_before_prolog(world):
    with pytest.raises(ValueError, match="not a tool condition"):
        world.set_condition("us_probe_1", "rusty")  # type: ignore[arg-type]
