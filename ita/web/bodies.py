"""The API's request bodies, each checked whole before anything is done.

    body = json_object(raw)                        # BadRequest unless a JSON object
    start = start_request(body, spec_count)        # POST /api/runs
    command = control_command(body)                # POST /api/runs/{id}/control

A body is UTF-8 JSON holding one object, with finite numbers only (no NaN or Infinity,
no number that overflows to one), and only the fields of its request, each of its type
(a boolean is not a number).  Anything else is a `BadRequest` (400) whose one line names
the field and what it may hold.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ita.errors import InputError, ItaError
from ita.labels import LABEL_RULE, label_problem
from ita.part.store import SPECS_FILE, ensure_builtin
from ita.seeds import SEED_MAX
from ita.sim.inject import InjectionPlan
from ita.specs.io import read_spec_table

START_FIELDS = ("part", "limit", "seed", "faults", "inject", "serial", "operator")
#: at most this many scripted faults in one start request, each at most INJECT_CHARS long
MAX_INJECT, INJECT_CHARS = 8, 80
CONTROL_FIELDS = ("command",)
COMMANDS = ("STOP", "INTERRUPT", "CONTINUE")
_WHOLE = re.compile(r"[0-9]{1,30}", re.ASCII)
_DECIMAL = re.compile(r"[0-9]{0,30}(\.[0-9]{0,30})?([eE][-+]?[0-9]{1,4})?", re.ASCII)


class BadRequest(ItaError):
    """A request body the API does not take (answered 400 with the one line)."""

    status = 400


@dataclass(frozen=True)
class StartRequest:
    """A run to start: its part directory (None: the built-in bulkhead), how many
    measurements (None: every one), the simulator's seed, the fault rate."""

    part: str | None
    limit: int | None
    seed: int
    faults: float
    serial: str | None = None
    operator: str | None = None
    inject: tuple[str, ...] = ()          # scripted faults, as `ita inspect --inject` takes them


def _reject_constant(name: str) -> Any:
    raise BadRequest(f"the body holds {name}: numbers must be finite")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise BadRequest(f"the body holds the number {text[:40]}, which is not finite")
    return value


def json_object(raw: bytes) -> dict[str, Any]:
    """The JSON object of a request body; BadRequest for anything else."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BadRequest(f"the body is not UTF-8 text (byte {exc.start}); it must be a JSON object") from None
    try:
        value = json.loads(text, parse_constant=_reject_constant, parse_float=_finite_float)
    except RecursionError:
        raise BadRequest("the body is nested too deeply; it must be a flat JSON object") from None
    except ValueError as exc:      # JSONDecodeError, and an integer of more digits than int() takes
        raise BadRequest(f"the body is not JSON ({str(exc).splitlines()[0][:120]}); it must be a JSON object") \
            from None
    if not isinstance(value, dict):
        raise BadRequest(f"the body is a JSON {_kind(value)}; it must be a JSON object")
    return value


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, (int, float)):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, list):
        return "array"
    return "object"


def _shown(value: Any) -> str:
    """A value as an error message shows it (short)."""
    if isinstance(value, str):
        return repr(value[:30])
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return str(value)[:30]
    return f"a {_kind(value)}"


def _fields(body: dict[str, Any], allowed: tuple[str, ...]) -> None:
    unknown = sorted(k for k in body if k not in allowed)
    if unknown:
        shown = unknown[0][:40]
        raise BadRequest(f"unknown field {shown!r}: the fields are {', '.join(allowed)}")


def _whole(body: dict[str, Any], name: str, low: int, high: int, allowed: str) -> int | None:
    """A whole number field (a JSON integer or a string of digits); None when absent,
    null or ""."""
    value = body.get(name)
    if value is None or value == "":
        return None
    if isinstance(value, str) and _WHOLE.fullmatch(value.strip()):
        value = int(value.strip())
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise BadRequest(f"{name}: {allowed} (got {_shown(body.get(name))})")
    return value


def _fraction(body: dict[str, Any], name: str, allowed: str) -> float | None:
    """A number field in 0..1 (a JSON number or its decimal string); None when absent,
    null or ""."""
    value = body.get(name)
    if value is None or value == "":
        return None
    if isinstance(value, str) and _DECIMAL.fullmatch(value.strip()):
        try:
            value = float(value.strip())
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise BadRequest(f"{name}: {allowed} (got {_shown(body.get(name))})")
    return float(value)


def part_field(body: dict[str, Any]) -> str | None:
    """The `part` field: None for the built-in bulkhead (absent, null, ""), else an
    existing directory, resolved."""
    value = body.get("part")
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    allowed = "a part directory on the server (a mesh and specs.csv), or empty for the built-in bulkhead"
    if not isinstance(value, str):
        raise BadRequest(f"part: {allowed} (got a {_kind(value)})")
    text = value.strip()
    if "\x00" in text or len(text) > 4096:
        raise BadRequest(f"part: {allowed} (got a string that is no path)")
    try:
        path = Path(text).expanduser()
        if not path.is_dir():
            raise BadRequest(f"part: {text[:200]!r} is not a directory; {allowed}")
        return str(path.resolve())
    except (OSError, RuntimeError) as exc:
        raise BadRequest(f"part: {text[:200]!r} cannot be read ({getattr(exc, 'strerror', None) or exc}); "
                         f"{allowed}") from None


def start_request(body: dict[str, Any], spec_count: Callable[[str | None], int]) -> StartRequest:
    """The run a POST /api/runs body asks for.  `spec_count(part)` is the number of specs
    of the part (read only when a limit is given): the largest limit."""
    _fields(body, START_FIELDS)
    part = part_field(body)
    seed = _whole(body, "seed", 0, SEED_MAX, f"a whole number from 0 to {SEED_MAX}, or empty for 0")
    faults = _fraction(body, "faults", "a number from 0 to 1 (the chance each command meets a fault), or empty "
                                       "for none")
    limit = None
    if body.get("limit") not in (None, ""):
        try:
            count = spec_count(part)
        except ItaError as exc:
            first = (str(exc).splitlines() or [type(exc).__name__])[0]
            raise BadRequest(f"part: its specs cannot be read ({first[:200]})") from None
        limit = _whole(body, "limit", 1, count,
                       f"a whole number from 1 to {count} (the part's specs), or empty for every measurement")
    return StartRequest(part, limit, 0 if seed is None else seed, 0.0 if faults is None else faults,
                        _label(body, "serial"), _label(body, "operator"), _inject(body))


def _inject(body: dict[str, Any]) -> tuple[str, ...]:
    """The scripted faults of a start request: a text of FAULT[@TARGET][:after=S] separated
    by spaces or commas (or a list of such), each checked as `ita inspect --inject` checks
    it (the fault known, the form right); the targets the run checks against its cell."""
    value = body.get("inject")
    if value is None or value == "" or value == []:
        return ()
    if isinstance(value, str):
        items = [x for x in re.split(r"[\s,]+", value.strip()) if x]
    elif isinstance(value, list) and all(isinstance(x, str) for x in value):
        items = [x.strip() for x in value if x.strip()]
    else:
        raise BadRequest(f"inject: a text of FAULT[@TARGET][:after=S], separated by spaces (got {_shown(value)})")
    if len(items) > MAX_INJECT or any(len(x) > INJECT_CHARS for x in items):
        raise BadRequest(f"inject: at most {MAX_INJECT} faults, each at most {INJECT_CHARS} characters")
    try:
        InjectionPlan.parse(scripts=items)
    except InputError as exc:
        raise BadRequest("inject: " + "; ".join(f"{where.field}: {why}" for where, why in exc.problems)) from None
    return tuple(items)


def _label(body: dict[str, Any], name: str) -> str | None:
    """A serial number or a name: 1 to 64 printable characters (empty or absent: None)."""
    value = body.get(name)
    if value is None or value == "":
        return None
    if not isinstance(value, str):
        raise BadRequest(f"{name}: a text of {LABEL_RULE} (got a {_kind(value)})")
    if label_problem(value):
        raise BadRequest(f"{name}: a text of {LABEL_RULE}")
    return value.strip()


def control_command(body: dict[str, Any]) -> str:
    """The command of a POST /api/runs/{id}/control body: STOP, INTERRUPT or CONTINUE."""
    _fields(body, CONTROL_FIELDS)
    value = body.get("command")
    allowed = "command: STOP, INTERRUPT or CONTINUE"
    if not isinstance(value, str):
        raise BadRequest(f"{allowed} (got {'no command' if value is None else _shown(value)})")
    if value.strip().upper() not in COMMANDS:
        raise BadRequest(f"{allowed} (got {_shown(value)})")
    return value.strip().upper()


def spec_count(part: str | None) -> int:
    """The number of specs of a part directory (None: the built-in bulkhead, made first
    when it is not yet); InputError when its specs cannot be read."""
    directory = ensure_builtin() if part is None else Path(part)
    return len(read_spec_table(directory / SPECS_FILE).specs)
