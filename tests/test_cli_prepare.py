"""`ita prepare`: the offline main job."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.cli import main


def test_prepare_builds_and_checks_everything(builtin_part) -> None:
    result = CliRunner().invoke(main, ["prepare", "--json", "--quiet"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["ok"] and report["part"]["spec_count"] == 1076
    assert report["reach"] == {"reachable": 1076}
    assert report["knowledge_bases"]["problems"] == []
    assert {"world.pl", "operators.pl", "planner.pl"} <= set(report["knowledge_bases"]["files"])
    # the inspection is prepared: sequence plan, MKB, MACROPs; what cannot be done, and why
    prep = report["inspection"]
    assert Path(prep["plan"]["path"]).is_file() and Path(prep["mkb"]["path"]).is_file()
    assert sum(prep["plan"]["groups"].values()) == 1076
    assert 0 < prep["mkb"]["frames"] < prep["mkb"]["slra_specs"]
    assert prep["macrops"]["planned"] + prep["cannot_be_done"]["count"] == 1076
    assert all(c["reason"] for c in prep["cannot_be_done"]["specs"])
    again = json.loads(CliRunner().invoke(main, ["prepare", "--json", "--quiet"]).stdout)["inspection"]
    assert not again["plan"]["rebuilt"] and not again["mkb"]["rebuilt"]            # stored, current: reused
    assert again["macrops"]["hits"] == again["macrops"]["lookups"]                 # the store is warm


@pytest.mark.slow       # about 20 s: the plan and the MKB made again
def test_two_prepares_make_the_same_sequence_plan(builtin_part) -> None:
    """The ordering is bounded by work with a fixed seed: a plan made again (here, at any
    load, on any machine) orders every measurement the same."""
    def made(*force: str) -> dict:
        result = CliRunner().invoke(main, ["prepare", "--json", "--quiet", *force])
        assert result.exit_code == 0, result.output
        report = json.loads(result.stdout)["inspection"]
        assert report["plan"]["rebuilt"] or not force
        return json.loads(Path(report["plan"]["path"]).read_text())

    first = made()                  # the stored plan (made now, or by an earlier test)
    second = made("--force")        # made again
    assert [g["order"] for g in first["groups"]] == [g["order"] for g in second["groups"]]
    assert sum(len(g["order"]) for g in first["groups"]) == 1076


def test_prepare_rejects_a_part_with_bad_specs(builtin_part, tmp_path: Path) -> None:
    part = tmp_path / "p"
    assert CliRunner().invoke(main, ["part", "build", "-o", str(part)]).exit_code == 0
    specs = part / "specs.csv"
    specs.write_text(specs.read_text().replace("web_thickness", "web_thicknes", 1))
    result = CliRunner().invoke(main, ["prepare", "--part", str(part), "--quiet"])
    assert result.exit_code == 2
    assert f"{specs}:2 [kind]: unknown kind 'web_thicknes'" in result.stderr


def test_an_arm_the_cell_does_not_have_is_named_with_the_cells_arms(builtin_part) -> None:
    for command in (["prepare", "--quiet"], ["inspect", "--limit", "1"]):
        result = CliRunner().invoke(main, [*command, "--arm", "t9"])
        assert result.exit_code == 2, result.output
        assert "[arm]: the workcell has no arm 't9' (its arms: t3, t3_b)" in result.stderr


@pytest.mark.slow       # about 100 s: the second arm's plan, MKB and MACROPs made, then a short run
def test_the_second_arm_prepares_and_inspects_alone_without_touching_the_first_arms_plan(builtin_part) -> None:
    def prepared(*arm: str) -> dict:
        result = CliRunner().invoke(main, ["prepare", "--json", "--quiet", *arm])
        assert result.exit_code == 0, result.output
        return json.loads(result.stdout)["inspection"]

    first = prepared()
    before = Path(first["plan"]["path"]).read_bytes()
    second = prepared("--arm", "t3_b")
    assert second["plan"]["path"] != first["plan"]["path"] and "t3_b" in Path(second["plan"]["path"]).name
    done_by_b = sum(second["plan"]["groups"].values())
    # the second arm, at the part's left end, reaches part of it; what it cannot do is said
    assert 0 < done_by_b < 1076
    assert done_by_b + second["cannot_be_done"]["count"] == 1076
    assert Path(first["plan"]["path"]).read_bytes() == before          # the first arm's plan untouched
    result = CliRunner().invoke(main, ["inspect", "--arm", "t3_b", "--limit", "3", "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout[result.stdout.index("{"):])
    assert summary["measured"] >= 1
    from ita.archive import Archive, archive_path

    with Archive.open(archive_path(None), create=False) as archive:
        run = archive.run(archive.resolve("last"))
        assert run.settings["arm"] == "t3_b"        # `ita continue` works the run with the same arm


@pytest.mark.slow       # about 3 min: both arms' plans and MKBs, the allocation, the coordination, the 3-D check
def test_sequence_allocate_splits_by_what_each_arms_mkb_places_and_the_arms_never_touch(builtin_part) -> None:
    result = CliRunner().invoke(main, ["sequence", "allocate", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    counts = {a["arm"]: a["measurements"] for a in report["arms"]}
    assert set(counts) == {"t3", "t3_b"} and min(counts.values()) > 100
    assert sum(counts.values()) + len(report["unassigned"]) <= 1076
    coordinated = report["coordinated"]
    assert coordinated["arm_arm_contacts"] == 0 and coordinated["moments"] > 1000
    assert report["makespan_s"] <= coordinated["makespan_s"] < report["one_arm_s"]


@pytest.mark.slow       # about 2.5 min: both arms prepared, then a two-arm run of 420 measurements
def test_two_arms_inspect_at_once_each_its_share_with_its_own_tools_and_never_touch(builtin_part) -> None:
    result = CliRunner().invoke(main, ["inspect", "--arms", "2", "--limit", "420", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["arm_arm_contacts"] == 0 and report["contact_check"]["moments"] > 1000
    assert report["total"] == 420 and report["measured"] == 420
    per_arm = report["per_arm"]
    assert set(per_arm) == {"t3", "t3_b"} and all(p["measured"] > 0 for p in per_arm.values())
    assert all(p["refused"] == 0 or p["refusals"] for p in per_arm.values())     # a refusal says why
    from ita.archive import Archive, archive_path

    with Archive.open(archive_path(), create=False) as archive:
        tools = {arm: {r.tool for r in archive.results(p["run_id"])} for arm, p in per_arm.items()}
        second = archive.events(per_arm["t3_b"]["run_id"])
        settings = {arm: archive.run(p["run_id"]).settings for arm, p in per_arm.items()}
        events = {arm: archive.events(p["run_id"]) for arm, p in per_arm.items()}
    for arm in per_arm:
        # each arm works its share in the order of the allocation's tours (arranged for both)
        order = [i for _t, ids, _c in settings[arm]["two_arms"]["tours"] for i in ids]
        pos = {i: k for k, i in enumerate(order)}
        began = list(dict.fromkeys(e.payload["spec"] for e in events[arm] if e.kind == "plan_start"
                                   and e.payload.get("spec") and not e.payload.get("purpose")))
        assert began and set(began) <= set(pos)
        assert [pos[i] for i in began[:60]] == sorted(pos[i] for i in began[:60])
        # each probe reads the calibration block once (the second arm before the registration)
        read = [e.payload["probe"] for e in events[arm] if e.kind == "calibration" and e.payload["ok"]]
        assert len(read) == len(set(read))
    taken = [e.payload for e in second if e.kind == "alignment"]
    aligned_at = [e.sim_time for e in second if e.kind == "alignment"]
    ready_at = [e.sim_time for e in second
                if e.kind == "calibration" or (e.kind == "plan_start" and e.payload.get("purpose") == "the first tool")]
    # while the first arm registers the part, the second gets its first tool ready
    assert ready_at and aligned_at and ready_at[0] < aligned_at[0]
    # each arm its own tools: the second never takes the first's, nor the first the second's
    assert not tools["t3"] & tools["t3_b"]
    # the second arm measures in the first arm's registration of the part
    assert taken and taken[0]["why"] == "the other arm's registration" and "shift_mm" in taken[0]
    # either arm's report draws both arms' streams and zone claims on one time axis
    from ita.report.data import collect, summarize
    from ita.report.sections import SECTIONS, Context

    with Archive.open(archive_path(), create=False) as archive:
        data = collect(archive, per_arm["t3_b"]["run_id"])
    assert [arm for arm, _r, _e in data.group] == ["t3", "t3_b"]
    section = dict(SECTIONS)["two_arms"](data, Context(summarize(data)))
    assert section is not None
    lanes = {y for trace in section["figure"]["data"] for y in trace["y"] if y}
    assert {"t3 arm", "t3 zones", "t3_b arm", "t3_b zones"} <= lanes


@pytest.mark.slow       # about 2 min: both arms prepared, then a two-arm run of 420 measurements, one arm down
def test_an_arm_down_for_good_hands_what_it_left_to_the_other_arm_and_they_never_touch(builtin_part) -> None:
    """The second arm's controller fails for good: its run stops on its alarm, a person
    moves it by hand out of the way (once the conductor grants the space), and the first
    arm makes its own share and everything the downed arm left; the arms never touch."""
    result = CliRunner().invoke(main, ["inspect", "--arms", "2", "--limit", "420", "--json",
                                       "--inject", "t3_b:controller_failed:after=150"])
    report = json.loads(result.stdout)
    assert report["arm_arm_contacts"] == 0 and report["contact_check"]["moments"] > 1000
    down, up = report["per_arm"]["t3_b"], report["per_arm"]["t3"]
    assert down["status"] == "stopped" and down["measured"] < down["total"]     # its controller failed: the alarm
    assert up["status"] == "completed" and up["handed_over"] > 50                 # what it left, to the other arm
    assert report["measured"] == down["measured"] + up["measured"] + up["handover"]["measured"]
    from ita.archive import Archive, archive_path

    with Archive.open(archive_path(), create=False) as archive:
        faults = [e.payload for e in archive.events(down["run_id"], kinds=["diagnosis"])]
        moved = [e.payload["update"] for e in archive.events(down["run_id"], kinds=["world_update"])]
        left = [r for run in (up["run_id"], up["handover"]["run_id"]) for r in archive.results(run)
                if r.outcome.value != "measured"]
        again = [e.payload for e in archive.events(up["handover"]["run_id"], kinds=["alignment"])]
    # the hand-over run measures in the registration its arm made before (no second one)
    assert [a["why"] for a in again] == ["this session's registration, made before this run"]
    assert any(d.get("cause") == "controller_not_answering" for d in faults)
    assert any("a person moved the arm" in m for m in moved)
    # everything the fault-free run makes is made; what is not would say the other arm kept
    # it (its Path Planner keeping clear of where that arm stands, or the zones)
    assert all("the other arm" in (r.reason or "") for r in left)
    assert report["measured"] == 420 - len(left)
    assert (result.exit_code, report["status"]) == ((0, "completed") if not left else (3, "not finished"))


@pytest.mark.slow       # about 2 min: both arms prepared, then a two-arm run of 420 measurements, the part knocked
def test_a_part_knocked_under_both_arms_is_registered_again_once_and_both_measure_in_it(builtin_part) -> None:
    """The part knocked off its place while both arms work (each arm's simulator holds a
    copy of the one part, knocked alike): the first arm's diagnosis registers it again and
    that reaches the second arm, which measures in it, and measures again what it made
    since the part may have moved; the second arm, finding it displaced too, asks the first
    for a registration instead of calling a person (it cannot see datum C), and takes the
    one just made.  Every measurement made, none accepted falsely, the arms never touch."""
    result = CliRunner().invoke(main, ["inspect", "--arms", "2", "--limit", "420", "--json",
                                       "--inject", "part_displaced:after=100"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["arm_arm_contacts"] == 0 and report["measured"] == report["total"] == 420
    from ita.archive import Archive, archive_path
    from ita.scoring.compare import compare
    from ita.scoring.truth import true_values

    runs = {arm: p["run_id"] for arm, p in report["per_arm"].items()}
    with Archive.open(archive_path(), create=False) as archive:
        aligned = {arm: [e.payload for e in archive.events(rid, kinds=["alignment"])] for arm, rid in runs.items()}
        diagnosed = {arm: [e.payload for e in archive.events(rid, kinds=["diagnosis"])
                           if e.payload.get("cause") == "part_displaced"] for arm, rid in runs.items()}
        again = [e.payload for e in archive.events(runs["t3_b"], kinds=["remeasure"])]
        results = [r for rid in runs.values() for r in archive.results(rid)]
    knocks = [json.loads(line) for rid in runs.values()
              for line in (archive_path().parent / "faults" / f"{rid}.jsonl").read_text().splitlines()]
    assert sorted(k["fault"] for k in knocks if "fault" in k) == ["part_displaced", "part_displaced"]
    first = [a for a in aligned["t3"] if a.get("registered", True)]
    whys = [a["why"] for a in first]
    assert whys[:2] == ["the run's start", "a recovery: the part found displaced"]
    # asked by the second arm, the first registers again only when its own new registration
    # began before the second saw the part displaced (else it answers with that one)
    assert whys[2:] in ([], ["the other arm found the part displaced"])
    assert first[1]["shift_mm"][0] > 1.0                             # millimetres off: found, not guessed
    # the second arm measures in the first arm's registrations, the newest at the end
    placements = [a["placement"] for a in aligned["t3_b"] if "placement" in a]
    assert placements[0] == first[0]["placement"] and placements[-1] == first[-1]["placement"]
    assert "the other arm registered the part again" in aligned["t3_b"][-1]["why"]
    assert any("when the other arm last found the part in place" in r.get("why", "") for r in again)
    # finding it displaced itself, it asked the first arm rather than call a person to re-clamp
    assert all("reclamp" not in " ".join(d["updates"]) for d in diagnosed["t3_b"])
    assert all("registered again by the other arm" in d["updates"][0] for d in diagnosed["t3_b"])
    scored = compare(results, true_values(builtin_part.directory))
    assert not scored.false_accepts
