"""What the run takes once more before it ends: a measurement left not done after a fault
it then put right, never one whose diagnosis left it beyond the cell's reach (decided from
the diagnosis recorded in the archive, not from the words of a result's reason)."""

from __future__ import annotations

from ita.toplevel.loop import _beyond_the_cell


def test_a_measurement_beyond_the_cells_reach_is_not_taken_again() -> None:
    assert _beyond_the_cell({"exception": "no_echo", "cause": "broken_probe(us_probe_1)", "actions": []})
    assert _beyond_the_cell({"exception": "view_not_measurable", "cause": None, "actions": []})
    # put right (a repair), or not isolated (a second try may find the cell well): taken again
    assert not _beyond_the_cell({"exception": "no_echo", "cause": "broken_probe(us_probe_1)",
                                 "actions": ["achieve(tool_swapped(us_probe_1))"]})
    assert not _beyond_the_cell({"exception": "too_few_pixels", "cause": None, "actions": []})
