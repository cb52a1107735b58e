/* ITA: the views of a run, drawn from the JSON that ita.report.sections makes.
 * Shared by the self-contained HTML report (data inlined) and `ita serve` (data fetched).
 * Needs plotly.js (window.Plotly), which ships with the package; loads nothing else.
 */
(function () {
  "use strict";
  const ITA = {};
  const DIGITS = 4;

  function esc(s) {
    return String(s === null || s === undefined ? "" : s).replace(/[&<>"']/g, (c) => (
      { "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
  }
  function num(x, d) {
    if (x === null || x === undefined || Number.isNaN(x)) return "";
    return Number(x).toFixed(d === undefined ? DIGITS : d);
  }
  function signed(x, d) {
    if (x === null || x === undefined) return "";
    const s = num(x, d);
    return x >= 0 ? "+" + s : s;
  }
  function label(s) { return String(s || "").replace(/_/g, " "); }
  function chip(colour) { return `<span class="chip" style="background:${colour}"></span>`; }
  function h(tag, attrs, html) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    if (html !== undefined) e.innerHTML = html;
    return e;
  }
  function table(header, rows, numeric) {
    const nums = new Set(numeric || []);
    let out = "<table><thead><tr>" + header.map((c) => `<th>${esc(c)}</th>`).join("") + "</tr></thead><tbody>";
    for (const r of rows) {
      out += "<tr>" + r.map((c, i) => `<td${nums.has(i) ? ' class="num"' : ""}>${esc(c)}</td>`).join("") + "</tr>";
    }
    return '<div class="scroll">' + out + "</tbody></table></div>";   // a wide table scrolls, the page does not
  }
  ITA.esc = esc;
  ITA.num = num;

  ITA.plot = function (div, fig, opts) {
    if (!window.Plotly || !fig) { div.textContent = "(charts need plotly.js)"; return null; }
    const config = Object.assign({ responsive: true, displaylogo: false, scrollZoom: true }, opts || {});
    div.classList.add("plot");
    return window.Plotly.newPlot(div, fig.data, fig.layout, config);
  };

  /* ------------------------------------------------------------ tolerance bar */
  ITA.toleranceBar = function (r, width) {
    const W = width || 140, H = 16, pad = 10;
    if (r.low_limit === null || r.high_limit === null) return "";
    const band = r.high_limit - r.low_limit;
    if (!(band > 0)) return "";
    const lo = r.low_limit - 0.5 * band, hi = r.high_limit + 0.5 * band;
    const X = (v) => pad + (W - 2 * pad) * (Math.min(Math.max(v, lo), hi) - lo) / (hi - lo);
    let s = `<svg width="${W}" height="${H}" viewBox="0 0 ${W} ${H}" role="img" aria-label="tolerance">`;
    s += `<rect x="${pad}" y="6" width="${W - 2 * pad}" height="4" fill="#eee"/>`;
    s += `<rect x="${X(r.low_limit)}" y="4" width="${X(r.high_limit) - X(r.low_limit)}" height="8" fill="#cfe8cf" stroke="#7fb07f"/>`;
    s += `<line x1="${X(r.nominal)}" x2="${X(r.nominal)}" y1="2" y2="14" stroke="#555" stroke-width="1"/>`;
    if (r.value !== null && r.value !== undefined) {
      const colour = { conforms: "#2ca02c", does_not_conform: "#d62728", uncertain: "#ff9f1c" }[r.decision] || "#333";
      if (r.U !== null) {
        s += `<line x1="${X(r.value - r.U)}" x2="${X(r.value + r.U)}" y1="8" y2="8" stroke="${colour}" stroke-width="2"/>`;
        s += `<line x1="${X(r.value - r.U)}" x2="${X(r.value - r.U)}" y1="4" y2="12" stroke="${colour}"/>`;
        s += `<line x1="${X(r.value + r.U)}" x2="${X(r.value + r.U)}" y1="4" y2="12" stroke="${colour}"/>`;
      }
      s += `<circle cx="${X(r.value)}" cy="8" r="3.2" fill="${colour}" stroke="#000" stroke-width=".5"/>`;
    }
    return s + "</svg>";
  };

  /* ------------------------------------------------------------------- summary */
  function renderSummary(root, sec) {
    const s = sec.summary, run = sec.run;
    let html = `<div class="verdict ${esc(s.verdict)}" id="verdict">PART ${esc(s.verdict.toUpperCase())}</div>`;
    html += `<p><b>${esc(s.verdict_reason)}</b></p>`;
    html += '<div class="cards">';
    html += `<div class="card">measurements<b>${s.done} of ${s.part_total}</b>${s.part_known === false ? "the run's specs; the part's are not at hand" : s.run_total !== s.part_total ? `run set out to do ${s.run_total}` : "every spec of the part"}</div>`;
    html += `<div class="card">simulated cycle time<b>${num(s.cycle_h, 3)} h</b>${num(s.cycle_s, 1)} s</div>`;
    if (s.complete) {
      html += `<div class="card">manual method (${s.manual_h} h)<b>${num(s.speedup_manual, 1)}x faster</b></div>`;
      html += `<div class="card">goal of 1987 (${s.goal_h} h)<b>${s.ratio_goal <= 1 ? "met" : "not met"}</b>${num(s.ratio_goal, 2)} of the goal time</div>`;
    } else {
      html += `<div class="card">rate<b>${s.rate_s === null ? "-" : num(s.rate_s, 1) + " s"}</b>simulated per measurement</div>`;
      html += `<div class="card">whole part, extrapolated<b>${s.projected_h === null ? "-" : num(s.projected_h, 2) + " h"}</b>not measured: this run covered ${s.done} of ${s.part_total} specs</div>`;
    }
    html += "</div>";
    if (!s.complete) {
      html += `<p class="note">No comparison with the manual method (${s.manual_h} h) or the 1987 goal (${s.goal_h} h): ` +
        "those compare whole-part inspections, and this run is not one.</p>";
    }
    html += "<h3>Results by decision</h3><table><tr><th>decision</th><th>results</th></tr>";
    for (const k of sec.order) {
      html += `<tr><td>${chip(sec.colours[k])}${esc(label(k))}</td><td class="num">${s.counts[k] || 0}</td></tr>`;
    }
    html += "</table>";
    if (s.missing_count) html += `<p class="note">${s.missing_count} spec(s) of the part have no result` +
      (s.missing.length ? ` (first: ${esc(s.missing.slice(0, 12).join(", "))}${s.missing_count > 12 ? ", ..." : ""})` : "") + ".</p>";
    const meta = [["run", run.id], ["part", run.part], ["part directory", run.part_dir], ["seed", run.seed],
      ["status", run.status], ["created (UTC)", run.created], ["ended (UTC)", run.ended]].filter((kv) => kv[1] !== null && kv[1] !== undefined);
    html += "<h3>Run</h3>" + table(["", ""], meta.concat(sec.settings || []));
    if (sec.alignment && sec.alignment.length) {
      html += "<h3>Alignment: the part located on its datums</h3>" +
        table(["simulated time", "when", "registration"], sec.alignment);
    }
    root.insertAdjacentHTML("beforeend", html);
  }

  /* ------------------------------------------------------------- results table */
  const TABLE_COLUMNS = [
    ["seq", "#", "num"], ["spec_id", "spec", "id"], ["kind", "kind"], ["tool", "tool"],
    ["nominal", "nominal (mm)", "num"], ["value", "measured (mm)", "num"], ["deviation", "deviation (mm)", "num"],
    ["lower", "tolerance (mm)", "tol"], ["position_in_band", "value and U in the tolerance", "bar"],
    ["U", "U (mm)", "num"], ["U_over_tolerance", "U / tolerance", "pct"], ["decision", "decision", "dec"],
    ["reason", "reason", "reason"]];

  const ROWS_PER_CHUNK = 120;
  ITA.resultsTable = function (root, sec, opts) {
    opts = opts || {};
    const rows = sec.rows.slice();
    const colours = sec.colours;
    const kinds = [...new Set(rows.map((r) => r.kind).filter(Boolean))].sort();
    const tools = [...new Set(rows.map((r) => r.tool).filter(Boolean))].sort();
    const decisions = Object.keys(colours).filter((d) => rows.some((r) => r.decision === d));
    const f = h("div", { class: "filters" });
    f.innerHTML = '<input type="search" placeholder="filter: spec, kind, tool, reason" aria-label="filter">' +
      '<select data-f="decision"><option value="">every decision</option>' +
      decisions.map((d) => `<option value="${d}">${esc(label(d))}</option>`).join("") + "</select>" +
      '<select data-f="kind"><option value="">every kind</option>' + kinds.map((k) => `<option>${esc(k)}</option>`).join("") + "</select>" +
      '<select data-f="tool"><option value="">every tool</option>' + tools.map((k) => `<option>${esc(k)}</option>`).join("") + "</select>" +
      '<label><input type="checkbox" data-f="failed"> only not proven to conform</label>' +
      '<label>sort by <select data-sort="1" aria-label="sort by"><option value="seq">order measured</option>' +
      '<option value="abs_deviation">|deviation|, largest first</option>' +
      '<option value="deviation_over_tolerance">deviation / tolerance, largest first</option></select></label>' +
      ' <span class="count note"></span>';
    root.appendChild(f);
    const t = h("table", { class: "results" });
    t.innerHTML = "<thead><tr>" + TABLE_COLUMNS.map((c) => `<th data-key="${c[0]}" tabindex="0" aria-sort="none" ` +
      `title="sort by ${esc(c[1])} (Enter)">${esc(c[1])}</th>`).join("") + "</tr></thead><tbody></tbody>";
    // derived keys: |deviation| and the deviation over half the tolerance band (1: at a limit)
    for (const r of rows) {
      r.abs_deviation = r.deviation === null || r.deviation === undefined ? null : Math.abs(r.deviation);
      const half = (r.upper - r.lower) / 2, mid = (r.upper + r.lower) / 2;
      r.deviation_over_tolerance = r.abs_deviation === null || !(half > 0) ? null : Math.abs(r.deviation - mid) / half;
    }
    const scroller = h("div", { class: "scroll" });
    scroller.appendChild(t);
    root.appendChild(scroller);
    let sortKey = "seq", sortDir = 1, drawing = 0;
    const state = { text: "", decision: "", kind: "", tool: "", failed: false };
    function cell(r, c) {
      const v = r[c[0]];
      switch (c[2]) {
        case "num": return `<td class="num">${c[0] === "seq" ? v : num(v, c[0] === "deviation" ? DIGITS : DIGITS)}</td>`;
        case "id": {
          const href = opts.resultHref ? opts.resultHref(r.spec_id) : null;
          return `<td>${href ? `<a href="${esc(href)}">${esc(v)}</a>` : esc(v)}</td>`;
        }
        case "tol": return `<td class="num">${signed(r.lower)} / ${signed(r.upper)}</td>`;
        case "bar": return `<td>${ITA.toleranceBar(r, 110)}</td>`;
        case "pct": return `<td class="num">${v === null || v === undefined ? "" : (100 * v).toFixed(1) + " %"}</td>`;
        case "dec": return `<td class="dec">${chip(colours[r.decision] || "#000")}${esc(label(r.decision))}</td>`;
        case "reason": return `<td class="reason">${esc(v)}</td>`;
        default: return `<td>${esc(v)}</td>`;
      }
    }
    function draw() {
      const text = state.text.toLowerCase();
      const shown = rows.filter((r) => (!state.decision || r.decision === state.decision) &&
        (!state.kind || r.kind === state.kind) && (!state.tool || r.tool === state.tool) &&
        (!state.failed || r.decision !== "conforms") &&
        (!text || [r.spec_id, r.kind, r.tool, r.reason, r.decision].join(" ").toLowerCase().includes(text)));
      shown.sort((a, b) => {
        const x = a[sortKey], y = b[sortKey];
        if (x === y) return a.seq - b.seq;
        if (x === null || x === undefined) return 1;
        if (y === null || y === undefined) return -1;
        return (x < y ? -1 : 1) * sortDir;
      });
      // the rows a chunk at a time, the page given back between chunks (a whole run's table
      // never keeps a click on STOP waiting); a newer draw stops an older one
      const mine = ++drawing;
      const body = t.tBodies[0];
      body.innerHTML = "";
      let at = 0;
      const chunk = () => {
        if (mine !== drawing) return;
        body.insertAdjacentHTML("beforeend", shown.slice(at, at + ROWS_PER_CHUNK).map((r) =>
          `<tr class="st-${r.decision}" data-spec="${esc(r.spec_id)}">` + TABLE_COLUMNS.map((c) => cell(r, c)).join("") +
          "</tr>").join(""));
        at += ROWS_PER_CHUNK;
        if (at < shown.length) setTimeout(chunk, 0);
      };
      chunk();
      f.querySelector(".count").textContent = `${shown.length} of ${rows.length} results shown`;
      t.querySelectorAll("th").forEach((th) => {
        const on = th.dataset.key === sortKey;
        th.classList.toggle("sorted-asc", on && sortDir > 0);
        th.classList.toggle("sorted-desc", on && sortDir < 0);
        th.setAttribute("aria-sort", on ? (sortDir > 0 ? "ascending" : "descending") : "none");
      });
      const by = f.querySelector("select[data-sort]");
      if (by) by.value = ["abs_deviation", "deviation_over_tolerance"].includes(sortKey) ? sortKey : "seq";
    }
    f.querySelector("input[type=search]").addEventListener("input", (e) => { state.text = e.target.value; draw(); });
    f.querySelectorAll("select[data-f]").forEach((s) => s.addEventListener("change", (e) => { state[e.target.dataset.f] = e.target.value; draw(); }));
    f.querySelector("input[type=checkbox]").addEventListener("change", (e) => { state.failed = e.target.checked; draw(); });
    function sortOn(th) {
      const key = th.dataset.key === "position_in_band" ? "deviation" : th.dataset.key;
      if (sortKey === key) sortDir = -sortDir; else { sortKey = key; sortDir = 1; }
      draw();
    }
    t.querySelectorAll("th").forEach((th) => {
      th.addEventListener("click", () => sortOn(th));
      th.addEventListener("keydown", (e) => {
        if (e.key === "Enter" || e.key === " ") { e.preventDefault(); sortOn(th); }
      });
    });
    f.querySelector("select[data-sort]").addEventListener("change", (e) => {
      sortKey = e.target.value;
      sortDir = sortKey === "seq" ? 1 : -1;
      draw();
    });
    if (opts.onRow) t.tBodies[0].addEventListener("click", (e) => {
      const tr = e.target.closest("tr");
      if (tr && e.target.tagName !== "A") opts.onRow(tr.dataset.spec);
    });
    draw();
    return { draw, state };
  };

  /* -------------------------------------------------------------------- events */
  // the Operation Planner's plan as its partial order: a step in the column after the
  // steps it waits for (left to right), an arrow from each of them; the MACROP it came from
  function planGraph(plan) {
    const steps = plan.steps || [];
    if (!steps.length) return "";
    const level = {};
    const byN = Object.fromEntries(steps.map((s) => [s.n, s]));
    const depth = (n, seen) => {
      if (level[n] !== undefined) return level[n];
      if (seen.has(n)) return 0;
      seen.add(n);
      const after = (byN[n] && byN[n].after) || [];
      level[n] = after.length ? 1 + Math.max(...after.map((a) => depth(a, seen))) : 0;
      return level[n];
    };
    steps.forEach((s) => depth(s.n, new Set()));
    const columns = {};
    const pos = {};
    const W = 190, H = 46, BW = 170, BH = 34;
    steps.forEach((s) => {
      const c = level[s.n];
      columns[c] = (columns[c] || 0) + 1;
      pos[s.n] = [10 + c * W, 10 + (columns[c] - 1) * H];
    });
    const width = 20 + (Math.max(...Object.keys(columns).map(Number)) + 1) * W;
    const height = 20 + Math.max(...Object.values(columns)) * H;
    let svg = `<svg class="plangraph" role="img" aria-label="the plan's partial order" width="${width}" height="${height}" ` +
      `viewBox="0 0 ${width} ${height}"><defs><marker id="arr" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="6" markerHeight="6" orient="auto"><path d="M0,0L10,5L0,10z" fill="#667"/></marker></defs>`;
    steps.forEach((s) => (s.after || []).forEach((a) => {
      if (!pos[a]) return;
      const [x1, y1] = pos[a], [x2, y2] = pos[s.n];
      svg += `<line x1="${x1 + BW}" y1="${y1 + BH / 2}" x2="${x2}" y2="${y2 + BH / 2}" stroke="#667" marker-end="url(#arr)"/>`;
    }));
    steps.forEach((s) => {
      const [x, y] = pos[s.n];
      const text = String(s.text || "");
      svg += `<g class="pstep"><title>${esc(s.n + ": " + text)}</title><rect x="${x}" y="${y}" width="${BW}" height="${BH}" rx="5" fill="#f6fbff" stroke="#8aa"/>` +
        `<text x="${x + 6}" y="${y + 14}" font-size="11"><tspan font-weight="600">${esc(s.n)}</tspan> ${esc(text.split("(")[0].slice(0, 22))}</text>` +
        `<text x="${x + 6}" y="${y + 28}" font-size="10" fill="#555">${esc(text.slice(text.indexOf("(") + 1, text.indexOf("(") + 30))}</text></g>`;
    });
    return `<div class="scroll">${svg}</svg></div>`;
  }

  // one diagnosis as the branch of the test tree it took: nodes (the posterior there) and
  // edges (the test chosen, its outcome), ending on the cause and the recovery
  function posteriorText(post) {
    return (post || []).slice(0, 3).map((cp) => `${esc(cp[0])} ${(100 * cp[1]).toFixed(0)} %`).join("<br>");
  }
  function diagnosisTree(d) {
    const tests = d.tests || [];
    let html = `<div class="dtree" data-spec="${esc(d.spec)}"><div class="dnode dexc"><b>${esc(label(d.exception))}</b>` +
      `<small>${esc(d.spec)} · ${num(d.sim_time, 1)} s${d.during ? ` · met while handling ${esc(label(d.during))}` : ""}</small>` +
      `<span class="dpost">${posteriorText(tests.length && tests[0].posterior && tests[0].posterior.length ? tests[0].posterior : d.posterior)}</span></div>`;
    tests.forEach((t, i) => {
      const after = i + 1 < tests.length ? tests[i + 1].posterior : null;
      html += `<div class="dedge">test <b>${esc(label(t.test))}</b><small>est. ${num(t.estimated_s, 0)} s, took ${num(t.seconds, 0)} s</small>` +
        `<span class="dout">&rarr; ${esc(label(t.outcome))}</span></div>`;
      if (after && after.length) html += `<div class="dnode">${posteriorText(after)}</div>`;
    });
    const end = d.cause ? `cause <b>${esc(d.cause)}</b>` :
      `no single cause${(d.remaining || []).length ? ": " + posteriorText(d.remaining) : ""}`;
    html += `<div class="dnode dend">${end}<small>recovery: ${esc(d.recovery || "none")}</small></div></div>`;
    return html;
  }

  // an event a person reads as a sentence (null: shown field by field)
  function sentence(kind, p) {
    if (kind === "diagnosis") {
      const tests = (p.tests || []).map((t) => `${label(t.test)} found ${label(t.outcome)}`).join(", then ");
      const found = p.cause ? `the cause is ${p.cause}` : "no single cause was isolated" +
        ((p.remaining || []).length ? ` (still possible: ${p.remaining.map((c) => c[0]).join(", ")})` : "");
      return `${label(p.exception)}${p.during ? ` (met while handling ${label(p.during)})` : ""}: ` +
        `${tests ? tests + "; " : "no test was needed; "}${found}. Recovery: ${p.recovery || "none"}.`;
    }
    if (kind === "exception") return `${p.kind === "timeout" ? "timeout" : "exception"}: ${p.message || ""}`;
    if (kind === "recovery") return `recovery${p.cause ? " from " + p.cause : ""}: ${p.how || ""}`;
    return null;
  }

  function eventsTable(events) {
    if (!events.length) return "<p>No events.</p>";
    const first = ["message", "diagnosis", "recovery", "reason", "how"];
    let out = '<table class="events"><tr><th>#</th><th>sim time (s)</th><th>kind</th><th>stream</th><th>spec</th><th>what it recorded</th></tr>';
    for (const e of events) {
      const p = e.payload || {};
      const said = sentence(e.kind, p);
      const keys = Object.keys(p).sort((a, b) => (first.indexOf(a) + 1 || 99) - (first.indexOf(b) + 1 || 99));
      const what = said !== null ? esc(said) :
        keys.map((k) => `<b>${esc(k)}</b>: ${esc(typeof p[k] === "object" ? JSON.stringify(p[k]) : p[k])}`).join("; ");
      out += `<tr><td class="num">${e.seq ?? ""}</td><td class="num">${num(e.sim_time, 2)}</td><td>${esc(label(e.kind))}</td>` +
        `<td>${esc(e.stream)}</td><td>${esc(e.spec_id)}</td><td>${what}</td></tr>`;
    }
    return out + "</table>";
  }
  ITA.eventsTable = eventsTable;

  /* ------------------------------------------------------------------ sections */
  ITA.renderSection = function (root, sec, opts) {
    opts = opts || {};
    const wrap = h(sec.kind === "scoring" ? "section" : "div", { id: "sec-" + sec.id, class: sec.kind === "scoring" ? "scoring" : "sec" });
    root.appendChild(wrap);
    wrap.appendChild(h("h2", {}, esc(sec.title)));
    if (sec.note && sec.kind !== "events") wrap.appendChild(h("p", { class: "note" }, esc(sec.note)));
    switch (sec.kind) {
      case "summary": renderSummary(wrap, sec); break;
      case "results": ITA.resultsTable(wrap, sec, opts); break;
      case "figure": {
        const div = h("div", { id: "fig-" + sec.id });
        wrap.appendChild(div);
        const p = ITA.plot(div, sec.figure);
        if (sec.clickable && opts.resultHref && p) p.then((gd) => gd.on("plotly_click", (ev) => {
          const spec = ev.points && ev.points[0] && ev.points[0].customdata;
          if (spec) window.location.href = opts.resultHref(spec);
        }));
        if (sec.rows) wrap.insertAdjacentHTML("beforeend", table(["", "", ""], sec.rows, [1, 2]));
        if (sec.table) {
          const t = table(sec.table.header, sec.table.rows, []);
          wrap.insertAdjacentHTML("beforeend", sec.table.rows.length > 12 ? `<details><summary>${sec.table.rows.length} rows</summary>${t}</details>` : t);
        }
        break;
      }
      case "diagnoses": {
        const shown = sec.trees.slice(0, 20).map(diagnosisTree).join("");
        const rest = sec.trees.slice(20).map(diagnosisTree).join("");
        wrap.insertAdjacentHTML("beforeend", shown + (rest ? `<details><summary>${sec.trees.length - 20} more</summary>${rest}</details>` : ""));
        break;
      }
      case "events":
        wrap.insertAdjacentHTML("beforeend", `<p class="note">${esc(sec.note)}</p>` + eventsTable(sec.events));
        break;
      case "kv": {
        if (sec.note) wrap.insertAdjacentHTML("beforeend", `<p class="note">${esc(sec.note)}</p>`);
        const t = table(sec.header || ["", ""], sec.rows, []);
        wrap.insertAdjacentHTML("beforeend", sec.collapsed ? `<details><summary>${sec.rows.length} rows</summary>${t}</details>` : t);
        break;
      }
      case "scoring": {
        wrap.insertAdjacentHTML("beforeend", table(["", ""], sec.rows, [1]));
        wrap.insertAdjacentHTML("beforeend", "<h3>Decision against the truth</h3>" +
          table(["decision", "truly in tolerance", "truly out of tolerance"], sec.confusion, [1, 2]));
        if (sec.figure) {
          wrap.appendChild(h("h3", {}, "Measurement error, per kind"));
          const div = h("div", { id: "fig-scoring" });
          wrap.appendChild(div);
          ITA.plot(div, sec.figure);
        }
        if (sec.wrong && sec.wrong.length) wrap.insertAdjacentHTML("beforeend", "<h3>Wrong decisions</h3>" +
          table(["spec", "decision", "value (mm)", "true (mm)", "U (mm)"], sec.wrong, [2, 3, 4]));
        break;
      }
      default:
        wrap.insertAdjacentHTML("beforeend", `<p>${esc(sec.text || "")}</p>`);
    }
    return wrap;
  };

  ITA.renderSections = function (root, sections, opts) {
    for (const sec of sections) ITA.renderSection(root, sec, opts);
  };
  // the same, giving the page back between sections (a click on STOP is handled between
  // them, not after a whole run's report has been drawn); `stale()` true: stop drawing
  ITA.renderSectionsAsync = async function (root, sections, opts, stale) {
    for (const sec of sections) {
      await new Promise((resolve) => setTimeout(resolve, 0));
      if (stale && stale()) return false;
      ITA.renderSection(root, sec, opts);
    }
    return true;
  };

  /* --------------------------------------------------------------- one result */
  ITA.renderResult = function (root, d, opts) {
    opts = opts || {};
    const r = d.row;
    let html = `<h1>${esc(r.spec_id)} <span class="meta">${esc(r.kind)} · ${esc(r.tool || "")}</span></h1>`;
    html += `<p>${chip(d.colours[r.decision])}<b>${esc(label(r.decision))}</b>` +
      (r.value !== null ? ` · measured ${num(r.value)} mm, U ${num(r.U)} mm (k = ${r.k}) · nominal ${num(r.nominal)} mm, ` +
        `tolerance ${signed(r.lower)} / ${signed(r.upper)} mm · deviation ${signed(r.deviation)} mm` : "") + "</p>";
    html += `<p>${ITA.toleranceBar(r, 360)}</p>`;
    if (r.reason) html += `<p><b>reason:</b> ${esc(r.reason)}</p>`;
    if (d.details && d.details.frame_of) html += `<p class="note">Measured in the frame taken for <a href="${esc(opts.resultHref ? opts.resultHref(d.details.frame_of) : "#")}">${esc(d.details.frame_of)}</a> (same SLRA view group).</p>`;
    root.insertAdjacentHTML("beforeend", html);
    if (d.range_figure) {
      root.appendChild(h("h2", {}, "Range image, with what Vision fitted"));
      const div = h("div", { id: "fig-range" });
      root.appendChild(div);
      ITA.plot(div, d.range_figure);
      const v = (d.details || {}).vision || {};
      if (v.numbers) root.insertAdjacentHTML("beforeend", table(["Vision", ""], Object.entries(v.numbers).map(([k, x]) => [label(k), typeof x === "number" && !Number.isInteger(x) ? num(x, 5) : x]), [1]));
    } else if (d.frame_note) {
      root.appendChild(h("p", { class: "note" }, esc(d.frame_note)));
    }
    const g = (d.details || {}).gauge;
    if (g) {
      root.appendChild(h("h2", {}, "Gauge reading"));
      root.insertAdjacentHTML("beforeend", table(["", ""], Object.entries(g).filter((kv) => kv[1] !== null).map(([k, x]) => [label(k), typeof x === "number" ? num(x, 5) : x]), [1]));
    }
    const plan = (d.details || {}).plan;
    if (plan) {
      root.appendChild(h("h2", {}, "Plan"));
      root.insertAdjacentHTML("beforeend", `<p class="note">source: ${esc(plan.source)}${plan.macrop ? `, MACROP ${esc(plan.macrop)}` : ""}; ${plan.steps.length} steps</p>` +
        planGraph(plan) +
        table(["step", "action", "after steps"], plan.steps.map((s) => [s.n, s.text, (s.after || []).join(", ")]), [0]));
    }
    if (d.timeline_figure) {
      root.appendChild(h("h2", {}, "Timeline of the plan"));
      const div = h("div", { id: "fig-plan-gantt" });
      root.appendChild(div);
      ITA.plot(div, d.timeline_figure);
    }
    if (d.workcell_figure) {
      root.appendChild(h("h2", {}, "The arm's path in the workcell"));
      root.appendChild(h("p", { class: "note" }, "The tool point's path of every arm command of the plan, as flown (world frame, m); the arm drawn where the plan left it."));
      const div = h("div", { id: "fig-workcell" });
      root.appendChild(div);
      ITA.plot(div, d.workcell_figure);
    }
    root.appendChild(h("h2", {}, "Events"));
    root.insertAdjacentHTML("beforeend", eventsTable(d.events || []));
  };

  /* ----------------------------------------------------------------- live view */
  ITA.renderLive = function (root, s, opts) {
    opts = opts || {};
    const frac = s.total ? s.done / s.total : 0;
    const fmt = (x) => {
      if (x === null || x === undefined) return "-";
      x = Math.round(x);
      return `${Math.floor(x / 3600)}:${String(Math.floor(x % 3600 / 60)).padStart(2, "0")}:${String(x % 60).padStart(2, "0")}`;
    };
    let html = `<div><b id="live-state">${esc(s.state)}</b> · <span id="live-done">${s.done}</span> of ${s.total ?? "?"} results` +
      ` · simulated ${fmt(s.sim_s)} · wall ${fmt(s.wall_s)}` + (s.eta_wall_s === null || s.eta_wall_s === undefined ? "" : ` · left ~${fmt(s.eta_wall_s)} wall, ~${fmt(s.eta_sim_s)} simulated`) + "</div>";
    html += `<div class="progress"><div style="width:${(100 * frac).toFixed(1)}%"></div></div>`;
    const c = s.current || {};
    html += `<p>current: group <b>${c.group === null || c.group === undefined ? "-" : c.group + 1}</b>, tool <b>${esc(c.tool || "-")}</b>, ` +
      `measurement <b id="live-current">${esc(c.spec || "-")}</b>${s.next ? ` · next in the plan: ${esc(s.next)}` : ""}</p>`;
    html += "<p>" + Object.entries(s.counts || {}).map(([k, n]) => `${chip((opts.colours || {})[k] || "#000")}${esc(label(k))} ${n}`).join(" &nbsp; ") + "</p>";
    if (s.arms && s.arms.length) {
      html += '<h3>Both arms</h3><table class="results" id="live-arms"><tr><th>arm</th><th>run</th><th>state</th><th>results</th><th>simulated</th><th>at</th></tr>' +
        s.arms.map((a) => `<tr><td>${esc(a.arm)}${a.handover ? " (hand-over)" : ""}</td><td>${opts.runHref ? `<a href="${esc(opts.runHref(a.run))}">${esc(a.run)}</a>` : esc(a.run)}</td>` +
          `<td>${esc(a.state)}</td><td class="num">${a.done} of ${a.total ?? "?"}</td><td class="num">${fmt(a.sim_s)}</td><td>${esc(a.current || "-")}</td></tr>`).join("") + "</table>";
    }
    if (s.last && s.last.length) {
      html += "<h3>Last results</h3>" + '<table class="results"><tr><th>#</th><th>spec</th><th>kind</th><th>measured (mm)</th><th>U (mm)</th><th>decision</th><th>reason</th></tr>' +
        s.last.map((r) => `<tr class="st-${r.decision}"><td class="num">${r.seq}</td><td>${opts.resultHref ? `<a href="${esc(opts.resultHref(r.spec_id))}">${esc(r.spec_id)}</a>` : esc(r.spec_id)}</td>` +
          `<td>${esc(r.kind)}</td><td class="num">${num(r.value)}</td><td class="num">${num(r.U)}</td>` +
          `<td class="dec">${chip((opts.colours || {})[r.decision] || "#000")}${esc(label(r.decision))}</td><td>${esc(r.reason)}</td></tr>`).join("") + "</table>";
    }
    if (s.exceptions && s.exceptions.length) {
      const counted = s.exception_counts ? s.exception_counts.text : `${s.exception_count} exceptions`;
      html += `<h3 id="live-exceptions">Exceptions: ${esc(counted)}</h3>` +
        (s.exceptions.length < s.exception_count ? `<p>the last ${s.exceptions.length}:</p>` : "") + eventsTable(s.exceptions.slice(-10));
    }
    if (s.log) html += `<details><summary>process output</summary><pre>${esc(s.log)}</pre></details>`;
    root.innerHTML = html;
  };

  window.ITA = ITA;
})();
