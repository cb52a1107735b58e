"""The HTML pages of the System Monitor: thin shells that load the shipped scripts
(plotly.js, ita.js, web.js) and draw what the API returns."""

from __future__ import annotations

import html
import json
from importlib import resources
from pathlib import Path


def web_asset(name: str) -> Path:
    return Path(str(resources.files("ita.web") / "static" / name))


def _page(title: str, body: str, boot: str, *, plotly: bool = True) -> str:
    scripts = ('<script src="/assets/plotly.min.js"></script>' if plotly else "") + \
        '<script src="/assets/ita.js"></script><script src="/assets/web.js"></script>'
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{html.escape(title)}</title><link rel=\"stylesheet\" href=\"/assets/ita.css\"></head><body>"
            "<header class=\"bar\"><a class=\"brand\" href=\"/\">ITA System Monitor</a><a href=\"/\">runs</a>"
            "<a href=\"/spc\">SPC</a></header>"
            f"<main>{body}</main>{scripts}<script>{boot}</script></body></html>")


def _arg(x: str) -> str:
    return json.dumps(x).replace("<", "\\u003c")


def runs_page() -> str:
    body = ("<h1>Runs</h1><div id=\"runs\"></div>"
            "<h2>Start a run</h2><form id=\"start\" class=\"filters\">"
            "<label>part directory <input name=\"part\" placeholder=\"built-in bulkhead\" size=\"30\"></label>"
            "<label>limit <input name=\"limit\" type=\"number\" min=\"1\" placeholder=\"every measurement\"></label>"
            "<label>seed <input name=\"seed\" type=\"number\" value=\"0\"></label>"
            "<label>serial <input name=\"serial\" size=\"12\" maxlength=\"64\"></label>"
            "<label>operator <input name=\"operator\" size=\"14\" maxlength=\"64\"></label>"
            "<label>fault rate <input name=\"faults\" type=\"number\" min=\"0\" max=\"1\" step=\"0.01\" "
            "placeholder=\"0: none\" title=\"each command meets a fault with this chance (ita inspect --faults)\">"
            "</label>"
            "<label>inject <input name=\"inject\" size=\"34\" maxlength=\"700\" "
            "placeholder=\"e.g. broken_probe@us_probe_1:after=60\" "
            "title=\"scripted faults, FAULT[@TARGET][:after=S], separated by spaces (ita inspect --inject)\">"
            "</label>"
            "<button type=\"submit\" id=\"start-run\">start inspection</button> <span id=\"start-msg\" class=\"note\"></span>"
            "</form><p class=\"note\">A run started here is `ita inspect` in a process of its own, on this server's "
            "runs directory; loading the system takes about a minute before the first measurement. Faults are "
            "simulated: a rate draws them at random, `inject` scripts them (the run's log says any that cannot "
            "land).</p>")
    return _page("ITA runs", body, "ITAWeb.runsPage();", plotly=False)


def run_page(run_id: str) -> str:
    body = (f"<h1>Run {html.escape(run_id)}</h1><p class=\"tabs\" id=\"tabs\"></p>"
            "<p class=\"gone\" id=\"server-gone\" hidden role=\"alert\">The server is not answering: this page "
            "shows the run as it last was, and its controls are off until the server is back.</p>"
            "<div class=\"controls\">"
            "<button class=\"stop\" id=\"btn-stop\" disabled>STOP</button>"
            "<button class=\"interrupt\" id=\"btn-interrupt\" disabled>INTERRUPT</button>"
            "<button class=\"continue\" id=\"btn-continue\" disabled>CONTINUE</button>"
            "<span id=\"control-msg\" class=\"note\" aria-live=\"polite\"></span></div>"
            "<details class=\"live\" id=\"live-panel\" open><summary>live: the run as it goes</summary>"
            "<div id=\"live\">connecting ...</div></details>"
            "<div id=\"report\"></div>")
    return _page(f"ITA run {run_id}", body, f"ITAWeb.runPage({_arg(run_id)});")


def result_page(run_id: str, spec: str) -> str:
    body = (f"<p><a href=\"/runs/{html.escape(run_id)}\">run {html.escape(run_id)}</a></p>"
            "<div id=\"result\">loading ...</div>")
    return _page(f"ITA {spec}", body, f"ITAWeb.resultPage({_arg(run_id)}, {_arg(spec)});")


def scoring_page(run_id: str) -> str:
    body = (f"<p><a href=\"/runs/{html.escape(run_id)}\">run {html.escape(run_id)}</a></p>"
            "<h1>Scoring against the as-built part</h1><p class=\"note\">Simulation only: this view compares the "
            "results with the simulated part's true dimensions, which the inspection never sees.</p>"
            "<div id=\"report\">loading ...</div>")
    return _page(f"ITA scoring {run_id}", body, f"ITAWeb.scoringPage({_arg(run_id)});")


def spc_page() -> str:
    body = ("<h1>SPC across serials</h1><form id=\"spc-form\" class=\"filters\">"
            "<label>design <select name=\"part\" id=\"spc-part\"></select></label>"
            "<label>kind <input name=\"kind\" size=\"16\" placeholder=\"every kind\"></label>"
            "<label>characteristic <input name=\"id\" size=\"14\" placeholder=\"spec id\"></label>"
            "<button type=\"submit\">chart</button> <span id=\"spc-msg\" class=\"note\"></span></form>"
            "<div id=\"report\">loading ...</div>")
    return _page("ITA SPC", body, "ITAWeb.spcPage();")
