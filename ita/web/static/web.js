/* ITA System Monitor: the page glue of `ita serve` (fetches the API, streams the live
 * view, sends STOP / INTERRUPT / CONTINUE).  The views themselves are ita.js. */
(function () {
  "use strict";
  const W = {};
  const enc = encodeURIComponent;
  const resultHref = (run) => (spec) => `/runs/${enc(run)}/results/${enc(spec)}`;

  async function getJSON(url) {
    const r = await fetch(url, { cache: "no-store" });
    const body = await r.json();
    if (!r.ok) throw new Error(body.error || r.statusText);
    return body;
  }
  async function post(url, body) {
    const r = await fetch(url, { method: "POST", headers: { "Content-Type": "application/json", "X-ITA": "1" }, body: JSON.stringify(body || {}) });
    const out = await r.json();
    if (!r.ok) throw new Error(out.error || r.statusText);
    return out;
  }

  W.runsPage = async function () {
    const root = document.getElementById("runs");
    async function draw() {
      const runs = await getJSON("/api/runs");
      if (!runs.length) { root.innerHTML = "<p>No runs yet.</p>"; return; }
      root.innerHTML = '<table class="results" id="runs-table"><tr><th>run</th><th>part</th><th>status</th><th>done</th><th>simulated</th><th>started (UTC)</th><th>verdict</th><th>serial</th><th>operator</th></tr>' +
        runs.map((r) => `<tr><td><a href="/runs/${enc(r.id)}">${ITA.esc(r.id)}</a></td><td>${ITA.esc(r.part)}</td>` +
          `<td>${ITA.esc(r.state)}</td><td class="num">${r.done}/${r.total ?? "?"}</td><td class="num">${r.sim_time === null ? "-" : ITA.num(r.sim_time, 0) + " s"}</td>` +
          `<td>${ITA.esc((r.created || "").replace("T", " ").replace("+00:00", ""))}</td>` +
          `<td>${ITA.esc(r.verdict)}</td><td>${ITA.esc(r.serial || "-")}</td><td>${ITA.esc(r.operator || "-")}</td></tr>`).join("") + "</table>";
    }
    await draw();
    setInterval(draw, 5000);
    document.getElementById("start").addEventListener("submit", async (e) => {
      e.preventDefault();
      const f = new FormData(e.target);
      const msg = document.getElementById("start-msg");
      try {
        const out = await post("/api/runs", { part: f.get("part"), limit: f.get("limit"), seed: f.get("seed"),
                                                serial: f.get("serial"), operator: f.get("operator"),
                                                faults: f.get("faults"), inject: f.get("inject") });
        window.location.href = `/runs/${enc(out.run)}`;
      } catch (err) { msg.textContent = err.message; msg.className = "err"; }
    });
    document.body.dataset.ready = "1";
  };

  W.runPage = function (run) {
    const live = document.getElementById("live");
    const report = document.getElementById("report");
    const msg = document.getElementById("control-msg");
    const gone = document.getElementById("server-gone");
    const buttons = { STOP: "btn-stop", INTERRUPT: "btn-interrupt", CONTINUE: "btn-continue" };
    let lastState = null, drawnKey = null, drawnAt = 0, connected = true;
    document.getElementById("tabs").innerHTML =
      `exports: <a href="/runs/${enc(run)}/results.csv">results.csv</a> <a href="/runs/${enc(run)}/results.json">results.json</a> ` +
      `<a href="/runs/${enc(run)}/report.html">report.html</a> <a href="/runs/${enc(run)}/report.pdf">report.pdf</a> <span id="scoring-link"></span>` +
      ' · on this page: <a href="#sec-summary">verdict</a> <a href="#sec-results">results</a> <a href="#sec-part3d">3-D</a> ' +
      '<a href="#sec-gantt">timeline</a> <a href="#sec-events">exceptions</a> <a href="#live-panel">live</a>';
    for (const [command, id] of Object.entries(buttons)) {
      document.getElementById(id).addEventListener("click", async () => {
        msg.textContent = `${command}: sending ...`;       // said at once, before the server answers
        msg.className = "note";
        try {
          await post(`/api/runs/${enc(run)}/control`, { command });
          msg.textContent = `${command} sent`;
          msg.className = "note";
        } catch (err) { msg.textContent = `${command} not sent: ${err.message}`; msg.className = "err"; }
      });
    }
    function setButtons(s) {
      document.getElementById("btn-stop").disabled = !connected || !s || !s.running || s.state === "starting";
      document.getElementById("btn-interrupt").disabled = !connected || !s || !s.running || s.state === "starting";
      document.getElementById("btn-continue").disabled = !connected || !s || !s.continuable;
    }
    // one report request at a time; while the run goes, the light views (verdict so far,
    // results, exceptions) at most every REDRAW_S, drawn a section at a time so that the
    // controls always answer; the whole report once it has ended
    const REDRAW_S = 30;
    let drawing = false, again = false, generation = 0;
    async function drawReport(running) {
      if (drawing) { again = true; return; }
      drawing = true;
      const mine = ++generation;
      try {
        const data = await getJSON(`/api/runs/${enc(run)}/report${running ? "?light=1" : ""}`);
        const fresh = document.createElement("div");
        const done = await ITA.renderSectionsAsync(fresh, data.sections, { resultHref: resultHref(run) },
                                                   () => mine !== generation);
        if (done) { report.replaceChildren(...fresh.childNodes); }
        if (data.scoring_available) document.getElementById("scoring-link").innerHTML =
          ` · <a href="/runs/${enc(run)}/scoring">scoring against the as-built part (simulation only)</a>`;
        document.body.dataset.ready = "1";
      } catch (err) { report.innerHTML = `<p class="note">${ITA.esc(err.message)}</p>`; }
      finally {
        drawing = false;
        if (again) { again = false; drawReport(lastState ? lastState.running : false); }
      }
    }
    function verdictFirst(ended) {
      // a run that has ended leads with its verdict: the report above, the spent live panel folded below
      const panel = document.getElementById("live-panel");
      if (ended && panel.previousElementSibling !== report) {
        report.after(panel);
        panel.open = false;
      } else if (!ended && report.previousElementSibling !== panel) {
        panel.after(report);
        panel.open = true;
      }
    }
    function onState(s) {
      ITA.renderLive(live, s, { colours: { conforms: "#2ca02c", does_not_conform: "#d62728", uncertain: "#ff9f1c", not_done: "#6b6b6b", cannot_be_done: "#9467bd" }, resultHref: resultHref(run) });
      setButtons(s);
      const running = s.running || s.state === "starting";
      verdictFirst(!running && s.state !== "unknown");
      const key = `${s.state}:${s.done}`;
      const now = Date.now() / 1000;
      if (s.state !== "starting" && (drawnKey === null || (lastState && lastState.state !== s.state) ||
                                     (running && s.done !== drawnKey && now - drawnAt >= REDRAW_S))) {
        drawnKey = s.done;
        drawnAt = now;
        drawReport(running);
      }
      lastState = s;
      live.dataset.key = key;
    }
    function serverGone(isGone) {
      connected = !isGone;
      gone.hidden = !isGone;
      document.body.dataset.serverGone = isGone ? "1" : "";
      setButtons(lastState);
    }
    const source = new EventSource(`/api/runs/${enc(run)}/live`);
    source.addEventListener("state", (e) => { serverGone(false); onState(JSON.parse(e.data)); });
    source.addEventListener("open", () => serverGone(false));
    source.onerror = () => serverGone(true);      // the browser tries again on its own; the next state clears it
  };

  W.resultPage = async function (run, spec) {
    const root = document.getElementById("result");
    try {
      const d = await getJSON(`/api/runs/${enc(run)}/results/${enc(spec)}`);
      root.innerHTML = "";
      ITA.renderResult(root, d, { resultHref: resultHref(run) });
    } catch (err) { root.innerHTML = `<p class="err">${ITA.esc(err.message)}</p>`; }
    document.body.dataset.ready = "1";
  };

  W.scoringPage = async function (run) {
    const root = document.getElementById("report");
    try {
      const d = await getJSON(`/api/runs/${enc(run)}/scoring`);
      root.innerHTML = d.note ? `<p>${ITA.esc(d.note)}</p>` : "";
      ITA.renderSections(root, d.sections, {});
    } catch (err) { root.innerHTML = `<p class="err">${ITA.esc(err.message)}</p>`; }
    document.body.dataset.ready = "1";
  };

  W.spcPage = async function () {
    const root = document.getElementById("report");
    const msg = document.getElementById("spc-msg");
    const form = document.getElementById("spc-form");
    const here = new URLSearchParams(window.location.search);
    for (const k of ["kind", "id"]) if (here.get(k)) form.elements[k].value = here.get(k);
    const ask = new URLSearchParams();
    for (const k of ["part", "kind", "id"]) if (here.get(k)) ask.set(k, here.get(k));
    try {
      const d = await getJSON(`/api/spc?${ask.toString()}`);
      const select = document.getElementById("spc-part");
      select.innerHTML = d.parts.map((p) => `<option${p === d.part ? " selected" : ""}>${ITA.esc(p)}</option>`).join("");
      root.innerHTML = d.note ? `<p>${ITA.esc(d.note)}</p>` : "";
      ITA.renderSections(root, d.sections, {});
    } catch (err) { root.innerHTML = ""; msg.textContent = err.message; msg.className = "err"; }
    form.addEventListener("submit", (ev) => {
      ev.preventDefault();
      const f = new FormData(form);
      const q = new URLSearchParams();
      for (const [k, v] of f.entries()) if (String(v).trim()) q.set(k, String(v).trim());
      window.location.href = `/spc?${q.toString()}`;
    });
    document.body.dataset.ready = "1";
  };

  window.ITAWeb = W;
})();
