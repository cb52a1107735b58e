"""The figures of a campaign: per kind, crossed gauge R&R, bias against the truth, false
accepts with their 95 % upper bound; for fault campaigns the measured share and how many
diagnoses named the injected cause; a plot per kind.

    report = campaign_report(out_dir)          # a dict (JSON-ready)
    print(format_report(report))
    plot_kinds(out_dir, report, plots_dir)     # one PNG per kind

Items of the gauge study are (part, spec) pairs that every appraiser measured in every
trial; the truth comes from each part's as-built values (this is scoring: it reads the
truth, as the simulator's parts carry one).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Hashable
from pathlib import Path
from typing import Any

import numpy as np

from ita.campaign.grr import gauge_rr, upper_bound
from ita.campaign.store import CAMPAIGN_FILE, CampaignStore
from ita.files.atomic import write_atomic
from ita.scoring.truth import has_true_values, true_values

__all__ = ["campaign_report", "format_report", "plot_kinds"]


def _truths(out_dir: Path) -> dict[int, dict[str, float]]:
    """Part seed -> spec id -> true value, for the parts the campaign made."""
    out: dict[int, dict[str, float]] = {}
    for d in sorted((out_dir / "parts").glob("part-*")):
        seed = int(d.name.split("-")[1])
        if has_true_values(d):
            out[seed] = true_values(d)
    return out


def campaign_report(out_dir: Path) -> dict[str, Any]:
    out_dir = Path(out_dir)
    with CampaignStore.open(out_dir / CAMPAIGN_FILE, create=False) as store:
        runs = store.runs()
        results = store.results()
    truths = _truths(out_dir)
    by_kind: dict[str, list[dict]] = defaultdict(list)
    for r in results:
        by_kind[r["kind"] or "?"].append(r)
    kinds = {}
    for kind, rows in sorted(by_kind.items()):
        measured = [r for r in rows if r["value"] is not None]
        errors = [r["value"] - truths[r["part_seed"]][r["spec_id"]] for r in measured
                  if r["spec_id"] in truths.get(r["part_seed"], {})]
        accepted = [r for r in rows if r["decision"] == "conforms" and r["spec_id"] in truths.get(r["part_seed"], {})]
        fa = [r for r in accepted if not r["low"] <= truths[r["part_seed"]][r["spec_id"]] <= r["high"]]
        entry: dict[str, Any] = {
            "results": len(rows), "measured": len(measured),
            "measured_share": len(measured) / len(rows) if rows else float("nan"),
            "decisions": {d: sum(r["decision"] == d for r in rows) for d in ("conforms", "does_not_conform",
                                                                             "uncertain")},
            "bias_mm": float(np.mean(errors)) if errors else None,
            "error_sd_mm": float(np.std(errors, ddof=1)) if len(errors) > 1 else None,
            "coverage": float(np.mean([abs(e) <= r["big_u"] for e, r in zip(errors, measured)])) if errors else None,
            "false_accepts": len(fa), "accepted": len(accepted),
            "false_accept_rate": len(fa) / len(accepted) if accepted else None,
            "false_accept_upper95": upper_bound(len(fa), len(accepted)) if accepted else None,
        }
        cells: dict[tuple[Hashable, Hashable, Hashable], float] = {}   # (item, appraiser, trial)
        for r in measured:
            cells[((r["part_seed"], r["spec_id"]), r["appraiser"], r["trial"])] = r["value"]
        apprs = {k[1] for k in cells}
        trials = {k[2] for k in cells}
        full: defaultdict[Hashable, int] = defaultdict(int)
        for k in cells:
            full[k[0]] += 1
        items = {i for i, c in full.items() if c == len(apprs) * len(trials)}
        study = {k: v for k, v in cells.items() if k[0] in items}
        if len(items) >= 2 and len(apprs) >= 2 and len(trials) >= 2:
            widths = [r["high"] - r["low"] for r in measured if (r["part_seed"], r["spec_id"]) in items]
            g = gauge_rr(study, tolerance=float(np.median(widths)))
            entry["gauge_rr"] = {"items": g.items, "appraisers": g.appraisers, "trials": g.trials,
                                 "repeatability_mm": g.ev, "reproducibility_mm": g.av, "grr_mm": g.grr,
                                 "part_mm": g.pv, "percent_grr": g.percent_grr, "ndc": g.ndc,
                                 "percent_tolerance": g.percent_tolerance, "interaction_pooled": g.pooled,
                                 "interaction_p": g.interaction_p}
        else:
            entry["gauge_rr"] = None
        kinds[kind] = entry
    scores = [r["score"] for r in runs if r["score"]]
    faults = {"with_fault": sum(s["with_fault"] for s in scores), "named": sum(s["named"] for s in scores)} \
        if scores else None
    statuses: defaultdict[str, int] = defaultdict(int)
    for r in runs:
        statuses[r["status"]] += 1
    return {"runs": len(runs), "statuses": dict(statuses), "parts": sorted(truths), "kinds": kinds,
            "diagnoses": faults,
            "wall_s": sum(r["wall_s"] or 0.0 for r in runs)}


def format_report(rep: dict[str, Any]) -> str:
    lines = [f"{rep['runs']} runs ({', '.join(f'{k} {v}' for k, v in rep['statuses'].items())}); parts "
             f"{', '.join(map(str, rep['parts']))}"]
    head = (f"{'kind':18} {'results':>7} {'meas%':>6} {'bias um':>8} {'cov%':>5} {'FA':>3}/{'acc':<5} "
            f"{'FA<=95%':>8} {'%GRR':>6} {'%tol':>6} {'ndc':>4} {'EV um':>7} {'AV um':>7}")
    lines += [head, "-" * len(head)]
    for kind, e in rep["kinds"].items():
        g = e["gauge_rr"] or {}

        def f(x, fmt):
            return format(x, fmt) if x is not None else "-"

        lines.append(f"{kind:18} {e['results']:7d} {100 * e['measured_share']:6.1f} "
                     f"{f(None if e['bias_mm'] is None else 1000 * e['bias_mm'], '8.2f'):>8} "
                     f"{f(None if e['coverage'] is None else 100 * e['coverage'], '5.1f'):>5} "
                     f"{e['false_accepts']:3d}/{e['accepted']:<5d} "
                     f"{f(None if e['false_accept_upper95'] is None else 100 * e['false_accept_upper95'], '7.2f'):>7}% "
                     f"{f(g.get('percent_grr'), '6.1f'):>6} {f(g.get('percent_tolerance'), '6.1f'):>6} "
                     f"{f(g.get('ndc'), 'd'):>4} "
                     f"{f(None if not g else 1000 * g['repeatability_mm'], '7.2f'):>7} "
                     f"{f(None if not g else 1000 * g['reproducibility_mm'], '7.2f'):>7}")
    if rep["diagnoses"]:
        d = rep["diagnoses"]
        lines.append(f"diagnoses with an injected fault to find: {d['with_fault']}, named its cause: {d['named']}")
    lines.append("(%GRR of the total variation and of the tolerance, ANOVA method; FA: accepted results whose true "
                 "value is out of tolerance, with the exact 95 % upper bound of their rate)")
    return "\n".join(lines)


def plot_kinds(out_dir: Path, rep: dict[str, Any], plots_dir: Path) -> list[Path]:
    """One PNG per kind: the errors against the truth by appraiser, and the gauge study's
    standard deviations."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with CampaignStore.open(Path(out_dir) / CAMPAIGN_FILE, create=False) as store:
        results = store.results()
    truths = _truths(Path(out_dir))
    plots_dir = Path(plots_dir)
    plots_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for kind, e in rep["kinds"].items():
        rows = [r for r in results if r["kind"] == kind and r["value"] is not None
                and r["spec_id"] in truths.get(r["part_seed"], {})]
        if not rows:
            continue
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.4))
        apprs = sorted({r["appraiser"] for r in rows})
        for i, a in enumerate(apprs):
            err = [1000 * (r["value"] - truths[r["part_seed"]][r["spec_id"]]) for r in rows if r["appraiser"] == a]
            ax1.plot(np.full(len(err), i) + np.linspace(-0.2, 0.2, len(err)), err, ".", ms=3)
        ax1.set_xticks(range(len(apprs)), [f"appraiser {a}" for a in apprs])
        ax1.axhline(0, color="k", lw=0.5)
        ax1.set_ylabel("error against the truth (um)")
        ax1.set_title(kind)
        g = e["gauge_rr"]
        if g:
            names = ["repeatability", "reproducibility", "GRR", "part"]
            vals = [1000 * g[k] for k in ("repeatability_mm", "reproducibility_mm", "grr_mm", "part_mm")]
            ax2.bar(names, vals, color=["#4c72b0", "#dd8452", "#c44e52", "#55a868"])
            ax2.set_ylabel("standard deviation (um)")
            ax2.set_title(f"%GRR {g['percent_grr']:.1f}, of tolerance {g['percent_tolerance']:.1f}, ndc {g['ndc']}")
        else:
            ax2.text(0.5, 0.5, "no crossed study (2+ appraisers and trials)", ha="center", va="center")
            ax2.set_axis_off()
        fig.tight_layout()
        import io

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90)
        plt.close(fig)
        path = plots_dir / f"grr-{kind}.png"
        write_atomic(path, buf.getvalue(), what="plot")
        written.append(path)
    return written
