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
            "land).</p>"
            "<h2>Enter a part's specs by pointing at it</h2><form action=\"/parts/specs\" method=\"get\" "
            "class=\"filters\"><label>part directory <input name=\"dir\" size=\"40\" required></label>"
            "<button type=\"submit\">open the spec editor</button></form>")
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


def _back(run_id: str) -> str:
    """The link back to a run's page."""
    return f"<p><a href=\"/runs/{html.escape(run_id)}\">run {html.escape(run_id)}</a></p>"


def result_page(run_id: str, spec: str) -> str:
    body = (_back(run_id) +
            "<div id=\"result\">loading ...</div>")
    return _page(f"ITA {spec}", body, f"ITAWeb.resultPage({_arg(run_id)}, {_arg(spec)});")


def scoring_page(run_id: str) -> str:
    body = (_back(run_id) +
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


def part_specs_page(directory: str) -> str:
    """The Offline Measurement Entry: the part in 3-D, a spec proposed where one clicks, a
    form for its kind, tolerance and datum, save and undo, the part's specs."""
    body = (f"<h1>Specs of the part in {html.escape(directory)}</h1>"
            "<p class=\"note\">Click the part where a measurement is to be made: the proposal below is read from "
            "the mesh there (a hole from its wall or rim, a web or a wall with its back face, a rib's or a rim's "
            "top). Choose the kind where several fit, set the tolerance and the datum, save. Every change is "
            "checked as <code>ita spec add</code> checks it and written to specs.csv at once; undo takes back "
            "the last change made here.</p>"
            "<div class=\"editor\"><div id=\"part3d\" class=\"part3d\"></div>"
            "<form id=\"proposal\" class=\"proposal\"><h2>Proposal</h2><p id=\"pick-what\" class=\"note\">"
            "nothing picked yet</p>"
            "<label>kind <select name=\"kind\" id=\"pick-kind\"></select></label>"
            "<label>id <input name=\"id\" id=\"pick-id\" size=\"14\" maxlength=\"64\"></label>"
            "<label>feature <input name=\"feature\" id=\"pick-feature\" size=\"10\" maxlength=\"64\"></label>"
            "<label>nominal (mm) <input name=\"nominal\" id=\"pick-nominal\" size=\"10\"></label>"
            "<label>lower (mm) <input name=\"lower\" id=\"pick-lower\" size=\"8\" value=\"-0.1\"></label>"
            "<label>upper (mm) <input name=\"upper\" id=\"pick-upper\" size=\"8\" value=\"0.1\"></label>"
            "<label>datum <input name=\"datum\" id=\"pick-datum\" size=\"8\" value=\"A\"></label>"
            "<label>note <input name=\"note\" id=\"pick-note\" size=\"20\" maxlength=\"200\"></label>"
            "<p id=\"pick-where\" class=\"note\"></p>"
            "<button type=\"submit\" id=\"spec-save\" disabled>save</button> "
            "<button type=\"button\" id=\"spec-undo\" disabled>undo the last change</button> "
            "<span id=\"spec-msg\" class=\"note\" aria-live=\"polite\"></span></form></div>"
            "<h2>The part's specs</h2><div id=\"spec-list\">loading ...</div>")
    return _page(f"ITA specs {directory}", body, f"ITAWeb.specEditor({_arg(directory)});")


def paths_page(run_id: str) -> str:
    body = (_back(run_id) +
            "<h1>The Path Planner's paths: every arm move of the run</h1><p class=\"note\">The tool point's path of "
            "each move the arm made, one colour per tool, in the workcell with the part (world frame, m); hover: the "
            "measurement and the command.</p><div id=\"paths\">loading ...</div>")
    return _page(f"ITA paths {run_id}", body, f"ITAWeb.pathsPage({_arg(run_id)});")
