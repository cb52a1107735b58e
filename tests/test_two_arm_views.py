"""What the views show of a two-arm run: the live state and `ita monitor` list both arms'
runs (while they run too), and the 3-D view of the Path Planner's paths draws both arms'
moves, each arm at rest and the second arm's pedestal."""

from __future__ import annotations

import pytest

from archive_synth import fake_specs, record_two_arm_run
from ita.archive import Archive, Result

def test_the_live_view_and_the_monitor_show_both_arms_runs_of_a_two_arm_run(tmp_path) -> None:
    from ita.cli.inspect import monitor_text
    from ita.report.live import live_state

    with Archive.open(tmp_path / "archive.sqlite") as archive:
        runs = record_two_arm_run(archive)
        alone = archive.create_run("bulkhead", total=3)
        state = live_state(archive, runs["t3"])
        assert live_state(archive, alone)["arms"] == []                 # one arm: nothing more
        assert [(a["arm"], a["run"], a["done"], a["total"]) for a in state["arms"]] == [
            ("t3", runs["t3"], 2, 2), ("t3_b", runs["t3_b"], 1, 2)]
        # the same from the other arm's run, and the key changes when the other arm measures
        assert live_state(archive, runs["t3_b"])["arms"] == state["arms"]
        before = state["key"]
        archive.record_result(runs["t3_b"], Result.measured(fake_specs(4)[3], 6.35, 0.002, tool="slra_2"))
        assert live_state(archive, runs["t3"])["key"] != before
    lines = monitor_text(state, columns=400)
    assert any(f"arm t3_b: run {runs['t3_b']}" in line and "1/2" in line for line in lines)


@pytest.mark.parametrize("which", ["t3", "t3_b"])
def test_the_3d_view_of_either_arms_run_draws_both_arms_moves_and_both_arms(tmp_path, builtin_part, which) -> None:
    from ita.report.paths import run_paths_figure
    from ita.report.scene import PartScene

    scene = PartScene.load(builtin_part.directory)
    with Archive.open(tmp_path / "archive.sqlite") as archive:
        runs = record_two_arm_run(archive)
        alone = archive.create_run("bulkhead", total=1)
        archive.record_result(alone, Result.measured(fake_specs(1)[0], 2.5, 0.002, tool="slra_1"),
                              details={"arm_paths": [{"tcp": [[1.0, 0.0, 1.5], [1.1, 0.0, 1.5]], "tool": "slra_1"}]})
        found = run_paths_figure(archive, runs[which], scene)
        one = run_paths_figure(archive, alone, scene)
    assert found is not None and one is not None
    names = [t.get("name") for t in found["figure"]["data"]]
    assert found["moves"] == 3
    assert "t3: slra_1 (2 moves)" in names and "t3_b: slra_2 (1 moves)" in names
    assert "t3 at rest" in names and "t3_b at rest" in names
    cells = sum(1 for n in names if n == "cell")
    one_names = [t.get("name") for t in one["figure"]["data"]]
    assert not any(n and n.endswith("at rest") for n in one_names)      # one arm: its moves alone
    assert cells > sum(1 for n in one_names if n == "cell")              # the second arm's pedestal too
    rest = {t["name"]: t for t in found["figure"]["data"] if t.get("name", "").endswith("at rest")}
    # each arm stands on its own base: the first at the origin, the second where the cell puts it
    base_b = scene.workcell.second_arm.base.position
    assert rest["t3 at rest"]["x"][0] == pytest.approx(0.0, abs=1e-6)
    assert (rest["t3_b at rest"]["x"][0], rest["t3_b at rest"]["y"][0]) == pytest.approx(base_b[:2], abs=1e-6)
