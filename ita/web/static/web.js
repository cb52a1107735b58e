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
      '<a href="#sec-gantt">timeline</a> <a href="#sec-events">exceptions</a> <a href="#sec-diagnoses">test trees</a> ' +
      `<a href="#sec-tours">tours</a> <a href="/runs/${enc(run)}/paths">every arm move in 3-D</a> <a href="#live-panel">live</a>`;
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
      ITA.renderLive(live, s, { colours: { conforms: "#2ca02c", does_not_conform: "#d62728", uncertain: "#ff9f1c", not_done: "#6b6b6b", cannot_be_done: "#9467bd" }, resultHref: resultHref(run), runHref: (id) => `/runs/${enc(id)}` });
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

  W.specEditor = async function (dir) {
    const q = `dir=${enc(dir)}`;
    const msg = document.getElementById("spec-msg");
    const form = document.getElementById("proposal");
    const kindSel = document.getElementById("pick-kind");
    const save = document.getElementById("spec-save");
    const undo = document.getElementById("spec-undo");
    const say = (text, err) => { msg.textContent = text; msg.className = err ? "err" : "note"; };
    let picked = null, specs = [], editing = null;
    const prefix = { hole_diameter: "HD", hole_position: "HP", edge_distance: "ED", web_thickness: "WT",
                     flange_thickness: "FT", flange_height: "FH", flange_width: "FW", stiffener_height: "SH",
                     stiffener_width: "SW" };
    function freeId(kind, feature) {
      const used = new Set(specs.map((s) => s.id));
      for (let k = 1; ; k++) {
        const id = `${prefix[kind] || "S"}-${feature}-${k}`;
        if (!used.has(id)) return id;
      }
    }
    function drawList() {
      const root = document.getElementById("spec-list");
      if (!specs.length) { root.innerHTML = "<p>No specs yet: click the part.</p>"; return; }
      root.innerHTML = '<table class="results" id="spec-table"><thead><tr><th>id</th><th>kind</th><th>feature</th><th>point (mm)</th>' +
        "<th>nominal (mm)</th><th>tolerance (mm)</th><th>datum</th><th></th></tr></thead><tbody>" +
        specs.map((s) => `<tr data-spec="${ITA.esc(s.id)}"><td>${ITA.esc(s.id)}</td><td>${ITA.esc(s.kind)}</td><td>${ITA.esc(s.feature)}</td>` +
          `<td class="num">${s.point.map((x) => ITA.num(x, 2)).join(", ")}</td><td class="num">${ITA.num(s.nominal, 4)}</td>` +
          `<td class="num">${ITA.num(s.lower, 3)} / ${ITA.num(s.upper, 3)}</td><td>${ITA.esc(s.datum)}</td>` +
          `<td><button type="button" class="spec-remove" data-id="${ITA.esc(s.id)}">delete</button></td></tr>`).join("") + "</tbody></table>";
      root.querySelectorAll(".spec-remove").forEach((b) => b.addEventListener("click", (e) => {
        e.stopPropagation();
        change({ action: "remove", id: b.dataset.id });
      }));
      root.querySelectorAll("#spec-table tbody tr").forEach((tr) => tr.addEventListener("click", () => edit(tr.dataset.spec)));
    }
    function edit(id) {          // a spec of the list into the form: its tolerance, datum, nominal, note changed
      const s = specs.find((x) => x.id === id);
      if (!s) return;
      editing = id;
      picked = { kind: s.kind, point: s.point, normal: s.normal, direction: s.direction, candidates: [s.kind] };
      kindSel.innerHTML = `<option selected>${ITA.esc(s.kind)}</option>`;
      const f = form.elements;
      f.id.value = s.id; f.feature.value = s.feature; f.nominal.value = s.nominal; f.lower.value = s.lower;
      f.upper.value = s.upper; f.datum.value = s.datum; f.note.value = s.note || "";
      document.getElementById("pick-what").textContent = `editing ${s.id} (save changes it; click the part for a new one)`;
      document.getElementById("pick-what").className = "note";
      save.disabled = false;
    }
    function drawPart(view) {
      const m = view.mesh;
      const traces = [{ type: "mesh3d", x: m.x, y: m.y, z: m.z, i: m.i, j: m.j, k: m.k, color: "#b8c4d0", opacity: 1,
                        flatshading: true, name: "part", hoverinfo: "x+y+z" },
                      { type: "scatter3d", mode: "markers", name: "specs", x: specs.map((s) => s.point[0]),
                        y: specs.map((s) => s.point[1]), z: specs.map((s) => s.point[2]), text: specs.map((s) => s.id),
                        hoverinfo: "text", marker: { size: 3, color: "#d62728" } }];
      const div = document.getElementById("part3d");
      const layout = { height: 520, margin: { l: 0, r: 0, t: 0, b: 0 }, showlegend: false,
                       scene: { aspectmode: "data", camera: { eye: { x: 0.1, y: -1.4, z: 2.0 } } } };
      if (!div.dataset.drawn) {
        Plotly.newPlot(div, traces, layout, { displaylogo: false, responsive: true });
        div.on("plotly_click", (ev) => {
          const p = ev.points && ev.points[0];
          if (p && p.data && p.data.type === "mesh3d") W.pickAt([p.x, p.y, p.z]);
        });
        div.dataset.drawn = "1";
      } else {
        Plotly.react(div, traces, layout);
      }
    }
    function show(view) {
      specs = view.specs;
      undo.disabled = !view.can_undo;
      drawList();
      drawPart(view);
    }
    async function change(body) {
      try {
        const view = await post(`/api/parts/specs?${q}`, body);
        show(view);
        say(view.done);
      } catch (err) { say(err.message, true); }
    }
    function fill(p) {
      picked = p;
      editing = null;
      const what = document.getElementById("pick-what");
      const where = document.getElementById("pick-where");
      kindSel.innerHTML = (p.candidates || []).map((k) => `<option${k === p.kind ? " selected" : ""}>${ITA.esc(k)}</option>`).join("");
      if (!p.kind) {
        what.textContent = p.what ? `${p.what}: ${p.reason}` : p.reason;
        what.className = "err";
        where.textContent = "";
        save.disabled = true;
        return;
      }
      what.textContent = p.what;
      what.className = "note";
      form.elements.feature.value = p.feature;
      form.elements.nominal.value = p.nominal;
      form.elements.id.value = freeId(p.kind, p.feature);
      if (p.kind === "hole_position") { form.elements.lower.value = "0"; form.elements.upper.value = "0.5"; }
      const reach = Object.entries(p.reach || {}).map(([c, v]) => `${c} ${v}`).join(", ");
      const none = p.reach && !Object.values(p.reach).includes("reachable");
      where.textContent = `point ${p.point.join(", ")}; normal ${p.normal.join(", ")}` + (p.direction ? `; direction ${p.direction.join(", ")}` : "") +
        (reach ? `; the arm's reach: ${reach}` : "") + (none ? " (no tool reaches it: a run would mark it cannot be done)" : "");
      where.className = none ? "err" : "note";
      save.disabled = false;
    }
    W.pickAt = async function (at, kind) {
      try {
        fill(await getJSON(`/api/parts/pick?${q}&at=${enc(at.map((x) => Number(x).toFixed(4)).join(","))}` + (kind ? `&kind=${enc(kind)}` : "")));
        document.body.dataset.picked = String(Number(document.body.dataset.picked || 0) + 1);
      } catch (err) { say(err.message, true); }
    };
    kindSel.addEventListener("change", () => { if (picked && picked.point) W.pickAt(picked.point, kindSel.value); });
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (!picked || !picked.kind) return;
      const f = form.elements;
      if (editing) {
        const id = editing;
        editing = null;
        change({ action: "edit", id, spec: { id: f.id.value, feature: f.feature.value, nominal: f.nominal.value,
                                             lower: f.lower.value, upper: f.upper.value, datum: f.datum.value,
                                             note: f.note.value } });
        return;
      }
      const spec = { id: f.id.value, kind: picked.kind, feature: f.feature.value, x: picked.point[0], y: picked.point[1],
                     z: picked.point[2], nx: picked.normal[0], ny: picked.normal[1], nz: picked.normal[2], nominal: f.nominal.value,
                     lower: f.lower.value, upper: f.upper.value, datum: f.datum.value, note: f.note.value };
      if (picked.direction) Object.assign(spec, { dx: picked.direction[0], dy: picked.direction[1], dz: picked.direction[2] });
      change({ action: "add", spec });
    });
    undo.addEventListener("click", () => change({ action: "undo" }));
    try { show(await getJSON(`/api/parts/specs?${q}`)); } catch (err) { say(err.message, true); }
    document.body.dataset.ready = "1";
  };

  W.pathsPage = async function (run) {
    const root = document.getElementById("paths");
    try {
      const d = await getJSON(`/api/runs/${enc(run)}/paths`);
      if (!d.moves) { root.innerHTML = `<p class="note">${ITA.esc(d.note || "no path")}</p>`; }
      else {
        root.innerHTML = `<p>${d.moves} moves</p><div id="fig-paths"></div>`;
        await ITA.plot(document.getElementById("fig-paths"), d.figure);
      }
    } catch (err) { root.innerHTML = `<p class="err">${ITA.esc(err.message)}</p>`; }
    document.body.dataset.ready = "1";
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
