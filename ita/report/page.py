"""The HTML report: one self-contained, interactive page that works from a file, offline.

    text = html_page(payload, drill={spec_id: result_payload(...)})

The page carries everything: the stylesheet, plotly.js (from the plotly wheel), the
project's `ita.js` that draws the views, and the report's data as JSON.  The summary and
the part's verdict are also written as plain HTML, so they read without scripts.  The
drill-down (a result's range image, plan, events, arm path) is included for the results
given in `drill` (the report includes those not proven to conform, up to a limit).
"""

from __future__ import annotations

import html
import json
from collections.abc import Mapping
from typing import Any

from ita.report.assets import asset_text
from ita.report.data import jsonable


def _script_safe(text: str) -> str:
    """Text that can sit inside <script>...</script> (no closing tag, no comment opener)."""
    return text.replace("</script", "<\\/script").replace("</SCRIPT", "<\\/SCRIPT").replace("<!--", "<\\!--")


def _json(obj: Any) -> str:
    text = json.dumps(jsonable(obj), separators=(",", ":"), allow_nan=False, default=str)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _e(x: Any) -> str:
    return html.escape("" if x is None else str(x))


def static_summary(payload: Mapping[str, Any]) -> str:
    """The verdict and the key figures as plain HTML (read without scripts, printed)."""
    s = payload["summary"]
    lines = [f'<div class="verdict {_e(s["verdict"])}">PART {_e(s["verdict"].upper())}</div>',
             f"<p><b>{_e(s['verdict_reason'])}</b></p>",
             f"<p>{s['done']} of {s['part_total']} specs measured; simulated cycle time {s['cycle_h']:.3f} h "
             f"({s['cycle_s']:.1f} s).</p>"]
    if s["complete"]:
        lines.append(f"<p>Manual method ({s['manual_h']:g} h): {s['speedup_manual']:.1f}x faster; goal of 1987 "
                     f"({s['goal_h']:g} h): {s['ratio_goal']:.2f} of the goal time "
                     f"({'met' if s['ratio_goal'] <= 1 else 'not met'}).</p>")
    elif s["rate_s"] is not None:
        lines.append(f"<p>Partial run: {s['rate_s']:.1f} s simulated per measurement; the whole part extrapolated "
                     f"(not measured): {s['projected_h']:.2f} h.</p>")
    return "\n".join(lines)


_BOOT = """
(function () {
  const data = JSON.parse(document.getElementById("ita-data").textContent);
  const drill = JSON.parse(document.getElementById("ita-drill").textContent);
  const root = document.getElementById("report");
  document.getElementById("static-summary").remove();
  const href = (spec) => (drill[spec] ? "#result-" + encodeURIComponent(spec) : null);
  ITA.renderSections(root, data.sections, { resultHref: href });
  const panel = document.getElementById("drill");
  function show() {
    const m = /^#result-(.+)$/.exec(window.location.hash);
    panel.innerHTML = "";
    if (!m) { panel.hidden = true; return; }
    const spec = decodeURIComponent(m[1]);
    if (!drill[spec]) return;
    panel.hidden = false;
    panel.insertAdjacentHTML("beforeend", '<p><a href="#sec-results">back to the results</a></p>');
    ITA.renderResult(panel, drill[spec], { resultHref: href });
    panel.scrollIntoView();
  }
  window.addEventListener("hashchange", show);
  show();
  document.body.dataset.ready = "1";
})();
"""


def html_page(payload: Mapping[str, Any], drill: Mapping[str, Any] | None = None, *, title: str | None = None,
              note: str = "") -> str:
    """The self-contained report page of `payload` (see ita.report.sections.report_payload)."""
    drill = dict(drill or {})
    title = title or f"ITA inspection report: run {payload['run']}"
    drill_note = (f"Opened results (range image, plan, events, arm path) are included for {len(drill)} result(s) "
                  "not proven to conform: their ids in the table are links." if drill else "")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{_e(title)}</title>"
        f"<style>{asset_text('ita.css')}</style></head><body><main>\n"
        f"<h1>{_e(title)}</h1><p class=\"meta\">part {_e(payload['part'])}, status {_e(payload['status'])}. "
        f"{_e(note)} {_e(drill_note)}</p>\n"
        f"<div id=\"static-summary\">{static_summary(payload)}</div>\n"
        "<div id=\"report\"></div><div id=\"drill\" class=\"live\" hidden></div>\n</main>\n"
        f"<script id=\"ita-data\" type=\"application/json\">{_json(payload)}</script>\n"
        f"<script id=\"ita-drill\" type=\"application/json\">{_json(drill)}</script>\n"
        f"<script>{_script_safe(asset_text('plotly.min.js'))}</script>\n"
        f"<script>{_script_safe(asset_text('ita.js'))}</script>\n"
        f"<script>{_BOOT}</script>\n</body></html>\n")
