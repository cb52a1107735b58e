"""`ita campaign`: the campaign file, the gauge R&R figures, the archive, local pool and Dask."""

from __future__ import annotations

import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from ita.campaign.grr import gauge_rr, upper_bound
from ita.campaign.study import load_campaign
from ita.cli import main
from ita.errors import InputError

REPO = Path(__file__).resolve().parents[1]

# AIAG MSA (4th ed.) gauge study: 10 parts x appraisers A, B, C x 3 trials; rows are trials
AIAG = {
    "A": [[0.29, -0.56, 1.34, 0.47, -0.80, 0.02, 0.59, -0.31, 2.26, -1.36],
          [0.41, -0.68, 1.17, 0.50, -0.92, -0.11, 0.75, -0.20, 1.99, -1.25],
          [0.64, -0.58, 1.27, 0.64, -0.84, -0.21, 0.66, -0.17, 2.01, -1.31]],
    "B": [[0.08, -0.47, 1.19, 0.01, -0.56, -0.20, 0.47, -0.63, 1.80, -1.68],
          [0.25, -1.22, 0.94, 1.03, -1.20, 0.22, 0.55, 0.08, 2.12, -1.62],
          [0.07, -0.68, 1.34, 0.20, -1.28, 0.06, 0.83, -0.34, 2.19, -1.50]],
    "C": [[0.04, -1.38, 0.88, 0.14, -1.46, -0.29, 0.02, -0.46, 1.77, -1.49],
          [-0.11, -1.13, 1.09, 0.20, -1.07, -0.67, 0.01, -0.56, 1.45, -1.77],
          [-0.15, -0.96, 0.67, 0.11, -1.45, -0.49, 0.21, -0.49, 1.87, -2.16]],
}


def test_gauge_rr_equals_the_aiag_textbook_example():
    values = {(p + 1, a, t + 1): x for a, rows in AIAG.items() for t, row in enumerate(rows) for p, x in enumerate(row)}
    g = gauge_rr(values)
    # the manual's ANOVA table
    assert g.ss["appraiser"] == pytest.approx(3.1673, abs=5e-5)
    assert g.ss["part"] == pytest.approx(88.3619, abs=5e-5)
    assert g.ss["interaction"] == pytest.approx(0.3590, abs=5e-5)
    assert g.ss["equipment"] == pytest.approx(2.7589, abs=5e-5)
    assert g.ss["total"] == pytest.approx(94.6471, abs=5e-5)
    assert g.df == {"part": 9, "appraiser": 2, "interaction": 18, "equipment": 60, "total": 89}
    assert g.interaction_p == pytest.approx(0.974, abs=0.002) and g.pooled     # not significant: pooled
    # its variance components and figures (the interaction pooled into the equipment term)
    assert g.ev == pytest.approx(0.19993, abs=5e-5)
    assert g.av == pytest.approx(0.22684, abs=5e-5)
    assert g.grr == pytest.approx(0.30237, abs=5e-5)
    assert g.pv == pytest.approx(1.04233, abs=5e-5)
    assert g.percent_grr == pytest.approx(27.86, abs=0.01)
    assert g.ndc == 4
    assert gauge_rr(values, tolerance=6.0).percent_tolerance == pytest.approx(100 * 6 * 0.30237 / 6.0, abs=0.01)


def test_an_unbalanced_study_is_refused():
    values = {(p, a, t): 1.0 + p for p in range(3) for a in "AB" for t in range(2)}
    del values[(0, "A", 0)]
    with pytest.raises(ValueError, match="unbalanced"):
        gauge_rr(values)


def test_upper_bound_of_a_rate_is_the_exact_clopper_pearson_one():
    assert upper_bound(0, 1000) == pytest.approx(1 - 0.05 ** (1 / 1000))
    assert upper_bound(0, 100) == pytest.approx(0.0295, abs=1e-4)                    # "rule of three"
    assert upper_bound(3, 100) == pytest.approx(0.0757, abs=1e-3)
    assert upper_bound(5, 5) == 1.0


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "study.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_campaign_file_gives_every_part_appraiser_and_trial(tmp_path):
    c = load_campaign(_write(tmp_path, "[campaign]\nlimit = 5\n[parts]\nseeds = [3, 4]\n"
                                       "[appraisers]\nseeds = [1, 2, 7]\ntrials = 2\n"))
    tasks = c.tasks(tmp_path / "out")
    assert len(tasks) == 2 * 3 * 2 and len({t.key for t in tasks}) == 12
    assert len({t.sim_seed for t in tasks}) == 12                      # no two runs share their noise
    assert {t.limit for t in tasks} == {5} and c.name == "study"
    assert {t.arms for t in tasks} == {1} and '"arms"' not in tasks[0].settings()   # one-arm archives stay valid


def test_a_two_arm_campaign_runs_every_run_with_both_arms(tmp_path):
    c = load_campaign(_write(tmp_path, "[campaign]\narms = 2\n[parts]\nseeds = [3]\n[appraisers]\nseeds = [1]\n"))
    (task,) = c.tasks(tmp_path / "out")
    assert task.arms == 2 and '"arms": 2' in task.settings()     # a restart with arms changed is refused


@pytest.mark.parametrize("text, field", [
    ("[parts]\nseeds = [1]\n", "appraisers"),
    ("[parts]\nseeds = []\n[appraisers]\nseeds = [1]\n", "parts.seeds"),
    ("[parts]\nseeds = [1, 1]\n[appraisers]\nseeds = [1]\n", "parts.seeds"),
    ("[parts]\nseeds = [1]\n[appraisers]\nseeds = [1]\ntrials = 0\n", "appraisers.trials"),
    ("[parts]\nseeds = [1]\nparams = 'nowhere.toml'\n[appraisers]\nseeds = [1]\n", "parts.params"),
    ("[campaign]\nfaults = 2\n[parts]\nseeds = [1]\n[appraisers]\nseeds = [1]\n", "campaign.faults"),
    ("[campaign]\narms = 3\n[parts]\nseeds = [1]\n[appraisers]\nseeds = [1]\n", "campaign.arms"),
    ("[campaign]\nlimt = 3\n[parts]\nseeds = [1]\n[appraisers]\nseeds = [1]\n", "campaign.limt"),
    ("[parts\nseeds = [1]\n", "TOML"),
])
def test_a_bad_campaign_file_names_the_field_and_exits_2(tmp_path, text, field):
    path = _write(tmp_path, text)
    with pytest.raises(InputError) as err:
        load_campaign(path)
    assert field in str(err.value) and str(path) in str(err.value)
    result = CliRunner().invoke(main, ["campaign", str(path)])
    assert result.exit_code == 2 and field in result.output
    assert not (tmp_path / "study.campaign").exists()


# -- real campaigns (each run an `ita inspect`): slow -------------------------------------------
TINY = """[campaign]
limit = 3
[parts]
seeds = [11]
params = "small.toml"
[appraisers]
seeds = [1, 2]
trials = 2
"""


@pytest.fixture(scope="module")
def prepared(tmp_path_factory, builtin_part):
    """A tiny campaign file (4 runs of 3 measurements on a small bulkhead) and one campaign
    directory with its part made and prepared (copied by each test: preparing is the slow part)."""
    from ita.campaign.execute import prepare_parts
    from ita.part.bulkhead import default_params_path
    from tests.test_cli_part import small_bulkhead_params

    d = tmp_path_factory.mktemp("campaign")
    (d / "small.toml").write_text(small_bulkhead_params(default_params_path().read_text(encoding="utf-8")),
                                  encoding="utf-8")
    study = d / "tiny.toml"
    study.write_text(TINY, encoding="utf-8")
    base = d / "base"
    c = load_campaign(study)
    prepare_parts(c, c.tasks(base), lambda _m: None)
    return study, base


def _rows(out: Path) -> list[tuple]:
    with sqlite3.connect(out / "campaign.sqlite") as c:
        return c.execute("SELECT key, spec_id, outcome, value, u, decision, tool FROM results ORDER BY key, spec_id"
                         ).fetchall()


@pytest.mark.slow
def test_a_campaign_on_a_dask_cluster_gives_the_same_archive_as_the_local_pool(prepared, tmp_path):
    from distributed import LocalCluster

    study, base = prepared
    pool, dask = tmp_path / "pool", tmp_path / "dask"
    for d in (pool, dask):
        shutil.copytree(base, d)
    result = CliRunner().invoke(main, ["campaign", str(study), "--out", str(pool), "--workers", "2"])
    assert result.exit_code == 0, result.output
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        result = CliRunner().invoke(main, ["campaign", str(study), "--out", str(dask), "--cluster",
                                           cluster.scheduler_address])
    assert result.exit_code == 0, result.output
    a, b = _rows(pool), _rows(dask)
    assert len(a) == 4 * 3 and a == b
    rep = CliRunner().invoke(main, ["campaign", "report", str(dask), "--plots", str(tmp_path / "plots")])
    assert rep.exit_code == 0 and "%GRR" in rep.output, rep.output
    assert list((tmp_path / "plots").glob("grr-*.png"))


@pytest.mark.slow
def test_a_campaign_killed_and_started_again_runs_only_what_is_missing(prepared, tmp_path):
    study, base = prepared
    out = tmp_path / "out"
    shutil.copytree(base, out)
    cmd = [sys.executable, "-m", "ita.cli", "campaign", str(study), "--out", str(out), "--workers", "1"]
    proc = subprocess.Popen(cmd, env=dict(os.environ), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    db = out / "campaign.sqlite"
    first = None
    try:
        deadline = time.time() + 300
        while time.time() < deadline and proc.poll() is None:
            if db.is_file():
                with sqlite3.connect(db) as c:
                    first = c.execute("SELECT key, finished FROM runs WHERE status = 'completed'").fetchall()
                if first:
                    break
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGKILL)       # the campaign and the run it is in the middle of
    finally:
        proc.wait(timeout=30)
    assert first and len(first) < 4, "no run finished before the kill (or all did)"
    result = CliRunner().invoke(main, ["campaign", str(study), "--out", str(out), "--workers", "2"])
    assert result.exit_code == 0, result.output
    assert f"{len(first)} done, {4 - len(first)} to run" in result.output
    with sqlite3.connect(db) as c:
        rows = dict(c.execute("SELECT key, finished FROM runs WHERE status = 'completed'").fetchall())
    assert len(rows) == 4 and all(rows[k] == t for k, t in first)        # the finished one was not run again


@pytest.mark.slow
def test_a_two_arm_campaign_run_gives_both_arms_results(prepared, tmp_path):
    """`arms = 2`: the part prepared for both arms (`ita prepare --arms 2`), each run an
    `ita inspect --arms 2` whose two arms' results are read back as one run's.  The whole
    small bulkhead (its plan's first measurements, the SLRA's near the datums, are one
    arm's: a limit would leave the other nothing)."""
    study, _base = prepared
    two = study.parent / "two.toml"
    two.write_text(TINY.replace("limit = 3", "arms = 2").replace("seeds = [1, 2]\ntrials = 2", "seeds = [1]\ntrials = 1"),
                   encoding="utf-8")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["campaign", str(two), "--out", str(out), "--workers", "1"])
    assert result.exit_code == 0, result.output
    with sqlite3.connect(out / "campaign.sqlite") as c:
        (status, summary), = c.execute("SELECT status, summary FROM runs").fetchall()
        specs = [r[0] for r in c.execute("SELECT spec_id FROM results")]
    summary = json.loads(summary)
    assert status == "completed" and summary["arms"] == 2 and summary["arm_arm_contacts"] == 0
    made = {arm: a["measured"] for arm, a in summary["per_arm"].items()}
    assert len(made) == 2 and all(n > 0 for n in made.values()), made     # both arms worked the part
    # each result once, from its arm's run (and nearly all measured)
    assert len(specs) == len(set(specs)) and 0.98 * len(specs) <= sum(made.values()) <= len(specs)
