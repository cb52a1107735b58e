"""The System Monitor's web application (Starlette): pages, a JSON API, a live stream.

    app = create_app(runs_dir, host="127.0.0.1")    # served by `ita serve` (ita.web.server)

Pages: `/` runs (and a form to start one), `/runs/{id}` a run (live view, controls,
results table, 3-D part, Gantt chart, events), `/runs/{id}/results/{spec}` one result
(range image with Vision's fit, gauge reading, plan, events, timeline, arm path),
`/runs/{id}/scoring` the scoring against the as-built part (simulated runs only, on its
own page).  API under `/api/`; `/api/runs/{id}/live` is a server-sent event stream.
Exports: `/runs/{id}/results.csv|json`, `/runs/{id}/report.html|pdf`.  Scripts are
served from the package (`/assets/`): no page loads anything from elsewhere.

What the server refuses (:mod:`ita.web.guard`, in front of every route): a request whose
`Host` is not `127.0.0.1`, `localhost` or `[::1]` (or the `--host` address, or the
address the connection reached) with the server's port, or that has no `Host` (421: DNS
rebinding gets nothing); a POST whose `Origin` is another site's (403); a body over 1 MB
(413, by its Content-Length before a byte is read, or as soon as a chunked one passes it).
A POST must also carry the header `X-ITA: 1` (403 otherwise), which a page of another site
cannot send without this server's consent (it gives none).  A body must be a JSON object
of the request's fields, each of its type and range (:mod:`ita.web.bodies`; 400 naming the
field and what it may hold).  The project's errors (a damaged archive, an unknown run)
are answered with their one line (400, 404 or 409); anything unexpected with a one-line
500 and one line in the server's log, never a traceback.  No knowledge-base query is
offered.
"""

from __future__ import annotations

import asyncio
import csv
import io
import json
import logging
import re
import threading
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import (
    FileResponse,
    HTMLResponse,
    JSONResponse,
    Response,
    StreamingResponse,
)
from starlette.routing import Route

from ita import report
from ita.archive import (
    Archive,
    ArchiveError,
    NoArchive,
    RunInfo,
    UnknownRun,
    archive_path,
)
from ita.archive.exceptions import ExceptionCounts
from ita.errors import InputError, ItaError
from ita.report.assets import asset_path
from ita.report.data import (
    COLUMNS,
    STATUS_COLOURS,
    arm_runs,
    collect,
    jsonable,
    result_row,
    run_verdict,
)
from ita.report.live import live_state
from ita.report.paths import run_paths_figure
from ita.report.result import result_payload
from ita.report.scene import PartScene
from ita.report.sections import report_payload
from ita.scoring import truth as scoring_truth
from ita.spc import chart_all, design_series
from ita.spc.page import spc_sections
from ita.specs.model import MeasurementKind
from ita.web import pages
from ita.web.bodies import (
    BadRequest,
    control_command,
    json_object,
    spec_count,
    start_request,
)
from ita.web.guard import LOG, Guard, printable
from ita.web.parts import Editor
from ita.web.runner import Processes

ASSETS = {"plotly.min.js": "application/javascript", "ita.js": "application/javascript",
          "ita.css": "text/css", "web.js": "application/javascript"}
LIVE_POLL_S = 1.0
LIVE_KEEPALIVE_S = 15.0
STOP_CHECK_S = 0.1      # how often a live stream looks whether the server is stopping
RUN_ID = re.compile(r"[A-Za-z0-9_.-]{1,80}", re.ASCII)


class State:
    """What the app keeps between requests: the runs directory, its child processes, the
    part scenes it loaded, recent report payloads, whether the server is stopping.  One
    per app, shared by its threads."""

    def __init__(self, runs_dir: Path) -> None:
        self.runs_dir = Path(runs_dir)
        self.procs = Processes(self.runs_dir)
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._scenes: dict[str, Any] = {}
        self._payloads: dict[str, tuple[str, Any]] = {}
        self.editor = Editor()

    def stop(self) -> None:
        """The server is stopping: live streams end now (uvicorn waits for them)."""
        self.stopping.set()

    def archive(self) -> Archive:
        """A fresh connection (each request thread its own); NoArchive when no run yet."""
        return Archive.open(archive_path(self.runs_dir), create=False)

    def scene(self, part_dir: str | None) -> Any:
        """The part scene of a run's part directory (loaded once); None when unreadable."""
        if not part_dir:
            return None
        with self._lock:
            if part_dir in self._scenes:
                return self._scenes[part_dir]
        try:
            scene = PartScene.load(part_dir) if Path(part_dir).is_dir() else None
        except Exception:  # noqa: BLE001 - a run whose part cannot be read is still shown, without it
            scene = None
        with self._lock:
            self._scenes[part_dir] = scene
        return scene

    def payload(self, run_id: str, key: str, make: Any) -> Any:
        with self._lock:
            hit = self._payloads.get(run_id)
            if hit is not None and hit[0] == key:
                return hit[1]
        value = make()
        with self._lock:
            if len(self._payloads) > 8:
                self._payloads.clear()
            self._payloads[run_id] = (key, value)
        return value


def _json(obj: Any, status: int = 200) -> JSONResponse:
    return JSONResponse(jsonable(obj), status_code=status)


def _error(message: str, status: int) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


def _state(request: Request) -> State:
    return request.app.state.ita


def _checked(request: Request) -> JSONResponse | None:
    if request.headers.get("x-ita") != "1":
        return _error("a request that changes something needs the header X-ITA: 1", 403)
    return None


def _run_id(request: Request) -> str:
    """The run id of the path; UnknownRun (404) for one no run could have."""
    run_id = request.path_params["run"]
    if not RUN_ID.fullmatch(run_id):
        raise UnknownRun(f"no run {printable(run_id, 80)!r}")
    return run_id


async def _body(request: Request) -> dict[str, Any]:
    """The request's JSON object (the guard has capped its size); BadRequest otherwise."""
    return json_object(await request.body())


def error_status(exc: ItaError) -> int:
    """The status the project's error answers: 400 a bad request, 404 an unknown run or no
    archive, 409 anything else (the archive or the run cannot do it now, or is damaged)."""
    if isinstance(exc, (BadRequest, InputError)):
        return 400
    if isinstance(exc, (UnknownRun, NoArchive)):
        return 404
    return 409


def _one_line(exc: Exception) -> str:
    return printable((str(exc).strip().splitlines() or [type(exc).__name__])[0], 300)


async def ita_error(request: Request, exc: Exception) -> JSONResponse:
    """An ItaError raised while serving: its one line (the first of its message), no
    traceback; one line in the server's log when it is not the request's fault."""
    status = error_status(exc) if isinstance(exc, ItaError) else 500
    line = _one_line(exc)
    if status >= 409:
        logging.getLogger(LOG).warning("%s %s: %s", request.method, printable(request.url.path), line)
    return _error(line, status)


# ------------------------------------------------------------------------------ pages
async def page_runs(request: Request) -> HTMLResponse:
    return HTMLResponse(pages.runs_page())


async def page_run(request: Request) -> HTMLResponse:
    return HTMLResponse(pages.run_page(_run_id(request)))


async def page_result(request: Request) -> HTMLResponse:
    return HTMLResponse(pages.result_page(_run_id(request), request.path_params["spec"]))


async def page_part_specs(request: Request) -> HTMLResponse:
    directory = await run_in_threadpool(Editor.part_dir, request.query_params.get("dir"))
    return HTMLResponse(pages.part_specs_page(str(directory)))


async def api_part_specs(request: Request) -> JSONResponse:
    """The editor's part (GET) or a change to its specs (POST: add, edit, remove, undo)."""
    state = _state(request)
    directory = await run_in_threadpool(Editor.part_dir, request.query_params.get("dir"))
    if request.method == "POST":
        bad = _checked(request)
        if bad:
            return bad
        body = await _body(request)
        return _json(await run_in_threadpool(state.editor.change, directory, body))
    return _json(await run_in_threadpool(state.editor.view, directory))


async def api_part_pick(request: Request) -> JSONResponse:
    """A spec proposed at the clicked point (ita.part.pick)."""
    q = request.query_params
    directory = await run_in_threadpool(Editor.part_dir, q.get("dir"))
    return _json(await run_in_threadpool(Editor.pick, directory, q.get("at"), q.get("kind")))


async def page_paths(request: Request) -> HTMLResponse:
    return HTMLResponse(pages.paths_page(_run_id(request)))


async def api_paths(request: Request) -> JSONResponse:
    """Every arm move of the run in the workcell (ita.report.paths)."""
    state, run_id = _state(request), _run_id(request)

    def make(archive: Archive) -> Any:
        rid, info, key = _as_now(archive, run_id)
        scene = state.scene(info.part_dir)
        # a run of a two-arm run draws every arm's runs: a new move of any of them redraws
        key += "".join(f":{r}={archive.run(r).done}" for _arm, r in arm_runs(archive, rid) if r != rid)
        return state.payload(rid + ":paths", f"paths:{key}", lambda: jsonable(run_paths_figure(archive, rid, scene) or {
            "moves": 0, "note": "the run kept no arm path (a run from before they were kept, or none moved)"}))

    out = await run_in_threadpool(_with_archive, state, make)
    return _json(out) if out is not None else _error("no archive yet", 404)


async def page_spc(request: Request) -> HTMLResponse:
    return HTMLResponse(pages.spc_page())


#: the Benjamini-Hochberg level of the SPC page (as `ita spc`'s default)
SPC_Q = 0.05


async def api_spc(request: Request) -> JSONResponse:
    """SPC across serials of one design: ?part=NAME (default: the first design with serials),
    ?kind=KIND, ?id=SPEC (a characteristic to chart).  Unknown values are a 400 naming them."""
    params = request.query_params
    kind, part, chosen = params.get("kind") or None, params.get("part") or None, params.get("id") or None
    if kind is not None and kind not in {k.value for k in MeasurementKind}:
        return _error(f"kind: not a measurement kind: {printable(kind)}", 400)

    def make(archive: Archive) -> Any:
        designs = sorted({r.part for r in archive.runs() if isinstance(r.settings.get("serial"), str)})
        name = part if part is not None else (designs[0] if designs else None)
        if name is None:
            return {"parts": [], "part": None, "sections": [], "note": "No runs with a serial number yet "
                                                                        "(ita inspect --serial SN)."}
        if name not in designs:
            return {"error": f"part: no runs with a serial of {printable(name)}"}
        serials, series = design_series(archive, name, kind)
        charts = chart_all(series, q=SPC_Q)
        if chosen is not None and chosen not in {c.series.id for c in charts}:
            return {"error": f"id: no characteristic {printable(chosen)} charted for {name}"}
        return {"parts": designs, "part": name, "sections": spc_sections(name, serials, charts, SPC_Q, chosen)}

    out = await run_in_threadpool(_with_archive, _state(request), make)
    if out is None:
        return _error("no archive yet", 404)
    if "error" in out:
        return _error(out["error"], 400)
    return _json(out)


async def page_scoring(request: Request) -> HTMLResponse:
    return HTMLResponse(pages.scoring_page(_run_id(request)))


async def asset(request: Request) -> Response:
    name = request.path_params["name"]
    if name not in ASSETS:
        return Response("not found", status_code=404)
    path = pages.web_asset(name) if name == "web.js" else asset_path(name)
    return FileResponse(path, media_type=ASSETS[name], headers={"Cache-Control": "max-age=300"})


# -------------------------------------------------------------------------------- API
def _runs(state: State) -> list[dict[str, Any]]:
    try:
        archive = state.archive()
    except NoArchive:
        return []
    with archive:
        return [{"id": r.id, "part": r.part, "part_dir": r.part_dir, "seed": r.seed, "state": r.state_label,
                 "done": r.done, "total": r.total, "sim_time": r.sim_time, "created": r.created, "ended": r.ended,
                 "running": r.status.value == "running" and r.alive is not False,
                 "continuable": r.state_label in ("interrupted", "stopped", "dead", "failed"),
                 "verdict": run_verdict(r), "serial": r.settings.get("serial"), "operator": r.settings.get("operator")}
                for r in reversed(archive.runs())]


async def api_runs(request: Request) -> JSONResponse:
    state = _state(request)
    if request.method == "POST":
        bad = _checked(request)
        if bad:
            return bad
        body = await _body(request)
        start = await run_in_threadpool(start_request, body, spec_count)
        run_id = await run_in_threadpool(state.procs.start_inspect, limit=start.limit, seed=start.seed,
                                         part=start.part, faults=start.faults, serial=start.serial,
                                         operator=start.operator, inject=start.inject)
        return _json({"run": run_id, "started": True}, 201)
    return _json(await run_in_threadpool(_runs, state))


def _with_archive(state: State, fn: Any) -> Any:
    try:
        archive = state.archive()
    except NoArchive:
        return None
    with archive:
        return fn(archive)


async def api_control(request: Request) -> JSONResponse:
    bad = _checked(request)
    if bad:
        return bad
    state, run_id = _state(request), _run_id(request)
    command = control_command(await _body(request))

    def act(archive: Archive) -> JSONResponse:
        rid = archive.resolve(run_id)
        if command == "CONTINUE":
            info = archive.run(rid)
            if info.state_label not in ("interrupted", "stopped", "dead", "failed"):
                return _error(f"run {rid} is {info.state_label}: nothing to continue", 409)
            state.procs.continue_run(rid)
            return _json({"run": rid, "sent": command})
        request_id = archive.issue_control(rid, command)
        return _json({"run": rid, "sent": command, "request": request_id})

    try:
        out = await run_in_threadpool(_with_archive, state, act)
    except RuntimeError as exc:
        return _error(str(exc), 409)
    return out if out is not None else _error("no archive yet", 404)


#: the report's views on a run's page; LIGHT_VIEWS while the run goes (no 3-D part or
#: timeline: they are redrawn when it ends; the tours mark the next measurement)
REPORT_VIEWS = ("summary", "results", "part3d", "gantt", "breakdown", "events", "diagnoses", "tours")
LIGHT_VIEWS = ("summary", "results", "events", "tours")


def _as_now(archive: Archive, run_id: str) -> tuple[str, RunInfo, str]:
    """The run's id, its info and a key that changes whenever anything of it does (a
    cached view is good while the key stands)."""
    rid = archive.resolve(run_id)
    info = archive.run(rid)
    last = archive.events(rid, last=1)
    return rid, info, f"{info.status.value}:{info.done}:{last[0].seq if last else 0}"


def _report(state: State, run_id: str, light: bool = False) -> Any:
    def make(archive: Archive) -> Any:
        rid, info, now = _as_now(archive, run_id)
        key = f"{now}:{light}"
        scene = state.scene(info.part_dir)

        def build() -> Any:
            data = collect(archive, rid, scene.specs if scene is not None else None)
            payload = report_payload(data, mesh=None if scene is None else scene.mesh,
                                     only=LIGHT_VIEWS if light else REPORT_VIEWS)
            payload["scoring_available"] = _truth_dir(info) is not None
            return jsonable(payload)

        return state.payload(rid, key, build)

    return _with_archive(state, make)


def _truth_dir(info: RunInfo) -> Path | str | None:
    """The part directory of a simulated run whose part has true values to score against, else None."""
    source = scoring_truth.run_part_truth(info.part_dir, dict(info.settings))
    if bool(info.settings.get("simulated", True)) and scoring_truth.has_true_values(source):
        return source
    return None


async def api_report(request: Request) -> JSONResponse:
    light = request.query_params.get("light") == "1"
    payload = await run_in_threadpool(_report, _state(request), _run_id(request), light)
    return _json(payload) if payload is not None else _error("no archive yet", 404)


async def api_scoring(request: Request) -> JSONResponse:
    state, run_id = _state(request), _run_id(request)

    def make(archive: Archive) -> Any:
        rid = archive.resolve(run_id)
        info = archive.run(rid)
        part_dir = _truth_dir(info)
        if part_dir is None:
            return {"run": rid, "sections": [], "note": "This run has no as-built truth to score against."}
        scene = state.scene(info.part_dir)
        data = collect(archive, rid, scene.specs if scene is not None else None)
        return report_payload(data, true_values=scoring_truth.true_values(part_dir), only=("scoring",),
                              injected=scoring_truth.injected_faults(archive.path.parent, rid))

    out = await run_in_threadpool(_with_archive, state, make)
    return _json(out) if out is not None else _error("no archive yet", 404)


async def api_result(request: Request) -> JSONResponse:
    state, run_id, spec = _state(request), _run_id(request), request.path_params["spec"]

    def make(archive: Archive) -> Any:
        rid = archive.resolve(run_id)
        info = archive.run(rid)
        return result_payload(archive, rid, spec, scene=state.scene(info.part_dir))

    out = await run_in_threadpool(_with_archive, state, make)
    return _json(out) if out is not None else _error(f"no result {spec} in run {run_id}", 404)


def _live(state: State, run_id: str) -> dict[str, Any]:
    def make(archive: Archive) -> dict[str, Any]:
        try:
            rid = archive.resolve(run_id)
        except ArchiveError:       # not (yet) in the archive, or an ambiguous prefix
            return {}
        return live_state(archive, rid)

    out = _with_archive(state, make) or {}
    if not out:        # started here, still loading the system (or it failed before the run existed)
        code = state.procs.exit_code(run_id)
        starting = state.procs.running(run_id)
        out = {"run": run_id, "state": "starting" if starting else ("failed to start" if code else "unknown"),
               "running": starting, "done": 0, "total": None, "counts": {}, "current": {}, "last": [],
               "exceptions": [], "exception_count": 0, "exception_counts": ExceptionCounts().to_dict(),
               "sim_s": None, "wall_s": None, "eta_wall_s": None,
               "eta_sim_s": None, "key": f"starting:{starting}:{code}"}
    out["log"] = state.procs.log_tail(run_id) if state.procs.log_path(run_id).exists() else ""
    out["continuable"] = out["state"] in ("interrupted", "stopped", "dead", "failed")
    out["key"] = out["key"] + f":{len(out['log'])}"
    return out


async def _pause(state: State, seconds: float) -> None:
    """Sleep `seconds`, or less when the server begins to stop."""
    loop = asyncio.get_running_loop()
    end = loop.time() + seconds
    while not state.stopping.is_set() and (left := end - loop.time()) > 0:
        await asyncio.sleep(min(STOP_CHECK_S, left))


async def api_live(request: Request) -> StreamingResponse:
    """Server-sent events: the run's live state whenever it changes (polled every second),
    a comment line every LIVE_KEEPALIVE_S otherwise, a `problem` event with one line when
    the archive cannot be read; the stream ends when the server stops (so Ctrl-C does not
    wait for the page)."""
    state, run_id = _state(request), _run_id(request)

    async def stream() -> Any:
        key, quiet = None, 0.0
        while not state.stopping.is_set() and not await request.is_disconnected():
            try:
                now = await run_in_threadpool(_live, state, run_id)
            except ItaError as exc:     # a damaged archive, say: said once, looked at again next second
                now = {"key": f"error:{exc}", "error": _one_line(exc)}
            if now["key"] != key:
                key, quiet = now["key"], 0.0
                kind = "problem" if "error" in now else "state"
                yield f"event: {kind}\ndata: {json.dumps(jsonable(now))}\n\n"
            elif quiet >= LIVE_KEEPALIVE_S:
                quiet = 0.0
                yield ": keep-alive\n\n"
            await _pause(state, LIVE_POLL_S)
            quiet += LIVE_POLL_S

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})


async def api_live_once(request: Request) -> JSONResponse:
    return _json(await run_in_threadpool(_live, _state(request), _run_id(request)))


# ----------------------------------------------------------------------------- exports
async def export(request: Request) -> Response:
    state, run_id, what = _state(request), _run_id(request), request.path_params["what"]

    def make(archive: Archive) -> Response:
        rid = archive.resolve(run_id)
        if what in ("results.csv", "results.json"):
            rows = [result_row(r) for r in archive.results(rid)]
            if what == "results.json":
                return JSONResponse(jsonable({"run": rid, "columns": list(COLUMNS), "results": rows}))
            buf = io.StringIO()
            w = csv.DictWriter(buf, fieldnames=list(COLUMNS), lineterminator="\n")
            w.writeheader()
            for row in rows:
                w.writerow({k: ("" if v is None else v) for k, v in row.items()})
            return Response(buf.getvalue(), media_type="text/csv",
                            headers={"Content-Disposition": f'attachment; filename="{rid}-results.csv"'})
        info = archive.run(rid)
        scene = state.scene(info.part_dir)
        truth = None
        part_dir = _truth_dir(info)
        if part_dir is not None:
            truth = scoring_truth.true_values(part_dir)
        if what == "report.pdf":
            return Response(report.build_pdf(archive, rid, true_values=truth, scene=scene),
                            media_type="application/pdf",
                            headers={"Content-Disposition": f'attachment; filename="{rid}-report.pdf"'})
        return HTMLResponse(report.build_report(archive, rid, true_values=truth, scene=scene),
                            headers={"Content-Disposition": f'attachment; filename="{rid}-report.html"'})

    if what not in ("results.csv", "results.json", "report.html", "report.pdf"):
        return _error("no such export", 404)
    out = await run_in_threadpool(_with_archive, state, make)
    return out if out is not None else _error("no archive yet", 404)


def create_app(runs_dir: Path | str, host: str | None = None) -> Starlette:
    """The System Monitor over the archive in `runs_dir`, behind its walls
    (:class:`~ita.web.guard.Guard`): it answers requests that name 127.0.0.1,
    localhost or [::1], or `host` (the address `ita serve --host` listens on)."""
    routes = [
        Route("/", page_runs),
        Route("/runs/{run}", page_run),
        Route("/runs/{run}/results/{spec}", page_result),
        Route("/runs/{run}/scoring", page_scoring),
        Route("/runs/{run}/paths", page_paths),
        Route("/api/runs/{run}/paths", api_paths),
        Route("/spc", page_spc),
        Route("/parts/specs", page_part_specs),
        Route("/api/parts/specs", api_part_specs, methods=["GET", "POST"]),
        Route("/api/parts/pick", api_part_pick),
        Route("/api/spc", api_spc),
        Route("/runs/{run}/{what:str}", export),
        Route("/assets/{name}", asset),
        Route("/api/runs", api_runs, methods=["GET", "POST"]),
        Route("/api/runs/{run}/control", api_control, methods=["POST"]),
        Route("/api/runs/{run}/report", api_report),
        Route("/api/runs/{run}/scoring", api_scoring),
        Route("/api/runs/{run}/results/{spec}", api_result),
        Route("/api/runs/{run}/live", api_live),
        Route("/api/runs/{run}/state", api_live_once),
    ]
    app = Starlette(routes=routes, middleware=[Middleware(Guard, host=host)],
                    exception_handlers={ItaError: ita_error})
    app.state.ita = State(Path(runs_dir))
    app.state.colours = STATUS_COLOURS
    return app
