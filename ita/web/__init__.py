"""The System Monitor as a web application: `ita serve`.

:mod:`~ita.web.app` (the Starlette app: pages, API, live stream, exports),
:mod:`~ita.web.guard` (its walls: Host, Origin, body size, one-line errors),
:mod:`~ita.web.bodies` (the API's request bodies, checked), :mod:`~ita.web.server`
(uvicorn with its limits and a prompt stop), :mod:`~ita.web.pages` (the HTML shells),
:mod:`~ita.web.runner` (runs started from the page, as `ita inspect` / `ita continue`
child processes), `static/web.js` (page glue).  The views are :mod:`ita.report`'s, so
the report and the monitor show the same.
"""
