"""Running a campaign: its parts made and prepared once, its runs on a local pool or a
Dask cluster, each finished run into the campaign archive.

    summary = run_campaign(load_campaign(path), out_dir, workers=2)                # local
    summary = run_campaign(campaign, out_dir, cluster="tcp://10.0.0.5:8786")     # Dask

Local: a pool of `workers` threads, each starting its runs as processes of their own
(`ita inspect`), so runs share nothing but the machine.  Cluster: the tasks go to an
existing Dask distributed scheduler (`distributed.Client(ADDRESS)`); Dask does the
scheduling, the retries (one per task) and carries each record back; this module only
writes what comes back.  Either way a run's record lands in the archive when the run ends,
and a campaign started again runs only the runs the archive does not hold (and those that
failed or were interrupted).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from ita.campaign.runner import run_task
from ita.campaign.store import CAMPAIGN_FILE, CampaignStore
from ita.campaign.study import Campaign, RunTask
from ita.errors import ItaError
from ita.part.store import new_part

__all__ = ["prepare_parts", "run_campaign"]


def prepare_parts(campaign: Campaign, tasks: list[RunTask], progress: Callable[[str], None]) -> None:
    """Make each part the tasks need (`ita part new`) and prepare it once (`ita prepare`,
    with ``--arms 2`` for a two-arm campaign, into the part's own ITA_HOME), so that every
    run of it starts from the same plans (and allocation)."""
    seen: set[str] = set()
    for t in tasks:
        if t.part_dir in seen:
            continue
        seen.add(t.part_dir)
        part_dir, home = Path(t.part_dir), Path(t.home)
        if not (part_dir / "specs.csv").is_file():
            progress(f"making part {part_dir.name} (generator seed {t.part_seed})")
            new_part(part_dir, campaign.params_path, t.part_seed)
        progress(f"preparing part {part_dir.name}")
        home.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ, ITA_HOME=str(home))
        arms = ["--arms", "2"] if campaign.arms == 2 else []
        done = subprocess.run([sys.executable, "-m", "ita.cli", "prepare", "--part", str(part_dir), *arms], env=env,
                              capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise ItaError(f"preparing {part_dir} failed: {done.stderr[-1500:]}")


def run_campaign(campaign: Campaign, out_dir: Path, *, workers: int | None = None, cluster: str | None = None,
                 progress: Callable[[str], None] = lambda _m: None) -> dict[str, Any]:
    """Run what the archive in `out_dir` lacks of `campaign`; a summary of this call."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tasks = campaign.tasks(out_dir)
    t0 = time.perf_counter()
    with CampaignStore.open(out_dir / CAMPAIGN_FILE) as store:
        store.check_tasks(tasks)
        done = store.done()
        todo = [t for t in tasks if t.key not in done]
        progress(f"campaign {campaign.name}: {len(tasks)} runs, {len(done & {t.key for t in tasks})} done, "
                 f"{len(todo)} to run ({'cluster ' + cluster if cluster else f'{workers or 1} local workers'})")
        if not todo:
            return {"runs": len(tasks), "ran": 0, "failed": 0, "wall_s": 0.0}
        prepare_parts(campaign, todo, progress)
        counts = {"ran": 0, "failed": 0}

        def finished(task: RunTask, fut: Any) -> None:
            n = counts["ran"] + counts["failed"] + 1
            try:
                record = fut.result()
            except Exception as exc:  # noqa: BLE001 - a failed run is recorded, the campaign goes on
                store.record_failure(task, f"{type(exc).__name__}: {exc}")
                counts["failed"] += 1
                progress(f"[{n}/{len(todo)}] {task.key} FAILED: {str(exc)[-300:]}")
                return
            store.record(task, record)
            counts["ran"] += 1
            progress(f"[{n}/{len(todo)}] {task.key} {record['status']}: {len(record['results'])} results in "
                     f"{record['wall_s']:.0f} s on {record['host']}")

        if cluster:
            _on_dask(cluster, todo, finished)
        else:
            _on_pool(workers or 1, todo, finished)
    return {"runs": len(tasks), **counts, "wall_s": time.perf_counter() - t0}


def _on_pool(workers: int, todo: list[RunTask], finished: Callable[[RunTask, Any], None]) -> None:
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="ita-campaign")
    futures: dict[Future, RunTask] = {pool.submit(run_task, t.to_dict()): t for t in todo}
    try:
        for fut in as_completed(futures):
            finished(futures[fut], fut)
    except KeyboardInterrupt:
        for fut in futures:
            fut.cancel()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _on_dask(address: str, todo: list[RunTask], finished: Callable[[RunTask, Any], None]) -> None:
    from distributed import Client
    from distributed import as_completed as dask_completed

    try:
        client = Client(address, timeout="20s")
    except OSError as exc:
        raise ItaError(f"no Dask scheduler at {address}: {exc}") from None
    with client:
        futures = {client.submit(run_task, t.to_dict(), key=f"ita-run-{t.key}-{os.getpid()}-{time.time_ns()}",
                                 pure=False, retries=1): t for t in todo}
        try:
            for fut in dask_completed(list(futures)):
                finished(futures[fut], fut)
        except KeyboardInterrupt:
            client.cancel(list(futures))
            raise
