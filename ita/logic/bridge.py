"""The Prolog bridge: the only module of ITA that imports pyswip.

Everything symbolic (world model, tool selection, operators, planner, diagnosis) lives
in the Prolog files of ``prolog/`` (engines) and ``kb/`` (knowledge).  A
:class:`KnowledgeBase` loads them all, once, and answers typed calls::

    kb = KnowledgeBase()
    kb.call("world", "type", Var("T"), "us_tool")   # [{'T': 'us_probe_1'}, {'T': 'us_probe_2'}]
    kb.once("world", "location", "slra_1", Var("W"))  # {'W': Term('in_rack', ('slot_3',))}

Arguments are Python values turned into Prolog terms as data (see ita.logic.terms):
they travel as JSON text to ``py_bridge:py_call/2``, never spliced into query text, so
an atom with quotes or spaces is just an atom.

SWI-Prolog can be initialised only once per process and has one global database, so the
engine is necessarily a process-wide singleton.  It is created on first use by
:func:`_engine` under a lock and kept out of sight; a :class:`KnowledgeBase` is the
explicit handle the rest of the code passes around.  Every query runs under the
engine's lock (pyswip's "query open" state is shared by all threads) and is closed
before the lock is released; a thread other than the one that initialised Prolog
borrows a Prolog engine for the duration of its call.
"""

from __future__ import annotations

import ctypes
import json
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ita.errors import KBLoadError, Location, PrologError, QueryLimitExceeded, QueryRefused
from ita.logic.model import Diagnostic, PredicateDoc, ProofNode, QueryResult, Severity
from ita.logic.pldoc import doc_comments
from ita.logic.terms import Str, Term, Var, from_json, to_json
from ita.paths import resource_dir

__all__ = ["KnowledgeBase", "KBLoadFailed", "check_sources"]

# The engine modules the bridge itself needs, loaded from the package's prolog/ dir.
_BRIDGE_FILES = ("py_bridge.pl", "kb_query.pl", "kb_explain.pl", "kb_check.pl")
_BRIDGE_MODULES = frozenset(Path(f).stem for f in _BRIDGE_FILES)

# SWI-Prolog.h constants used with PL_get_nchars / PL_put_chars.
_PL_STRING = 6
_CVT_STRING = 0x0002
_BUF_STACK = 0x00010000
_REP_UTF8 = 0x00100000
_PL_Q_NODEBUG = 0x0004
_PL_Q_CATCH_EXCEPTION = 0x0008


class KBLoadFailed(KBLoadError):
    """Loading failed; `diagnostics` also holds the warnings seen while loading."""

    def __init__(self, diagnostics: Sequence[Diagnostic]):
        self.diagnostics = tuple(diagnostics)
        super().__init__(
            [(d.location, d.message) for d in self.diagnostics if d.severity is Severity.ERROR]
        )


class _Engine:
    """The process's SWI-Prolog, reached only through ``py_bridge:py_call/2``."""

    def __init__(self) -> None:
        from pyswip import core  # the one pyswip import of the project (initialises Prolog)

        self._core = core
        self._lock = threading.RLock()
        lib = core._lib
        self._get_nchars = lib.PL_get_nchars
        self._get_nchars.argtypes = [
            ctypes.c_size_t,  # term_t
            ctypes.POINTER(ctypes.c_size_t),
            ctypes.POINTER(ctypes.c_char_p),
            ctypes.c_uint,
        ]
        self._get_nchars.restype = ctypes.c_int
        self._destroy_engine = lib.PL_thread_destroy_engine
        self._destroy_engine.restype = ctypes.c_int
        self._bootstrap()

    def _bootstrap(self) -> None:
        """Load the bridge's own Prolog files; fail loudly if they did not load."""
        core = self._core
        for name in _BRIDGE_FILES:
            path = resource_dir("prolog") / name
            fid = core.PL_open_foreign_frame()
            try:
                args = core.PL_new_term_refs(2)
                core.PL_put_atom_chars(args, str(path))
                core.PL_put_nil(args + 1)
                pred = core.PL_predicate("load_files", 2, "system")
                core.PL_call_predicate(None, _PL_Q_NODEBUG | _PL_Q_CATCH_EXCEPTION, pred, args)
            finally:
                core.PL_discard_foreign_frame(fid)
        try:
            reply = self.request({"module": "system", "name": "true", "args": [], "limit": 1})
        except PrologError as exc:
            raise KBLoadError(
                [(Location(str(resource_dir("prolog") / _BRIDGE_FILES[0])), str(exc))]
            ) from exc
        if reply != {"solutions": [{}]}:
            raise KBLoadError([(Location(str(resource_dir("prolog") / _BRIDGE_FILES[0])),
                                f"bridge self-test failed: {reply!r}")])

    def request(self, payload: dict[str, Any]) -> dict[str, Any]:
        """Send one request to ``py_bridge:py_call/2`` and return its decoded response."""
        text = json.dumps(payload).encode("utf-8")
        with self._lock:
            borrowed = self._core.PL_thread_self() == -1
            if borrowed and self._core.PL_thread_attach_engine(None) < 0:
                raise PrologError("py_call", "cannot attach a Prolog engine to this thread")
            try:
                return json.loads(self._call(text))
            finally:
                if borrowed:
                    self._destroy_engine()

    def _call(self, text: bytes) -> str:
        core = self._core
        fid = core.PL_open_foreign_frame()
        try:
            args = core.PL_new_term_refs(2)
            core.PL_put_chars(args, _PL_STRING | _REP_UTF8, len(text), text)
            pred = core.PL_predicate("py_call", 2, "py_bridge")
            qid = core.PL_open_query(None, _PL_Q_NODEBUG | _PL_Q_CATCH_EXCEPTION, pred, args)
            try:
                if not core.PL_next_solution(qid):
                    raise PrologError("py_bridge:py_call/2", "the bridge call failed or raised")
                length = ctypes.c_size_t()
                chars = ctypes.c_char_p()
                flags = _CVT_STRING | _REP_UTF8 | _BUF_STACK
                if not self._get_nchars(args + 1, ctypes.byref(length), ctypes.byref(chars), flags):
                    raise PrologError("py_bridge:py_call/2", "the bridge returned no text")
                return ctypes.string_at(chars, length.value).decode("utf-8")
            finally:
                core.PL_cut_query(qid)
        finally:
            core.PL_discard_foreign_frame(fid)


_ENGINE_LOCK = threading.Lock()
_ENGINE_BOX: list[_Engine] = []  # holds the one engine, once created


def _engine() -> _Engine:
    """The process-wide Prolog engine, created on first use (SWI allows only one)."""
    with _ENGINE_LOCK:
        if not _ENGINE_BOX:
            _ENGINE_BOX.append(_Engine())
        return _ENGINE_BOX[0]


def _pl_files(directory: Path) -> list[Path]:
    return sorted(p.resolve() for p in directory.glob("*.pl") if p.is_file())


def _diagnostic(term: Term) -> Diagnostic:
    kind, file, line, column, message = term.args
    return Diagnostic(Severity(kind), Location(str(file), int(line), int(column)), str(message))


def _location(file: str, line: int) -> Location | None:
    return Location(file, line) if file else None


def _proof_node(term: Term) -> ProofNode:
    kind, goal, file, line, children = term.args
    return ProofNode(
        goal=str(goal),
        kind=str(kind),
        location=_location(str(file), int(line)),
        children=tuple(_proof_node(c) for c in children),
    )


class KnowledgeBase:
    """The loaded engines (``prolog/``) and knowledge bases (``kb/``), and calls into them.

    `prolog_dir` and `kb_dir` default to the package's resource directories.  Every
    ``*.pl`` file of `prolog_dir`, then of `kb_dir`, is loaded once per process.  A
    syntax or load error in any of them raises :class:`KBLoadFailed` (a
    :class:`~ita.errors.KBLoadError`) naming file, line and column, and unloads the
    files again.  Because SWI-Prolog has one database per process, two knowledge bases
    that define the same module cannot be loaded into one process; load such a variant
    in a subprocess.
    """

    def __init__(self, prolog_dir: Path | None = None, kb_dir: Path | None = None):
        self._engine = _engine()
        self.prolog_dir = Path(prolog_dir) if prolog_dir else resource_dir("prolog")
        self.kb_dir = Path(kb_dir) if kb_dir else resource_dir("kb")
        self.engine_files = tuple(_pl_files(self.prolog_dir))
        self.kb_files = tuple(_pl_files(self.kb_dir))
        diagnostics = self._load(self.engine_files + self.kb_files)
        if any(d.severity is Severity.ERROR for d in diagnostics):
            raise KBLoadFailed(diagnostics)
        #: warnings (singletons, discontiguous clauses...) seen while loading
        self.load_warnings: tuple[Diagnostic, ...] = tuple(diagnostics)
        self.kb_modules = self._modules(self.kb_files)
        self.engine_modules = self._modules(self.engine_files)

    # -- generic calls -------------------------------------------------------------

    def call(self, module: str, name: str, *args: Any, limit: int | None = None) -> list[dict[str, Any]]:
        """All solutions (at most `limit`) of ``module:name(args...)``.

        Each solution maps the name of every :class:`Var` among `args` (except names
        starting with ``_``) to its value.  Raises :class:`~ita.errors.PrologError`
        when the goal raises.
        """
        if limit is not None and limit < 1:
            raise ValueError(f"limit must be positive, got {limit}")
        reply = self._engine.request(
            {"module": module, "name": name, "args": [to_json(a) for a in args], "limit": limit}
        )
        if "error" in reply:
            raise PrologError(reply.get("goal") or f"{module}:{name}/{len(args)}", reply["error"])
        return [{k: from_json(v) for k, v in s.items()} for s in reply["solutions"]]

    def once(self, module: str, name: str, *args: Any) -> dict[str, Any] | None:
        """The first solution of ``module:name(args...)``, or None when it fails."""
        solutions = self.call(module, name, *args, limit=1)
        return solutions[0] if solutions else None

    def holds(self, module: str, name: str, *args: Any) -> bool:
        """True when ``module:name(args...)`` has a solution."""
        return self.once(module, name, *args) is not None

    # -- the kb commands -----------------------------------------------------------

    def run_user_query(
        self,
        text: str,
        limit: int = 100,
        time_limit: float = 10.0,
        inference_limit: int = 10_000_000,
    ) -> QueryResult:
        """Run a goal typed by a person, safely (sandbox, scratch module, limits).

        Raises :class:`~ita.errors.QueryRefused` for a syntax error or an unsafe goal,
        :class:`~ita.errors.QueryLimitExceeded` when a limit stops it, and
        :class:`~ita.errors.PrologError` when the goal raises an error.
        """
        options = self._limits(time_limit, inference_limit) + [Term("limit", (int(limit),))]
        result = self._user_goal("kb_query", "run_query", text, options)
        names, rows, truncated = result.args
        return QueryResult(
            goal=text,
            variables=tuple(str(n) for n in names),
            rows=tuple(tuple(str(v) for v in row) for row in rows),
            truncated=truncated == "true",
        )

    def explain(
        self,
        text: str,
        max_depth: int = 30,
        time_limit: float = 10.0,
        inference_limit: int = 10_000_000,
    ) -> ProofNode | None:
        """The proof tree of the first solution of a user goal, or None when it fails.

        The root is the goal as solved (kind ``query``); predicates of ``kb/`` are
        expanded clause by clause, everything else is a leaf.  Same safety and errors
        as :meth:`run_user_query`.
        """
        options = self._limits(time_limit, inference_limit) + [Term("max_depth", (int(max_depth),))]
        result = self._user_goal("kb_explain", "explain_query", text, options)
        if result == "no_proof":
            return None
        return _proof_node(result.args[0])

    def check(self) -> list[Diagnostic]:
        """Warnings of the load, and calls to predicates that are defined nowhere."""
        modules = list(self.engine_modules + self.kb_modules)
        solution = self.once("kb_check", "undefined_calls", modules, Var("U"))
        found = list(self.load_warnings)
        for entry in solution["U"] if solution else []:
            callee, caller, file, line = entry.args
            found.append(
                Diagnostic(
                    Severity.ERROR,
                    Location(str(file), int(line)),
                    f"{_indicator(callee)} is called by {_indicator(caller)} but defined nowhere",
                )
            )
        return found

    def list_predicates(self) -> list[PredicateDoc]:
        """The exported predicates of each ``kb/`` file with the first line of their PlDoc."""
        docs: list[PredicateDoc] = []
        for path in self.kb_files:
            found = self.once("py_bridge", "file_module", str(path), Var("M"))
            if not found:
                continue
            module = found["M"]
            exports = self.once("system", "module_property", module, Term("exports", (Var("E"),)))
            comments = doc_comments(path)
            indicators = sorted((t.args[0], int(t.args[1])) for t in exports["E"]) if exports else []
            for name, arity in indicators:
                comment = comments.get((name, arity))
                docs.append(
                    PredicateDoc(
                        module=module,
                        name=name,
                        arity=arity,
                        file=str(path),
                        mode=comment.mode if comment else "",
                        summary=comment.summary if comment else "",
                    )
                )
        return docs

    # -- helpers -------------------------------------------------------------------

    def _load(self, files: Sequence[Path]) -> list[Diagnostic]:
        solution = self.once("py_bridge", "load_source_files", [str(f) for f in files], Var("D"))
        return [_diagnostic(t) for t in solution["D"]] if solution else []

    def _modules(self, files: Sequence[Path]) -> tuple[str, ...]:
        modules = []
        for path in files:
            found = self.once("py_bridge", "file_module", str(path), Var("M"))
            if found:
                modules.append(found["M"])
        return tuple(modules)

    @staticmethod
    def _limits(time_limit: float, inference_limit: int) -> list[Term]:
        if time_limit <= 0 or inference_limit <= 0:
            raise QueryRefused("limits must be positive")
        return [
            Term("time_limit", (float(time_limit),)),
            Term("inference_limit", (int(inference_limit),)),
        ]

    def _user_goal(self, module: str, name: str, text: str, options: list[Term]) -> Any:
        """Run a user-goal predicate and turn its refusals and limits into exceptions."""
        if name == "explain_query":
            modules = list(self.kb_modules)  # the modules whose clauses a proof expands
        else:
            modules = list(self.kb_modules) + [
                m for m in self.engine_modules if m not in _BRIDGE_MODULES
            ]
        solution = self.once(module, name, Str(text), modules, options, Var("R"))
        if solution is None:
            raise PrologError(text, f"{module}:{name}/4 failed")
        result = solution["R"]
        if isinstance(result, Term) and len(result.args) == 1:
            reason = str(result.args[0])
            if result.name == "refused":
                raise QueryRefused(reason)
            if result.name == "limit_exceeded":
                raise QueryLimitExceeded(reason)
            if result.name == "error":
                raise PrologError(text, reason)
        return result


def _indicator(term: Any) -> str:
    """``m:name/arity`` from a decoded ``:(m, /(name, arity))`` term."""
    if isinstance(term, Term) and term.name == ":":
        return f"{term.args[0]}:{_indicator(term.args[1])}"
    if isinstance(term, Term) and term.name == "/":
        return f"{term.args[0]}/{term.args[1]}"
    return str(term)


def check_sources(prolog_dir: Path | None = None, kb_dir: Path | None = None) -> list[Diagnostic]:
    """Load the knowledge bases and return every problem found, errors included.

    Unlike :class:`KnowledgeBase`, this does not raise on a load error: it returns the
    errors and warnings of the load (and, when the load succeeded, the calls to
    undefined predicates), sorted by file and line.
    """
    try:
        found = KnowledgeBase(prolog_dir, kb_dir).check()
    except KBLoadFailed as exc:
        found = list(exc.diagnostics)
    return sorted(found, key=lambda d: (d.location.file, d.location.line, d.location.column))
