"""SPC across serials (ita/spc, ita spc): capability, the rules, the false-alarm control."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from ita.cli import main
from ita.spc import Series, benjamini_hochberg, chart, chart_all

SERIALS = tuple(f"SN-{i:02d}" for i in range(10))


def test_capability_and_the_individuals_chart():
    x = (10.00, 10.02, 9.98, 10.01, 9.99, 10.00, 10.03, 9.97, 10.01, 9.99)
    c = chart(Series("D-1", "hole_diameter", 9.9, 10.1, SERIALS, x))
    sd = float(np.std(x, ddof=1))
    assert math.isclose(c.sd, sd) and math.isclose(c.cp, 0.2 / (6 * sd))
    assert math.isclose(c.cpk, min(10.1 - c.mean, c.mean - 9.9) / (3 * sd))
    low, high = c.cpk_ci
    assert low < c.cpk < high and high - low > 0.5 * c.cpk          # ten serials: a wide interval
    mr = np.abs(np.diff(x)).mean()
    assert math.isclose(c.ucl, c.mean + 3 * mr / 1.128) and math.isclose(c.mr_ucl, 3.267 * mr)
    one_sided = chart(Series("P-1", "hole_position", None, 0.5, SERIALS, tuple(abs(v - 10) for v in x)))
    assert one_sided.cp is None and one_sided.cpk is not None


def test_benjamini_hochberg_matches_the_textbook_example():
    p = [0.01, 0.04, 0.03, 0.005]
    assert np.allclose(benjamini_hochberg(p), [0.02, 0.04, 0.04, 0.02])


def test_a_step_in_the_later_serials_is_flagged_among_in_control_characteristics():
    rng = np.random.default_rng(1)
    series = [Series(f"C{j}", "web_thickness", -6.0, 6.0, SERIALS, tuple(rng.normal(0, 1, 10))) for j in range(300)]
    shifted = list(rng.normal(0, 1, 10))
    shifted[-3:] = [v + 12 for v in shifted[-3:]]
    series.append(Series("SHIFTED", "web_thickness", -6.0, 6.0, SERIALS, tuple(shifted)))
    charts = chart_all(series, q=0.05)
    flagged = [c for c in charts if c.flags]
    assert [c.series.id for c in flagged] == ["SHIFTED"]
    assert flagged[0].flags[0].rule == "step" and flagged[0].flags[0].serials == SERIALS[-3:]


def test_in_control_serials_are_rarely_flagged_where_3_sigma_flags_most():
    rng = np.random.default_rng(7)
    flagged = beyond = 0
    trials = 20
    for _ in range(trials):
        series = [Series(f"C{j}", "k", -6.0, 6.0, SERIALS, tuple(rng.normal(0, 1, 10))) for j in range(500)]
        charts = chart_all(series, q=0.05)
        flagged += any(c.flags for c in charts)
        beyond += any(c.beyond_3_sigma for c in charts)
    assert flagged <= 3 and beyond >= trials - 2


@pytest.fixture()
def serial_runs(tmp_path, builtin_part):
    """Ten serials' runs of 40 web thicknesses (results written straight to the archive), the
    first stepped by 0.3 mm in the last three serials, and a run without a serial."""
    from ita.archive import Archive, Result, archive_path
    from ita.specs.io import read_specs

    specs = [s for s in read_specs(builtin_part.specs_path) if s.kind.value == "web_thickness"][:40]
    rng = np.random.default_rng(3)
    runs = tmp_path / "runs"
    with Archive.open(archive_path(runs)) as archive:
        for i, sn in enumerate(SERIALS):
            rid = archive.create_run(builtin_part.name, builtin_part.directory, seed=0, total=len(specs),
                                     settings={"serial": sn})
            for s in specs:
                v = s.nominal + rng.normal(0, 0.02) + (0.3 if s is specs[0] and i >= 7 else 0.0)
                archive.record_result(rid, Result.measured(s, v, 0.002))
        other = archive.create_run(builtin_part.name, builtin_part.directory, seed=0, total=1)   # no serial
        archive.record_result(other, Result.measured(specs[1], 99.0, 0.002))
    return runs, specs


def test_ita_spc_charts_the_serials_of_a_design(serial_runs, tmp_path):
    """The JSON has one entry per characteristic with n, mean, sd, cp, cpk and the flags; a
    characteristic stepped in the last serials is flagged there, and nothing else."""
    runs, specs = serial_runs
    out = CliRunner().invoke(main, ["spc", "--runs-dir", str(runs), "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert data["serials"] == list(SERIALS)
    entries = {c["id"]: c for c in data["characteristics"]}
    assert set(entries) == {s.id for s in specs}
    assert all({"id", "n", "mean", "sd", "cp", "cpk", "flags"} <= set(c) for c in entries.values())
    assert entries[specs[1].id]["n"] == 10 and abs(entries[specs[1].id]["mean"] - specs[1].nominal) < 0.05
    assert [c for c in entries if entries[c]["flags"]] == [specs[0].id]
    assert entries[specs[0].id]["flags"][0]["serials"] == list(SERIALS[7:])
    text = CliRunner().invoke(main, ["spc", "--runs-dir", str(runs)])
    assert text.exit_code == 0 and "10 serials" in text.output and "step at SN-07,SN-08,SN-09" in text.output
    none = CliRunner().invoke(main, ["spc", "--runs-dir", str(tmp_path / "empty")])
    assert none.exit_code == 2 and none.output.startswith("error:")


def test_the_system_monitor_has_an_spc_page(serial_runs):
    from starlette.testclient import TestClient

    from ita.web.app import create_app

    runs, specs = serial_runs
    client = TestClient(create_app(runs), base_url="http://127.0.0.1:8765")
    page = client.get("/spc")
    assert page.status_code == 200 and "ITAWeb.spcPage()" in page.text and "<script src=\"http" not in page.text
    d = client.get("/api/spc").json()
    assert d["parts"] == ["bulkhead"] and d["part"] == "bulkhead"
    table = next(sec for sec in d["sections"] if sec["id"] == "spc_table")
    assert table["rows"][0][0] == specs[0].id and "step at SN-07" in table["rows"][0][-1]
    figures = [sec for sec in d["sections"] if sec["kind"] == "figure"]
    assert figures and figures[0]["id"] == f"spc-{specs[0].id}"
    one = client.get("/api/spc", params={"id": specs[5].id, "kind": "web_thickness"}).json()
    assert any(sec["id"] == f"spc-{specs[5].id}" for sec in one["sections"])
    for bad in ({"kind": "nope"}, {"id": "NO-SUCH"}, {"part": "<script>"}):
        r = client.get("/api/spc", params=bad)
        assert r.status_code == 400 and "error" in r.json(), bad


def test_a_point_measured_less_well_than_the_others_is_not_a_special_cause_for_that_alone():
    x = (0.10, 0.11, 0.09, 0.12, 0.10, 0.60, 0.11, 0.10, 0.09, 0.11)
    sure = chart(Series("P", "hole_position", None, 0.5, SERIALS, x, (0.005,) * 10))
    loose = chart(Series("P", "hole_position", None, 0.5, SERIALS, x, (0.005,) * 5 + (0.15,) + (0.005,) * 4))
    assert sure.rule == "point" and sure.rule_serials == ("SN-05",) and sure.p < 1e-6
    assert loose.p > 100 * sure.p
