"""`ita serve` driven in a real browser (headless Chromium through selenium), and the HTML
report opened from a file with no network.

One server and one browser for the module.  Skipped when Chromium or its driver is not
installed (`bash setup.sh test` installs them).
"""

from __future__ import annotations

import shutil
import socket
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from archive_synth import fake_specs, record_synthetic_run, record_two_arm_run, true_values

from ita.archive import Archive, Outcome, Result, StoredFrame, archive_path

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
DRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
pytestmark = pytest.mark.skipif(not (Path(CHROMIUM).exists() and Path(DRIVER).exists()),
                                reason="needs Debian's chromium and chromium-driver")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _synthetic_frame_result(archive: Archive, run_id: str) -> str:
    """A result with a range frame and Vision's overlay, as the Top Level keeps them."""
    spec = fake_specs(1)[0]
    spec = type(spec)("ring-1", "hole_diameter", (10.0, 10.0, 0.0), 6.35, -0.05, 0.05)
    rows, cols = np.mgrid[0:64, 0:80]
    rng = np.where(np.hypot(rows - 32, cols - 40) < 12, 0.60, 0.45) + 0.0002 * cols
    circle = [[32 + 12 * np.sin(a), 40 + 12 * np.cos(a)] for a in np.linspace(0, 2 * np.pi, 40)]
    frame = StoredFrame("ring-1", 0, rng, np.ones_like(rng) * 0.5, np.eye(4), (30.0, 24.0), {"group": "g"})
    archive.record_result(run_id, Result.measured(spec, 6.36, 0.004, tool="slra_1"),
                          details={"tool": "slra_1", "vision": {"patch": [10, 54, 15, 65], "circle": circle,
                                                                "rim": circle[::2], "nominal": [32, 40], "frame": 0},
                                   "plan": {"source": "macrop", "macrop": "m1", "steps": [
                                       {"n": 1, "text": "slra_scan(slra_1, t3, ring-1)", "after": []}]}},
                          frames=[frame])
    return "ring-1"


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """A runs directory with a synthetic run (and a frame), a server on it, a browser."""
    import uvicorn
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    from ita.web.app import create_app

    runs = tmp_path_factory.mktemp("web-runs")
    specs = fake_specs(80)
    with Archive.open(archive_path(runs)) as a:
        rid = record_synthetic_run(a, specs, true_values(specs))
        ring = _synthetic_frame_result(a, rid)
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(create_app(runs), host="127.0.0.1", port=port, log_level="warning",
                                           timeout_graceful_shutdown=1))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--window-size=1300,1500",
                f"--user-data-dir={tmp_path_factory.mktemp('chromium')}"):
        opts.add_argument(arg)
    browser = webdriver.Chrome(service=Service(DRIVER), options=opts)
    browser.set_page_load_timeout(60)
    try:
        yield {"base": f"http://127.0.0.1:{port}", "runs": runs, "run": rid, "ring": ring, "browser": browser,
               "specs": specs}
    finally:
        browser.quit()
        server.should_exit = True
        thread.join(timeout=10)


def _wait(browser, script: str, timeout: float = 30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = browser.execute_script(script)
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for: {script}")


def _canvas_is_drawn(browser, css: str) -> bool:
    """Whether the element's picture (a screenshot of it) has more than a few colours."""
    import io

    from PIL import Image

    el = browser.find_element("css selector", css)
    img = Image.open(io.BytesIO(el.screenshot_as_png)).convert("RGB")
    return len(img.getcolors(maxcolors=1 << 20) or []) > 20


def test_runs_list_loads(site) -> None:
    b = site["browser"]
    b.get(site["base"] + "/")
    _wait(b, "return document.body.dataset.ready")
    table = b.find_element("id", "runs-table").text
    assert site["run"] in table and "completed" in table


def test_results_table_filters_and_sorts(site) -> None:
    b = site["browser"]
    b.get(f"{site['base']}/runs/{site['run']}")
    _wait(b, "return document.body.dataset.ready && document.querySelector('table.results tbody tr[data-spec]')")
    count = b.find_element("css selector", "#sec-results .count")
    total = len(b.find_elements("css selector", "#sec-results tbody tr"))
    assert total == 81 and f"{total} of {total}" in count.text
    box = b.find_element("css selector", "#sec-results input[type=search]")
    box.send_keys("hole_diameter")
    shown = b.find_elements("css selector", "#sec-results tbody tr")
    assert 0 < len(shown) < total and all("hole_diameter" in r.text for r in shown)
    box.clear()
    b.execute_script("const s = document.querySelector('#sec-results select[data-f=decision]');"
                     "s.value = 'does_not_conform'; s.dispatchEvent(new Event('change'));")
    shown = b.find_elements("css selector", "#sec-results tbody tr")
    assert shown and all("does not conform" in r.text for r in shown)
    # the live panel (folded below the report of a run that has ended) says it is completed;
    # only CONTINUE would make sense, and it does not
    assert "completed" in b.execute_script("return document.getElementById('live').textContent")
    assert b.find_element("id", "btn-stop").get_attribute("disabled")
    # the headers sort from the keyboard, and say how (aria-sort)
    th = b.find_element("css selector", "#sec-results th[data-key=deviation]")
    th.send_keys("\ue007")                                    # Enter
    assert th.get_attribute("aria-sort") == "ascending"
    b.execute_script("const d = document.querySelector('#sec-results select[data-f=decision]');"
                     "d.value = ''; d.dispatchEvent(new Event('change'));"
                     "const s = document.querySelector('#sec-results select[data-sort]');"
                     "s.value = 'deviation_over_tolerance'; s.dispatchEvent(new Event('change'));")
    classes = b.execute_script("return [...document.querySelectorAll('#sec-results tbody tr')].map("
                               "(tr) => tr.className)")
    assert classes and classes[0] == "st-does_not_conform"      # the furthest out first


def test_3d_view_renders(site) -> None:
    b = site["browser"]
    b.get(f"{site['base']}/runs/{site['run']}")
    _wait(b, "return document.querySelector('#fig-part3d canvas')")
    time.sleep(1.0)
    assert _canvas_is_drawn(b, "#fig-part3d")


def test_result_page_shows_its_range_image(site) -> None:
    b = site["browser"]
    b.get(f"{site['base']}/runs/{site['run']}/results/{site['ring']}")
    _wait(b, "return document.body.dataset.ready")
    _wait(b, "return document.querySelector('#fig-range .heatmaplayer image, #fig-range .hm image')")
    text = b.find_element("id", "result").text
    assert "Range image" in text and "fitted circle" in text and "slra_scan" in text
    assert _canvas_is_drawn(b, "#fig-range")


def test_html_report_from_a_file_draws_its_charts_offline(site, tmp_path: Path) -> None:
    from ita.report import build_report, write_report

    with Archive.open(archive_path(site["runs"])) as a:
        page = build_report(a, site["run"], specs=site["specs"], true_values=true_values(site["specs"]))
    out = write_report(tmp_path / "report.html", page)
    b = site["browser"]
    b.get(out.as_uri())
    _wait(b, "return document.body.dataset.ready")
    drawn = b.execute_script("return document.querySelectorAll('.js-plotly-plot .main-svg').length")
    assert drawn >= 4
    assert "PART REJECT" in b.find_element("id", "verdict").text
    assert b.find_element("id", "sec-scoring").text.startswith("Scoring against the as-built part")
    errors = [e for e in b.get_log("browser") if e["level"] == "SEVERE" and "favicon" not in e["message"]]
    assert not errors, errors


def _live_text(b) -> str:
    return b.find_element("id", "live").text


LIMIT = 400


def test_start_stop_continue_from_the_page(site, builtin_part) -> None:
    """A real run started on the runs page: it progresses, STOP stops it, CONTINUE finishes
    it, and every measurement has exactly one result."""
    b = site["browser"]
    b.get(site["base"] + "/")
    _wait(b, "return document.body.dataset.ready")
    # 400: the probe's group comes first and takes well under a second a measurement: a run
    # of 150 once ended (about 9 s) before STOP reached it on a loaded machine
    b.find_element("css selector", "#start input[name=limit]").send_keys(str(LIMIT))
    b.find_element("id", "start-run").click()
    _wait(b, "return window.location.pathname.startsWith('/runs/r')", 20)
    run_id = b.current_url.rsplit("/", 1)[-1]
    _wait(b, "return Number((document.getElementById('live-done') || {}).textContent || 0) >= 2", 240)
    b.find_element("id", "btn-stop").click()
    _wait(b, "return document.getElementById('control-msg').textContent", 30)
    assert b.find_element("id", "control-msg").text == "STOP sent"
    _wait(b, "return (document.getElementById('live-state') || {}).textContent === 'stopped'", 60)
    with Archive.open(archive_path(site["runs"])) as a:
        stopped = a.run(run_id)
        assert stopped.status.value == "stopped" and 2 <= stopped.done < LIMIT
    _wait(b, "return !document.getElementById('btn-continue').disabled", 10)
    b.find_element("id", "btn-continue").click()
    _wait(b, "return (document.getElementById('live-state') || {}).textContent === 'completed'", 240)
    with Archive.open(archive_path(site["runs"])) as a:
        results = a.results(run_id)
        ids = Counter(r.spec_id for r in results)
        assert len(results) == LIMIT and set(ids.values()) == {1}
        assert ids.keys() == set(a.run(run_id).settings["specs"])
        assert [e.kind for e in a.events(run_id, kinds=["stop", "resume"])] == ["stop", "resume"]
    assert any(r.outcome is Outcome.MEASURED for r in results)


def _running_run(runs: Path, n: int) -> str:
    """A run as big as a whole part's, RUNNING in this (live) process: its page has every
    result and STOP, INTERRUPT enabled."""
    from archive_synth import fake_specs as specs_of
    from archive_synth import record_synthetic_run as record

    from ita.archive import RunStatus

    specs = specs_of(n)
    with Archive.open(archive_path(runs)) as a:
        return record(a, specs, true_values(specs), status=RunStatus.RUNNING)


def test_stop_is_answered_within_a_second_with_a_whole_runs_page_open(site) -> None:
    """The page says STOP at once and the run's control table (which the run reads before
    each measurement) has it within 1 s, while the page draws a whole run's report (1,076
    results): the live panel does not wait for it."""
    b = site["browser"]
    run_id = _running_run(site["runs"], 1076)
    b.get(f"{site['base']}/runs/{run_id}")
    _wait(b, "return !document.getElementById('btn-stop').disabled", 30)
    # the page notes (wall clock, ms) the click's dispatch, when its message first changes, and
    # every task that keeps it busy for long from now on (a click then would wait for it)
    b.execute_script("window.seen = {}; window.longtasks = []; window.enabledAt = performance.now();"
                     "new PerformanceObserver((l) => l.getEntries().forEach((e) => window.longtasks.push("
                     "[e.startTime, e.duration]))).observe({type: 'longtask', buffered: true});"
                     "document.getElementById('btn-stop').addEventListener('click', () => {"
                     "  window.seen.click = Date.now(); }, true);"
                     "const m = document.getElementById('control-msg');"
                     "new MutationObserver(() => { if (m.textContent && !window.seen.first) window.seen.first = Date.now(); })"
                     ".observe(m, {childList: true, characterData: true, subtree: true});")
    b.find_element("id", "btn-stop").click()
    seen = _wait(b, "return window.seen.first && window.seen", 10)
    _wait(b, "return document.getElementById('control-msg').textContent === 'STOP sent'", 10)
    with Archive.open(archive_path(site["runs"])) as a:
        pending = a.pending_control(run_id)
    assert [getattr(p.command, "value", p.command) for p in pending] == ["STOP"]
    acknowledged = (seen["first"] - seen["click"]) / 1000
    reached = pending[0].issued - seen["click"] / 1000   # when the run's control table had it (what the run reads)
    assert acknowledged < 1.0 and reached < 1.0, (acknowledged, reached)
    _wait(b, "return document.querySelectorAll('#sec-results tbody tr').length === 1076", 60)
    busy = b.execute_script("return window.longtasks.filter((t) => t[0] + t[1] > window.enabledAt && t[1] >= 1000)")
    assert busy == [], busy                         # while it drew the whole run, nothing kept a click waiting 1 s


def test_a_finished_runs_page_leads_with_its_verdict_and_fits_the_window(site) -> None:
    b = site["browser"]
    b.set_window_size(1400, 1000)
    try:
        b.get(f"{site['base']}/runs/{site['run']}")
        _wait(b, "return document.body.dataset.ready && document.querySelector('table.results tbody tr')")
        top = b.execute_script("return document.getElementById('verdict').getBoundingClientRect().bottom")
        height = b.execute_script("return window.innerHeight")
        assert 0 < top <= height, (top, height)
        assert "PART" in b.find_element("id", "verdict").text
        fits = b.execute_script("const t = document.querySelector('table.results');"
                                "return [t.scrollWidth, t.parentElement.clientWidth]")
        assert fits[0] <= fits[1], fits
        assert not b.execute_script("return document.getElementById('live-panel').open")   # the spent panel folded
    finally:
        b.set_window_size(1300, 1500)


def test_a_page_whose_server_is_gone_says_so_and_turns_its_controls_off(site, tmp_path) -> None:
    """A server stopped under an open page: the page says so and disables STOP and
    INTERRUPT; when a server answers again on that address, the banner goes and they are back."""
    import uvicorn

    from ita.web.app import create_app

    b = site["browser"]
    run_id = _running_run(site["runs"], 5)
    port = _free_port()

    def serve():
        server = uvicorn.Server(uvicorn.Config(create_app(site["runs"]), host="127.0.0.1", port=port,
                                               log_level="warning", timeout_graceful_shutdown=1))
        thread = threading.Thread(target=server.run, daemon=True)
        thread.start()
        deadline = time.monotonic() + 20
        while not server.started and time.monotonic() < deadline:
            time.sleep(0.05)
        return server, thread

    server, thread = serve()
    try:
        b.get(f"http://127.0.0.1:{port}/runs/{run_id}")
        _wait(b, "return !document.getElementById('btn-stop').disabled", 30)
        assert b.execute_script("return document.getElementById('server-gone').hidden")
        server.should_exit = True
        thread.join(timeout=10)
        _wait(b, "return !document.getElementById('server-gone').hidden", 20)
        assert "not answering" in b.find_element("id", "server-gone").text
        assert b.find_element("id", "btn-stop").get_attribute("disabled")
        assert b.find_element("id", "btn-interrupt").get_attribute("disabled")
        server, thread = serve()
        _wait(b, "return document.getElementById('server-gone').hidden", 30)
        _wait(b, "return !document.getElementById('btn-stop').disabled", 10)
    finally:
        server.should_exit = True
        thread.join(timeout=10)


def _fault_run(runs: Path) -> tuple[str, str]:
    """A run with a diagnosis (two tests, the posterior at each node, a cause, a recovery)
    and a result whose plan has a partial order."""
    from ita.archive import Event

    specs = fake_specs(30)
    with Archive.open(archive_path(runs)) as a:
        rid = record_synthetic_run(a, specs, true_values(specs))
        a.record_event(rid, Event("diagnosis", "top", 50.0, {
            "spec": "s0003", "exception": "no_echo", "posterior": [["dry_couplant", 0.6], ["broken_probe", 0.4]],
            "tests": [{"test": "read_cal_block", "outcome": "no_echo", "estimated_s": 12.0, "seconds": 10.0,
                       "posterior": [["dry_couplant", 0.6], ["broken_probe", 0.4]]},
                      {"test": "swap_probe", "outcome": "ok", "estimated_s": 40.0, "seconds": 38.0,
                       "posterior": [["broken_probe", 0.7], ["dry_couplant", 0.3]]}],
            "cause": "broken_probe(us_probe_1)", "remaining": [], "recovery": "plan repair (4 steps)",
            "updates": ["world: broken(us_probe_1)"], "t0": 50.0, "t1": 98.0}))
        spec = type(specs[0])("plan-1", "web_thickness", (10.0, 10.0, 0.0), 2.5, -0.127, 0.127)
        steps = [{"n": 1, "text": "move(t3, rack, meas(plan-1))", "after": []},
                 {"n": 2, "text": "squirt(us_probe_1, couplant)", "after": [1]},
                 {"n": 3, "text": "slra_prepare(slra_1)", "after": []},
                 {"n": 4, "text": "us_measure(us_probe_1, t3, plan-1)", "after": [2, 3]}]
        path = [[1.2 + 0.01 * k, 0.1 * k, 1.5] for k in range(30)]
        a.record_result(rid, Result.measured(spec, 2.51, 0.002, tool="us_probe_1"),
                        details={"tool": "us_probe_1", "plan": {"source": "macrop", "macrop": "m3", "steps": steps},
                                 "arm_paths": [{"tcp": path, "tool": "us_probe_1", "name": "move", "cmd": "7.1"},
                                               {"tcp": path[::-1], "tool": "us_probe_1", "name": "move", "cmd": "7.4"}]})
    return rid, "plan-1"


def test_the_components_graphics_are_drawn_for_a_fault_run(site) -> None:
    """The Sequence Planner's tours on the part, the Exception Handler's test tree of each
    diagnosis (tests, outcomes, the posterior at each node, the cause, the recovery), and
    the Operation Planner's plan of a result as its partial order with its MACROP."""
    b = site["browser"]
    run_id, planned = _fault_run(site["runs"])
    b.get(f"{site['base']}/runs/{run_id}")
    _wait(b, "return document.body.dataset.ready && document.querySelector('#sec-diagnoses .dtree')")
    tree = b.find_element("css selector", "#sec-diagnoses .dtree").text
    for said in ("no echo", "read cal block", "swap probe", "broken_probe(us_probe_1)", "plan repair", "70 %"):
        assert said in tree, (said, tree)
    _wait(b, "return document.querySelector('#fig-tours .scatterlayer .trace')")
    assert len(b.find_elements("css selector", "#fig-tours .scatterlayer .trace")) >= 2      # two tools' tours
    b.get(f"{site['base']}/runs/{run_id}/results/{planned}")
    _wait(b, "return document.body.dataset.ready && document.querySelector('svg.plangraph')")
    assert len(b.find_elements("css selector", "svg.plangraph g.pstep")) == 4
    assert len(b.find_elements("css selector", "svg.plangraph line")) == 3                    # 1->2, 2->4, 3->4
    assert "MACROP m3" in b.find_element("id", "result").text
    b.get(f"{site['base']}/runs/{run_id}/paths")                   # the Path Planner's: every move of the run
    _wait(b, "return document.body.dataset.ready && document.querySelector('#fig-paths canvas')")
    assert "2 moves" in b.find_element("id", "paths").text


def test_a_two_arm_runs_page_shows_both_arms_live_and_in_3d(site, builtin_part) -> None:
    """Either arm's run of a two-arm run: the live panel lists both arms' runs, and the
    3-D view of the paths draws both arms' moves and both arms."""
    b = site["browser"]
    with Archive.open(archive_path(site["runs"])) as a:
        runs = record_two_arm_run(a, group="r20261130-110000-web2", part_dir=builtin_part.directory)
    b.get(f"{site['base']}/runs/{runs['t3_b']}")
    _wait(b, "return document.body.dataset.ready && document.getElementById('live-arms')")
    table = b.find_element("id", "live-arms").text
    assert runs["t3"] in table and runs["t3_b"] in table and "1 of 2" in table
    b.get(f"{site['base']}/runs/{runs['t3']}/paths")
    _wait(b, "return document.body.dataset.ready && document.querySelector('#fig-paths canvas')")
    drawn = b.find_element("id", "paths").text
    assert "t3: slra_1 (2 moves)" in drawn and "t3_b: slra_2 (1 moves)" in drawn and "t3_b at rest" in drawn


def _enter_three_specs(site, tmp_path) -> Path:
    """A rim-walled plate with no specs; a hole, a web and a rim picked in the editor (as a
    click on its 3-D view does) and each saved with its tolerance."""
    from user_parts import HEADER, RIM_TOP, RIM_Y, make_rim_plate

    part = make_rim_plate(tmp_path / "rim")
    (part / "specs.csv").write_text(HEADER + "\n")
    b = site["browser"]
    b.get(f"{site['base']}/parts/specs?dir={part}")
    _wait(b, "return document.body.dataset.ready && document.querySelector('#part3d .main-svg')")
    assert "No specs yet" in b.find_element("id", "spec-list").text
    picks = [((-100.0, 0.0, 2.0), "hole_diameter", "-0.1", "0.1"), ((-100.0, 50.0, 3.0), "web_thickness", "-0.127",
                                                                   "0.127"),
             ((50.0, RIM_Y - 6.0, RIM_TOP), "flange_height", "-0.25", "0.25")]
    for k, (at, kind, lower, upper) in enumerate(picks, 1):
        b.execute_script(f"ITAWeb.pickAt({list(at)})")
        _wait(b, f"return Number(document.body.dataset.picked) === {k}")
        assert b.find_element("id", "pick-kind").get_attribute("value") == kind
        assert "the arm's reach: " in b.find_element("id", "pick-where").text
        for name, value in (("lower", lower), ("upper", upper)):
            box = b.find_element("id", f"pick-{name}")
            box.clear()
            box.send_keys(value)
        b.find_element("id", "spec-save").click()
        _wait(b, f"return document.querySelectorAll('#spec-table tbody tr').length === {k}")
    return part


@pytest.mark.slow     # about 30 s: the part's calibration on its master, then the run
def test_three_specs_entered_in_the_browser_are_prepared_and_measured(site, tmp_path) -> None:
    import json

    from click.testing import CliRunner

    from ita.cli import main

    part = _enter_three_specs(site, tmp_path)
    run = CliRunner()
    assert run.invoke(main, ["prepare", "--part", str(part)]).exit_code == 0
    runs = tmp_path / "runs"
    assert run.invoke(main, ["inspect", "--part", str(part), "--runs-dir", str(runs)]).exit_code == 0
    rows = json.loads(run.invoke(main, ["results", "--runs-dir", str(runs), "last", "--json"]).output)["results"]
    assert len(rows) == 3 and all(r["value"] is not None for r in rows), rows


def test_specs_are_entered_by_pointing_at_the_part(site, tmp_path) -> None:
    """The Offline Measurement Entry in the browser: a hole, a web and a rim picked on the
    part (as a click on the 3-D view does), each saved with its tolerance to specs.csv
    (checked as `ita spec add` checks it), one undone and put back, one deleted."""
    from ita.specs.io import read_specs

    part = _enter_three_specs(site, tmp_path)
    b = site["browser"]
    specs = read_specs(part / "specs.csv")
    assert [s.kind.value for s in specs] == ["hole_diameter", "web_thickness", "flange_height"]
    assert specs[0].nominal == pytest.approx(40.0, abs=0.01) and specs[1].nominal == pytest.approx(3.0, abs=0.01)
    b.execute_script("document.querySelector('#spec-table tbody tr[data-spec^=\"HD-\"]').click()")   # edited
    upper = b.find_element("id", "pick-upper")
    upper.clear()
    upper.send_keys("0.2")
    b.find_element("id", "spec-save").click()
    _wait(b, "return document.getElementById('spec-msg').textContent.startsWith('changed')")
    assert read_specs(part / "specs.csv")[0].upper == pytest.approx(0.2)
    b.find_element("id", "spec-undo").click()                       # the edit taken back ...
    _wait(b, "return document.getElementById('spec-msg').textContent === 'undone'")
    assert read_specs(part / "specs.csv")[0].upper == pytest.approx(0.1)
    b.find_element("id", "spec-undo").click()                       # ... and the rim's height
    _wait(b, "return document.querySelectorAll('#spec-table tbody tr').length === 2")
    assert len(read_specs(part / "specs.csv")) == 2
    b.execute_script("document.querySelector('.spec-remove[data-id^=\"WT-\"]').click()")   # ... and the web deleted
    _wait(b, "return document.querySelectorAll('#spec-table tbody tr').length === 1")
    assert [s.kind.value for s in read_specs(part / "specs.csv")] == ["hole_diameter"]
    # nothing measurable there: the reason, and nothing to save
    b.execute_script("ITAWeb.pickAt([-100, 50, 0])")
    _wait(b, "return Number(document.body.dataset.picked) === 4")
    assert "faces down" in b.find_element("id", "pick-what").text
    assert b.find_element("id", "spec-save").get_attribute("disabled")
