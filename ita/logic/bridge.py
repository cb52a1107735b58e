"""The Prolog bridge: the only module of ITA that imports pyswip.

Everything symbolic (world model, tool selection, operators, planner, diagnosis) lives
in the Prolog files of ``prolog/`` (engines) and ``kb/`` (knowledge).  A
:class:`KnowledgeBase` loads them all, once, and answers typed calls::

    kb = KnowledgeBase()
    kb.call("world", "type", Var("T"), "us_tool")   # [{'T': 'us_probe_1'}, {'T': 'us_probe_2'}]
    kb.once("world", "location", "slra_1", Var("W"))  # {'W': Term('in_rack', ('slot_3',))}

Arguments are Python values turned into Prolog terms as data (see ita.logic.terms):
the goal is built term by term through SWI-Prolog's C interface and handed to
``py_bridge:py_run/5``; no value is ever text that Prolog reads or runs, so an atom
with quotes or spaces is just an atom.  Answers come back as quoted text that
:func:`ita.logic.terms.read_term` decodes.

Prolog calls Python the other way, through attached procedures (ita.logic.attached):
``py_bridge:attached(Name, Args, Result)`` is answered by the Python function that
:meth:`KnowledgeBase.attached` attached under ``Name`` for the duration of a ``with``
block, in the thread that entered it::

    with kb.attached({"double": lambda x: 2 * x}):
        kb.once("py_bridge", "attached", "double", [21], Var("R"))   # {'R': 42}

Its Python side is one foreign predicate, ``py_bridge:py_attached_call/3``, registered
here through ctypes: the arguments arrive as text that Prolog wrote and read_term
reads, the solutions go back as terms built with the C interface, like a goal's
arguments.  An exception of the function becomes a Prolog exception naming the
procedure; nothing escapes the C callback.

SWI-Prolog can be initialised only once per process and has one global database, so the
engine is necessarily a process-wide singleton.  It is created on first use by
:func:`_engine` under a lock and kept out of sight; a :class:`KnowledgeBase` is the
explicit handle the rest of the code passes around.  Every query runs under the
engine's lock, a re-entrant one, and is closed before the lock is released: an
attached procedure may run goals of its own in the same thread, each a query that
SWI-Prolog nests inside the one that called it (``PL_call_predicate`` from a foreign
predicate) and closes before it returns, so queries open and close in LIFO order;
another thread waits for the outermost call to end.  A thread other than the one
that initialised Prolog borrows a Prolog engine for the duration of its outermost
call.
"""

from __future__ import annotations

import ctypes
import math
import threading
from collections.abc import Mapping, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, cast

from ita.errors import KBLoadError, Location, PrologError
from ita.logic import sandbox
from ita.logic.attached import AttachedProcedures, Procedure
from ita.logic.model import Diagnostic, PredicateDoc, ProofNode, QueryResult, Severity
from ita.logic.pldoc import doc_comments
from ita.logic.sandbox import SandboxFiles
from ita.logic.terms import Str, Term, TermValue, Var, read_term
from ita.paths import resource_dir

if TYPE_CHECKING:
    from ita.logic.sandbox import SandboxFiles

__all__ = ["KnowledgeBase", "KBLoadFailed", "Solution", "check_sources"]

#: One solution of a call: the value of each reported variable, a decoded term
#: (:data:`~ita.logic.terms.TermValue`), left dynamically typed: the caller knows
#: from the predicate's mode what each one is (an atom, a number, a list of pairs...)
#: and reads it as such.
Solution: TypeAlias = dict[str, Any]

# The engine modules the bridge itself needs, loaded from the package's prolog/ dir.
_BRIDGE_FILES = ("py_bridge.pl", "kb_query.pl", "kb_explain.pl", "kb_check.pl", "kb_sandbox.pl")
_BRIDGE_MODULES = frozenset(Path(f).stem for f in _BRIDGE_FILES)

# SWI-Prolog.h constants used with PL_get_nchars / PL_put_chars.
_PL_ATOM = 2
_PL_STRING = 6
_CVT_ATOM = 0x0001
_CVT_STRING = 0x0002
_BUF_STACK = 0x00010000
_REP_UTF8 = 0x00100000
_PL_Q_NODEBUG = 0x0004
_PL_Q_CATCH_EXCEPTION = 0x0008

# How many atom handles the engine keeps (registered) for the atoms it sends.
_ATOM_CACHE_SIZE = 8192


class KBLoadFailed(KBLoadError):
    """Loading failed; `diagnostics` also holds the warnings seen while loading."""

    def __init__(self, diagnostics: Sequence[Diagnostic]):
        self.diagnostics = tuple(diagnostics)
        super().__init__(
            [(d.location, d.message) for d in self.diagnostics if d.severity is Severity.ERROR]
        )


class _Engine:
    """The process's SWI-Prolog, reached only through ``py_bridge:py_run/5``.

    A call builds its goal with SWI-Prolog's C interface (``PL_put_chars``,
    ``PL_cons_functor_v``, ``PL_cons_list``...): arguments become terms directly, never
    text that Prolog reads, so no value can be mistaken for code.  The reply comes
    back as text that ``py_run/5`` writes and :func:`ita.logic.terms.read_term` reads.
    """

    def __init__(self) -> None:
        from pyswip import (
            core,  # the one pyswip import of the project (initialises Prolog)
        )

        self._core = core
        self._lock = threading.RLock()
        #: functor handles by (name, arity); SWI never frees functors, so neither do we
        self._functors: dict[tuple[str, int], int] = {}
        #: atom handles by text, each registered (safe from atom GC) while it is here
        self._atoms: dict[str, int] = {}
        lib = core._lib
        # Our own ctypes function objects (lib[name] makes a new one each time), so
        # pyswip's declarations stay untouched; and no pyswip wrapper in between, which
        # would add a Python call to each of the C calls a request makes.
        size_t, int_, uint, char_p = ctypes.c_size_t, ctypes.c_int, ctypes.c_uint, ctypes.c_char_p
        self._open_frame = _cfunc(lib["PL_open_foreign_frame"], size_t, [])
        self._discard_frame = _cfunc(lib["PL_discard_foreign_frame"], None, [size_t])
        self._new_term_ref = _cfunc(lib["PL_new_term_ref"], size_t, [])
        self._new_term_refs = _cfunc(lib["PL_new_term_refs"], size_t, [int_])
        self._put_chars = _cfunc(lib["PL_put_chars"], int_, [size_t, int_, size_t, char_p])
        self._put_atom_c = _cfunc(lib["PL_put_atom"], int_, [size_t, size_t])
        self._unregister_atom = _cfunc(lib["PL_unregister_atom"], None, [size_t])
        self._put_int64 = _cfunc(lib["PL_put_int64"], int_, [size_t, ctypes.c_int64])
        self._put_float_c = _cfunc(lib["PL_put_float"], int_, [size_t, ctypes.c_double])
        self._put_nil = _cfunc(lib["PL_put_nil"], int_, [size_t])
        self._put_variable = _cfunc(lib["PL_put_variable"], int_, [size_t])
        self._put_term = _cfunc(lib["PL_put_term"], int_, [size_t, size_t])
        self._cons_list = _cfunc(lib["PL_cons_list"], int_, [size_t, size_t, size_t])
        self._cons_functor_v = _cfunc(lib["PL_cons_functor_v"], int_, [size_t, size_t, size_t])
        self._chars_to_term = _cfunc(lib["PL_chars_to_term"], int_, [char_p, size_t])
        self._new_atom = _cfunc(lib["PL_new_atom_mbchars"], size_t, [int_, size_t, char_p])
        self._new_functor = _cfunc(lib["PL_new_functor_sz"], size_t, [size_t, size_t])
        self._call_predicate = _cfunc(
            lib["PL_call_predicate"], int_, [ctypes.c_void_p, int_, ctypes.c_void_p, size_t]
        )
        self._get_nchars = _cfunc(
            lib["PL_get_nchars"], int_,
            [size_t, ctypes.POINTER(size_t), ctypes.POINTER(char_p), uint],
        )
        self._thread_self = _cfunc(lib["PL_thread_self"], int_, [])
        self._attach_engine = _cfunc(lib["PL_thread_attach_engine"], int_, [ctypes.c_void_p])
        self._destroy_engine = _cfunc(lib["PL_thread_destroy_engine"], int_, [])
        self._predicate = _cfunc(lib["PL_predicate"], ctypes.c_void_p, [char_p, int_, char_p])
        self._unify = _cfunc(lib["PL_unify"], int_, [size_t, size_t])
        self._raise_exception = _cfunc(lib["PL_raise_exception"], int_, [size_t])
        self._length = size_t()
        self._chars = char_p()
        self._length_ref = ctypes.byref(self._length)
        self._chars_ref = ctypes.byref(self._chars)
        #: the procedures attached by each thread (see ita.logic.attached)
        self.procedures = AttachedProcedures()
        #: per thread: how deep it is in run(), and the exceptions attached procedures
        #: raised during its runs (each run takes those raised while it ran)
        self._calls = threading.local()
        self._bootstrap()
        # py_bridge:py_attached_call/3, the Python side of py_bridge:attached/3; the
        # ctypes callback is kept here, for as long as Prolog may call it
        self._attached_callback = _FOREIGN_3(self._answer_attached)
        register = _cfunc(lib["PL_register_foreign_in_module"], int_,
                          [char_p, char_p, int_, ctypes.c_void_p, int_])
        if not register(b"py_bridge", b"py_attached_call", 3,
                        ctypes.cast(self._attached_callback, ctypes.c_void_p), 0):
            raise KBLoadError([(Location(str(resource_dir("prolog") / _BRIDGE_FILES[0])),
                                "cannot register py_bridge:py_attached_call/3")])

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
        self._py_run = self._predicate(b"py_run", 5, b"py_bridge")
        try:
            reply = self.run("system", "=", (Var("X"), "ok"), 1)
        except PrologError as exc:
            raise KBLoadError(
                [(Location(str(resource_dir("prolog") / _BRIDGE_FILES[0])), str(exc))]
            ) from exc
        if reply != (("X",), [["ok"]]):
            raise KBLoadError([(Location(str(resource_dir("prolog") / _BRIDGE_FILES[0])),
                                f"bridge self-test failed: {reply!r}")])

    def run(self, module: str, name: str, args: Sequence[TermValue], limit: int | None
            ) -> tuple[tuple[str, ...], list[list[TermValue]]]:
        """``py_bridge:py_run/5`` on ``module:name(args...)``: the names of the reported
        variables (sorted), and the values of each in each solution.

        Raises :class:`~ita.errors.PrologError` when the goal raised; when an attached
        procedure's exception caused that, the Python exception is its ``__cause__``.
        Re-entrant: an attached procedure may run goals, in the same thread, while
        its caller's goal runs (SWI-Prolog nests the queries; each is closed before
        the one that called it goes on).  Other threads wait for the engine's lock.
        """
        calls = self._calls
        with self._lock:
            depth = getattr(calls, "depth", 0)
            if depth == 0:
                calls.raised = []
            raised: list[tuple[str, BaseException]] = calls.raised
            mark = len(raised)
            borrowed = depth == 0 and self._thread_self() == -1
            if borrowed and self._attach_engine(None) < 0:
                raise PrologError("py_run", "cannot attach a Prolog engine to this thread")
            calls.depth = depth + 1
            try:
                names, text = self._run(module, name, args, limit)
            finally:
                calls.depth = depth
                if borrowed:
                    self._destroy_engine()
                mine = raised[mark:]
                del raised[mark:]
        for _, exc in mine:
            if not isinstance(exc, Exception):  # KeyboardInterrupt, SystemExit: not Prolog's to catch
                raise exc
        goal = f"{module}:{name}/{len(args)}"
        try:
            reply = read_term(text)
        except ValueError as exc:
            raise PrologError(goal, f"cannot read the reply: {exc}") from None
        if type(reply) is not list:
            assert isinstance(reply, Term)  # py_run/5 replies the solutions or error(Message, GoalText)
            message, goal_text = reply.args
            cause = next((exc for text, exc in reversed(mine) if text in message), None)
            raise PrologError(goal_text or goal, message) from cause
        return names, cast("list[list[TermValue]]", reply)  # one list of values per solution

    def _run(self, module: str, name: str, args: Sequence[TermValue], limit: int | None
             ) -> tuple[tuple[str, ...], str]:
        """Build the call in a foreign frame, run it, and discard the frame."""
        fid = self._open_frame()
        try:
            refs = self._new_term_refs(5)  # Module, Goal, Reported, Limit, Reply
            self._put_atom(refs, module)
            variables: dict[str, int] = {}
            if args:
                arity = len(args)
                arg_refs = self._new_term_refs(arity)
                put, atoms, put_atom = self._put, self._atoms, self._put_atom_c
                for i, value in enumerate(args):
                    if type(value) is str and value in atoms:  # the commonest argument
                        if not put_atom(arg_refs + i, atoms[value]):
                            raise PrologError(f"{module}:{name}/{arity}", "cannot build the goal")
                    else:
                        put(arg_refs + i, value, variables)
                ok = self._cons_functor_v(refs + 1, self._functor(name, arity), arg_refs)
            else:
                ok = self._put_atom(refs + 1, name)
            names = tuple(sorted(n for n in variables if not n.startswith("_")))
            reported = refs + 2
            ok = ok and self._put_nil(reported)
            for n in reversed(names):
                ok = ok and self._cons_list(reported, variables[n], reported)
            if limit is None:
                ok = ok and self._put_atom(refs + 3, "all")
            else:
                ok = ok and self._put_int64(refs + 3, limit)
            if not ok:
                raise PrologError(f"{module}:{name}/{len(args)}", "cannot build the goal")
            if not self._call_predicate(None, _PL_Q_NODEBUG | _PL_Q_CATCH_EXCEPTION,
                                        self._py_run, refs):
                raise PrologError("py_bridge:py_run/5", "the bridge call failed or raised")
            if not self._get_nchars(refs + 4, self._length_ref, self._chars_ref,
                                    _CVT_STRING | _REP_UTF8 | _BUF_STACK):
                raise PrologError("py_bridge:py_run/5", "the bridge returned no text")
            return names, ctypes.string_at(self._chars, self._length.value).decode("utf-8")
        finally:
            self._discard_frame(fid)

    def _answer_attached(self, name_ref: int, text_ref: int, out_ref: int) -> int:
        """``py_bridge:py_attached_call(+Name, +ArgsText, -Solutions)``, called by Prolog.

        Runs the procedure attached under Name in this thread on the arguments (the
        text of a list, as py_run/5 writes its replies) and unifies Solutions with
        the list of its solutions, built as terms.  Whatever goes wrong becomes a
        Prolog exception: nothing may escape a ctypes callback.
        """
        try:
            if getattr(self._calls, "depth", 0) == 0:
                # not inside run() of this thread (a thread Prolog started, say): the
                # engine's state is not ours to touch, the lock not held
                return self._raise_constant(
                    "error(permission_error(call, attached_procedure, outside_a_bridge_call), _)")
            name = self._text(name_ref, _CVT_ATOM)
            args = read_term(self._text(text_ref, _CVT_STRING))
            if not isinstance(args, list):
                raise TypeError(f"the arguments are not a list: {args!r}")
            indicator = Term("/", (name, len(args)))
            procedure = self.procedures.find(name)
            if procedure is None:
                return self._raise_term(Term("error", (
                    Term("existence_error", ("attached_procedure", indicator)), Var("_"))))
            try:
                solutions = self.procedures.solutions(procedure, args)
                result = self._new_term_ref()
                ok = self._put_nil(result)
                head = self._new_term_ref()
                for solution in reversed(solutions):
                    self._put(head, solution, {})  # each solution has variables of its own
                    ok = ok and self._cons_list(result, head, result)
                if not ok:
                    raise PrologError("py_bridge", "cannot build the list of solutions")
            except BaseException as exc:  # noqa: BLE001 - every exception goes back to Prolog
                kind = type(exc).__name__
                self._calls.raised.append((f"{name}/{len(args)} raised {kind}", exc))
                return self._raise_term(Term("error", (
                    Term("attached_procedure_error", (indicator, kind, Str(str(exc) or kind))),
                    Var("_"))))
            return int(self._unify(out_ref, result))
        except BaseException as exc:  # noqa: BLE001 - a failure of the bridge itself
            depth: int = getattr(self._calls, "depth", 0)
            if depth and not isinstance(exc, Exception):
                self._calls.raised.append(("", exc))  # a KeyboardInterrupt goes on in Python
            return self._raise_constant(
                "error(resource_error(python_bridge), _)" if isinstance(exc, MemoryError)
                else "error(system_error(attached_procedure_call_failed), _)")

    def _text(self, ref: int, flags: int) -> str:
        """The text of the atom or string in `ref`."""
        if not self._get_nchars(ref, self._length_ref, self._chars_ref, flags | _REP_UTF8 | _BUF_STACK):
            raise ValueError("not text")
        return ctypes.string_at(self._chars, self._length.value).decode("utf-8")

    def _raise_term(self, value: TermValue) -> int:
        """Raise the Prolog exception `value` (built as data) from a foreign predicate."""
        ref = self._new_term_ref()
        self._put(ref, value, {})
        return int(self._raise_exception(ref))

    def _raise_constant(self, text: str) -> int:
        """Raise the exception that constant `text` (never data) reads as."""
        ref = self._new_term_ref()
        if not self._chars_to_term(text.encode("ascii"), ref):
            return 0
        return int(self._raise_exception(ref))

    def _atom(self, text: str) -> int:
        """The handle of atom `text`, from the cache or made (and registered) now."""
        atoms = self._atoms
        if len(atoms) >= _ATOM_CACHE_SIZE:
            for atom in atoms.values():
                self._unregister_atom(atom)
            atoms.clear()
        data = text.encode("utf-8")
        atom = atoms[text] = int(self._new_atom(_REP_UTF8, len(data), data))
        return atom

    def _put_atom(self, ref: int, text: str) -> int:
        atom = self._atoms.get(text)
        return int(self._put_atom_c(ref, atom if atom is not None else self._atom(text)))

    def _functor(self, name: str, arity: int) -> int:
        key = (name, arity)
        functor = self._functors.get(key)
        if functor is None:
            data = name.encode("utf-8")
            atom = self._new_atom(_REP_UTF8, len(data), data)
            functor = self._functors[key] = self._new_functor(atom, arity)
        return functor

    def _put(self, ref: int, value: Any, variables: dict[str, int]) -> None:
        """Put the term for Python `value` in term reference `ref` (see ita.logic.terms).

        `value` is a :data:`~ita.logic.terms.TermValue`, left dynamically typed because the
        dispatch is on ``type(value)`` (the hot path of every call), through which mypy
        does not narrow; anything else raises TypeError.

        `variables` maps the names of the :class:`Var` met so far to the reference
        holding each; a name met again is the same Prolog variable.
        """
        kind = type(value)
        if kind is str:
            atom = self._atoms.get(value)
            ok = self._put_atom_c(ref, atom if atom is not None else self._atom(value))
        elif kind is list or kind is tuple:
            ok = self._put_nil(ref)
            if value:
                head = self._new_term_ref()
                put, cons = self._put, self._cons_list
                for item in reversed(value):
                    put(head, item, variables)
                    ok = ok and cons(ref, head, ref)
        elif kind is Term:
            arity = len(value.args)
            arg_refs = self._new_term_refs(arity)
            for i, item in enumerate(value.args):
                self._put(arg_refs + i, item, variables)
            ok = self._cons_functor_v(ref, self._functor(value.name, arity), arg_refs)
        elif kind is Var:
            first = variables.get(value.name)
            if first is None:
                ok = self._put_variable(ref)
                variables[value.name] = keep = self._new_term_ref()
                ok = ok and self._put_term(keep, ref)
            else:
                ok = self._put_term(ref, first)
        elif kind is int:
            ok = self._put_int(ref, value)
        elif kind is float:
            ok = self._put_float(ref, value)
        elif kind is Str:
            data = value.text.encode("utf-8")
            ok = self._put_chars(ref, _PL_STRING | _REP_UTF8, len(data), data)
        elif kind is bool:
            ok = self._put_atom(ref, "true" if value else "false")
        # subclasses (str and int enums, numpy floats...) are passed as their base value
        elif isinstance(value, str):
            ok = self._put_atom(ref, str.__str__(value))
        elif isinstance(value, int):
            ok = self._put_int(ref, int(value))
        elif isinstance(value, float):
            ok = self._put_float(ref, float(value))
        elif isinstance(value, (list, tuple)):
            return self._put(ref, list(value), variables)
        else:
            raise TypeError(f"cannot pass {type(value).__name__} {value!r} to Prolog")
        if not ok:
            raise PrologError("py_bridge", f"cannot pass {value!r} to Prolog")

    def _put_int(self, ref: int, value: int) -> int:
        if -(2**63) <= value < 2**63:
            return int(self._put_int64(ref, value))
        return int(self._chars_to_term(str(value).encode("ascii"), ref))  # digits only: a big integer

    def _put_float(self, ref: int, value: float) -> int:
        if -math.inf < value < math.inf:
            return int(self._put_float_c(ref, value))
        text = "1.5NaN" if math.isnan(value) else ("1.0Inf" if value > 0 else "-1.0Inf")
        return int(self._chars_to_term(text.encode("ascii"), ref))


#: The C type of a deterministic foreign predicate of arity 3:
#: ``foreign_t f(term_t, term_t, term_t)`` (foreign_t and term_t are uintptr_t).
_FOREIGN_3 = ctypes.CFUNCTYPE(ctypes.c_size_t, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_size_t)


def _cfunc(function: Any, restype: Any, argtypes: list[Any]) -> Any:
    """`function` of libswipl with its C signature declared."""
    function.restype = restype
    function.argtypes = argtypes
    return function


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

    def call(self, module: str, name: str, *args: TermValue, limit: int | None = None) -> list[Solution]:
        """All solutions (at most `limit`) of ``module:name(args...)``.

        Each solution maps the name of every :class:`Var` among `args` (except names
        starting with ``_``) to its value.  Raises :class:`~ita.errors.PrologError`
        when the goal raises.
        """
        if limit is not None and limit < 1:
            raise ValueError(f"limit must be positive, got {limit}")
        if not (isinstance(module, str) and isinstance(name, str)):
            raise TypeError(f"module and name must be str, got {module!r} and {name!r}")
        names, rows = self._engine.run(str.__str__(module), str.__str__(name), args, limit)
        return [dict(zip(names, values)) for values in rows]

    def once(self, module: str, name: str, *args: TermValue) -> Solution | None:
        """The first solution of ``module:name(args...)``, or None when it fails."""
        solutions = self.call(module, name, *args, limit=1)
        return solutions[0] if solutions else None

    def holds(self, module: str, name: str, *args: TermValue) -> bool:
        """True when ``module:name(args...)`` has a solution."""
        return self.once(module, name, *args) is not None

    def one(self, module: str, name: str, *args: TermValue) -> Solution:
        """The solution of ``module:name(args...)``, a predicate that always has one;
        :class:`~ita.errors.PrologError` when it failed."""
        solution = self.once(module, name, *args)
        if solution is None:
            raise PrologError(f"{module}:{name}/{len(args)}", "failed where it always succeeds")
        return solution

    def attached(self, procedures: Mapping[str, Procedure]) -> AbstractContextManager[None]:
        """Attach Python functions as the answers of ``py_bridge:attached(Name, Args,
        Result)`` for the goals this thread runs until the ``with`` block ends::

            with kb.attached({"double": lambda x: 2 * x, "divisors": nondet(divisors)}):
                kb.call("my_module", "uses_them", Var("X"))

        `procedures` maps each name to a function of the terms of ``Args`` that returns
        one solution or None (semidet), or to :func:`ita.logic.attached.nondet` of a
        function that returns an iterable of solutions.  Solutions are any
        :data:`~ita.logic.terms.TermValue`, passed to Prolog as data, as call arguments
        are.  A function may itself call this knowledge base (in this thread: another
        thread waits until the outer call is over, so a function must not wait for a
        thread that calls Prolog).  An exception it raises is a Prolog exception
        naming the procedure, then the outer call's :class:`~ita.errors.PrologError`,
        whose ``__cause__`` is the exception.  An inner block may attach a name
        again; the outer function is back when it ends.  Other threads, and the
        sandbox of :meth:`run_user_query`, see none of these procedures.
        """
        return self._engine.procedures.scope(procedures)

    # -- the kb commands -----------------------------------------------------------

    def run_user_query(
        self,
        text: str,
        limit: int = 100,
        time_limit: float = 10.0,
        inference_limit: int = 10_000_000,
    ) -> QueryResult:
        """Run a goal typed by a person, safely: in a child process with OS limits
        (see ita.logic.sandbox), the sandbox checks, a scratch module and the limits.

        Raises :class:`~ita.errors.QueryRefused` for a syntax error or an unsafe goal,
        :class:`~ita.errors.QueryLimitExceeded` when a limit stops it, and
        :class:`~ita.errors.PrologError` when the goal raises an error.
        """
        return sandbox.query(text, self._sandbox_files(),
                             sandbox.SandboxLimits(float(time_limit), int(inference_limit)), int(limit))

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
        as :meth:`run_user_query` (the goal runs in a child process).
        """
        return sandbox.explain(text, self._sandbox_files(),
                               sandbox.SandboxLimits(float(time_limit), int(inference_limit)), int(max_depth))

    def _sandbox_files(self) -> "SandboxFiles":
        return SandboxFiles(tuple(self.engine_files), tuple(self.kb_files))

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


def _indicator(term: TermValue) -> str:
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
