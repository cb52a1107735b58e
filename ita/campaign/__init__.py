"""Campaigns: studies of many inspection runs (gauge R&R, false-accept rates, fault
injection), run in parallel on a local pool or a Dask cluster into one campaign archive.

    campaign = load_campaign(Path("grr.toml"))             # ita.campaign.study
    run_campaign(campaign, out_dir, workers=2)             # ita.campaign.execute
    report = campaign_report(out_dir)                      # ita.campaign.report
"""

from ita.campaign.study import Campaign, RunTask, load_campaign

__all__ = ["Campaign", "RunTask", "load_campaign"]
