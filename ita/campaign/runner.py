"""One run of a campaign, on whatever process or machine a pool or a cluster gives it.

    record = run_task(task.to_dict())     # a plain dict: results, summary, diagnoses, faults

The run is `ita inspect` in a process of its own, in a temporary directory: the campaign's
prepared ITA_HOME of the part is copied in (its sequence plan, MKB and MACROPs: every run of
a part starts from the same ones, so a run's results depend on its task alone), its runs
archive is read back and the directory removed.  A worker that cannot see the campaign's
files (another machine of a cluster) makes the part itself from its seed and parameters
and prepares it (slower, the same results).  Everything returned is plain data: the engine
carries it back to the campaign.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ita.archive import Archive, archive_path
from ita.part.store import new_part
from ita.scoring.diagnoses import diagnosis_score
from ita.scoring.truth import injected_faults

__all__ = ["RunFailed", "run_task"]

#: a run that takes longer than this (s) is stopped and recorded as failed
RUN_TIMEOUT_S = 3 * 3600


class RunFailed(RuntimeError):
    """A campaign run that did not end with a status (exit code, the end of its stderr)."""


def _part(task: dict, tmp: Path) -> Path:
    part_dir = Path(task["part_dir"])
    if (part_dir / "specs.csv").is_file():
        return part_dir
    params = None
    if task.get("params_text"):
        params = tmp / "params.toml"
        params.write_text(task["params_text"], encoding="utf-8")
    return new_part(tmp / "part", params, task["part_seed"])


def _read_back(runs: Path, summary: dict[str, Any], *,
               two_arms: bool) -> tuple[str, list[dict], list[Mapping[str, Any]], list[dict]]:
    """The run's status, results, diagnoses and injected faults, from its runs archive.  A
    two-arm run is its arms' runs (the summary's ``runs``) and any hand-over run: a spec's
    result is its own arm's, or the hand-over's when that measured it."""
    with Archive.open(archive_path(runs), create=False) as archive:
        if two_arms:
            main = list(summary["runs"].values())
            handed = list(summary.get("handover_runs", {}).values())
            known = {r.id for r in archive.runs()}
            main, handed = [r for r in main if r in known], [r for r in handed if r in known]
            statuses = [archive.run(r).status.value for r in main]
            status = "completed" if summary.get("status") == "completed" else \
                next((s for s in statuses if s != "completed"), "failed")
        else:
            main, handed = [archive.runs()[-1].id], []
            status = archive.run(main[0]).status.value
        last = archive.merged_results(main, handed)
        results = [{"spec_id": r.spec_id, "kind": r.kind, "outcome": r.outcome.value, "value": r.value, "u": r.u,
                    "U": r.U, "low": r.low_limit, "high": r.high_limit,
                    "decision": None if r.decision is None else r.decision.value, "tool": r.tool,
                    "reason": r.reason} for r in last.values()]
        diagnoses = [e.payload for run_id in main + handed for e in archive.events(run_id, kinds=["diagnosis"])]
    injected = [f for run_id in main + handed for f in injected_faults(runs, run_id)]
    return status, results, diagnoses, injected


def run_task(task: dict) -> dict[str, Any]:
    """Run one campaign task (RunTask.to_dict()); its record (see the module doc)."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="ita-campaign-run-") as tmp_name:
        tmp = Path(tmp_name)
        home = tmp / "home"
        if Path(task["home"]).is_dir():
            shutil.copytree(task["home"], home)
        else:
            home.mkdir()
        part_dir = _part(task, tmp)
        runs = tmp / "runs"
        cmd = [sys.executable, "-m", "ita.cli", "inspect", "--part", str(part_dir), "--seed", str(task["sim_seed"]),
               "--runs-dir", str(runs), "--json"]
        if task.get("limit"):
            cmd += ["--limit", str(task["limit"])]
        if task.get("faults"):
            cmd += ["--faults", str(task["faults"])]
        if task.get("fault_kinds"):
            cmd += ["--fault-kinds", ",".join(task["fault_kinds"])]
        if task.get("arms", 1) == 2:
            cmd += ["--arms", "2"]
        env = dict(os.environ, ITA_HOME=str(home))
        env.pop("ITA_RUNS", None)
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT_S, check=False)
        if done.returncode not in (0, 3):
            raise RunFailed(f"run {task['key']}: exit {done.returncode}: {done.stderr[-1500:]}")
        summary = json.loads(done.stdout) if done.stdout.strip() else {}
        if task.get("arms", 1) == 2 and not summary.get("runs"):
            raise RunFailed(f"run {task['key']}: the two-arm run printed no summary: {done.stderr[-1500:]}")
        status, results, diagnoses, injected = _read_back(runs, summary, two_arms=task.get("arms", 1) == 2)
        score = diagnosis_score(injected, diagnoses) if injected else None
    return {"key": task["key"], "status": status, "summary": summary, "results": results,
            "diagnoses": [{k: d.get(k) for k in ("spec", "exception", "cause", "recovery", "summary")}
                          for d in diagnoses],
            "injected": injected,
            "diagnosis_score": None if score is None else {k: score[k] for k in ("with_fault", "named")}
            | {"unexplained": len(score["unexplained"])}, "wall_s": time.perf_counter() - t0,
            "host": os.uname().nodename}
