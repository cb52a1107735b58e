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
        env = dict(os.environ, ITA_HOME=str(home))
        env.pop("ITA_RUNS", None)
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT_S, check=False)
        if done.returncode not in (0, 3):
            raise RunFailed(f"run {task['key']}: exit {done.returncode}: {done.stderr[-1500:]}")
        summary = json.loads(done.stdout) if done.stdout.strip() else {}
        with Archive.open(archive_path(runs), create=False) as archive:
            info = archive.runs()[-1]
            results = [{"spec_id": r.spec_id, "kind": r.kind, "outcome": r.outcome.value, "value": r.value, "u": r.u,
                        "U": r.U, "low": r.low_limit, "high": r.high_limit,
                        "decision": None if r.decision is None else r.decision.value, "tool": r.tool,
                        "reason": r.reason} for r in archive.results(info.id)]
            diagnoses = [e.payload for e in archive.events(info.id, kinds=["diagnosis"])]
        injected = injected_faults(runs, info.id)
        score = diagnosis_score(injected, diagnoses) if injected else None
    return {"key": task["key"], "status": info.status.value, "summary": summary, "results": results,
            "diagnoses": [{k: d.get(k) for k in ("spec", "exception", "cause", "recovery", "summary")}
                          for d in diagnoses],
            "injected": injected,
            "diagnosis_score": None if score is None else {k: score[k] for k in ("with_fault", "named")}
            | {"unexplained": len(score["unexplained"])}, "wall_s": time.perf_counter() - t0,
            "host": os.uname().nodename}
