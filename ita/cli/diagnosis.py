"""`ita diagnosis`: the Exception Handler's diagnoses and what it has learned.

    ita diagnosis show [RUN] [--json]     the run's exceptions counted, and each diagnosis: exception, posterior,
                                          tests in order with results and costs, cause,
                                          world update, recovery
    ita diagnosis counts [--json]         how often each exception and cause has occurred
    ita diagnosis reset                   forget the learned counts (the stated priors stay)

The diagnosis knowledge itself is kb/faults.pl; ask it with `ita kb query` or see why a
cause is isolated with, e.g.,
`ita kb why "diagnosis:isolated(no_echo, [probe=us_probe_1, device=gauge], [read_cal_block-no_echo], C)"`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import click

from ita.cli.common import reports_errors
from ita.cli.runs import open_archive, resolve_run, runs_dir_option


@click.group()
def diagnosis() -> None:
    """The Exception Handler's diagnoses of a run, and the fault counts it has learned."""


@diagnosis.command()
@click.argument("run", default="last")
@runs_dir_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@reports_errors
def show(run: str, runs_dir: Path | None, as_json: bool) -> None:
    """Every diagnosis of RUN (an id, a unique prefix, or "last"), in order, after the run's
    count of exceptions (ita.archive.exceptions: the count `ita inspect`, `ita monitor`, the
    web pages and the reports show).  --json: the counts and one entry per exception (where
    it happened, its diagnosis or the one that ran it), and any diagnosis no exception
    raised (an interim check's)."""
    from ita.archive.exceptions import EVENT_KINDS, ExceptionCounts, exception_records

    with open_archive(runs_dir) as archive:
        run_id = resolve_run(archive, run)
        events = archive.events(run_id, kinds=EVENT_KINDS)
    found = [e for e in events if e.kind == "diagnosis"]
    records = exception_records(events)
    counts = ExceptionCounts.of(records)
    linked = {id(r.diagnosis) for r in records if r.diagnosis is not None}
    unlinked = [e for e in found if id(e.payload) not in linked]
    if as_json:
        click.echo(json.dumps({"run": run_id, "counts": counts.to_dict(),
                               "exceptions": [r.to_dict() for r in records],
                               "diagnoses_without_exception": [{"sim_time": e.sim_time, **e.payload}
                                                               for e in unlinked]}, indent=1))
        return
    click.echo(f"run {run_id}: {counts.text()}")
    aside = [r for r in records if not r.diagnosed]
    if aside:
        click.echo("  not diagnosed on their own: " + "; ".join(
            f"{r.at or 0:.1f} s {r.where} ({r.purpose or 'measurement'}{', ' + r.spec if r.spec else ''}): "
            f"{r.message[:60]}" for r in aside[:8]) + (f"; and {len(aside) - 8} more" if len(aside) > 8 else ""))
    if not found:
        click.echo("no exception needed a diagnosis")
        return
    click.echo(f"{len(found)} diagnoses")
    for e in found:
        d = e.payload
        click.echo(f"\n{e.sim_time:9.1f} s  {d['spec']}: {d['exception']}  ({d.get('reply', '')[:90]})"
                   + (f"  [met while handling {d['during']}]" if d.get("during") else ""))
        click.echo("   posterior: " + ", ".join(f"{c} {p:.2f}" for c, p in d.get("posterior", [])))
        click.echo(f"   decision tree's expected cost: {d.get('expected_s', 0):.1f} s")
        for k, t in enumerate(d.get("tests", []), 1):
            click.echo(f"   test {k}: {t['test']} -> {t['outcome']}  ({t['seconds']:.1f} s, "
                       f"estimated {t['estimated_s']:.1f} s){'  ' + t['note'] if t.get('note') else ''}")
        cause = d.get("cause") or "unresolved: " + ", ".join(c for c, _ in d.get("remaining", []))
        click.echo(f"   cause: {cause}")
        if d.get("cause"):
            click.echo(f"   why: ita kb why \"{why_goal(d)}\"")
        for u in d.get("updates", []):
            click.echo(f"   update: {u}")
        click.echo(f"   recovery: {d.get('recovery', '')}")


def _atom(text: str) -> str:
    return text if re.fullmatch(r"[a-z][A-Za-z0-9_]*", text) else "'" + text.replace("'", "\\'") + "'"


def why_goal(d: dict) -> str:
    """The goal whose proof (`ita kb why`) shows why a diagnosis isolated its cause: the
    exception's causes in its context and each test result's prediction."""
    context = ", ".join(f"{_atom(k)}={_atom(str(v))}" for k, v in d.get("context", {}).items())
    results = ", ".join(f"{_atom(t['test'])}-{_atom(t['outcome'])}" for t in d.get("tests", [])
                        if t.get("outcome") not in ("not_run", "interrupted"))
    return f"faults:isolated({_atom(d['exception'])}, [{context}], [{results}], Cause)"


@diagnosis.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@reports_errors
def counts(as_json: bool) -> None:
    """How often each exception and each cause has occurred (learned across runs)."""
    from ita.diagnosis import FaultCounts, counts_path

    c = FaultCounts.load()
    if as_json:
        click.echo(json.dumps({"causes": c.causes, "exceptions": c.exceptions, "path": str(counts_path())}, indent=1))
        return
    click.echo(f"learned fault counts ({counts_path()}):")
    for title, table in (("exceptions", c.exceptions), ("causes", c.causes)):
        click.echo(f"  {title}:" + ("" if table else " none yet"))
        for name, n in sorted(table.items(), key=lambda kv: -kv[1]):
            click.echo(f"    {n:6d}  {name}")


@diagnosis.command()
@reports_errors
def reset() -> None:
    """Forget the learned counts (the stated priors of kb/faults.pl stay)."""
    from ita.diagnosis import FaultCounts, counts_path

    path = counts_path()
    FaultCounts().save(path)
    click.echo(f"fault counts reset: {path}")
