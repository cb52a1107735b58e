"""The Offline Measurement Entry in the browser (`/parts/specs?dir=DIR`): the part in 3-D,
a spec proposed where a person clicks (ita.part.pick), saved to the part's specs.csv.

    GET  /api/parts/specs?dir=DIR            the part's specs and its mesh (for the 3-D view)
    GET  /api/parts/pick?dir=DIR&at=X,Y,Z[&kind=K]   a proposal (ita.part.pick.Proposal)
    POST /api/parts/specs?dir=DIR            {"action": "add", "spec": {CSV fields}}
                                             {"action": "edit", "id": ID, "spec": {fields to change}}
                                             {"action": "remove", "id": ID}
                                             {"action": "undo"}

Walls: a part is a directory with a mesh and a specs.csv (the built-in bulkhead is not
edited here); every change is checked as `ita spec add` checks it and written through the
atomic writer under the file's lock (ita.part.specfile), nothing written when it fails;
undo puts back the file as it was before the last change made here, only when nobody has
changed it since.  Requests that change something need the header X-ITA: 1 (app.py), and
the guard keeps them to this machine.
"""

from __future__ import annotations

import hashlib
import math
import threading
from pathlib import Path
from typing import Any

import numpy as np

from ita.errors import InputError
from ita.files.atomic import locked, write_atomic
from ita.offline.spec_reach import reach_at
from ita.part import specfile
from ita.part.pick import propose
from ita.part.store import SPECS_FILE, load_part
from ita.specs.io import COLUMNS
from ita.specs.model import MeasurementKind
from ita.web.bodies import BadRequest, part_field
from ita.workcell import workcell_for

__all__ = ["MAX_FACES", "Editor", "UNDO_DEPTH"]

#: the 3-D view gets at most this many faces of the part's mesh (decimated beyond)
MAX_FACES = 60_000
#: changes an editor can undo, per part
UNDO_DEPTH = 20
#: the fields of a spec the editor takes (the CSV's columns)
FIELDS = tuple(COLUMNS)


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class Editor:
    """The server's memory of changes made through the editor (for undo), per part
    directory, shared by its request threads."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._undo: dict[str, list[tuple[bytes, str]]] = {}     # dir -> [(bytes before, digest after)]

    @staticmethod
    def part_dir(value: str | None) -> Path:
        """The part directory a request names (`dir`): an existing directory with a mesh and
        a specs.csv; BadRequest otherwise (and for the built-in bulkhead)."""
        path = part_field({"part": value})
        if path is None:
            raise BadRequest("dir: a part directory on the server (a mesh and specs.csv); the built-in "
                             "bulkhead is not edited here (make your own with `ita part new DIR`)")
        if not (Path(path) / SPECS_FILE).is_file():
            raise BadRequest(f"dir: {path!r} has no {SPECS_FILE} (a part directory: a mesh and {SPECS_FILE})")
        return Path(path)

    def view(self, directory: Path) -> dict[str, Any]:
        """The part's specs and its mesh (x, y, z, i, j, k for plotly's mesh3d)."""
        part = load_part(directory)
        mesh = part.mesh
        if len(mesh.faces) > MAX_FACES:
            try:                          # a view of fewer faces; the proposals read the whole mesh
                mesh = mesh.simplify_quadric_decimation(face_count=MAX_FACES)
            except (ImportError, ValueError, RuntimeError):
                mesh = part.mesh
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        specs = [_spec_row(s) for s in specfile.load(part)]
        return {"part": part.name, "dir": str(directory), "specs": specs,
                "kinds": [k.value for k in MeasurementKind], "can_undo": bool(self._undo.get(str(directory))),
                "mesh": {"x": np.round(v[:, 0], 3).tolist(), "y": np.round(v[:, 1], 3).tolist(),
                         "z": np.round(v[:, 2], 3).tolist(), "i": f[:, 0].tolist(), "j": f[:, 1].tolist(),
                         "k": f[:, 2].tolist()}}

    @staticmethod
    def pick(directory: Path, at: str | None, kind: str | None) -> dict[str, Any]:
        """The proposal at `at` ('x,y,z', mm) of `kind` (a kind's name, or None)."""
        try:
            point = tuple(float(x) for x in (at or "").split(","))
        except ValueError:
            point = ()
        if len(point) != 3 or not all(math.isfinite(x) for x in point):
            raise BadRequest(f"at: three finite numbers x,y,z in mm (got {str(at)[:80]!r})")
        wanted = None
        if kind:
            try:
                wanted = MeasurementKind(kind)
            except ValueError:
                raise BadRequest(f"kind: one of {', '.join(k.value for k in MeasurementKind)}") from None
        part = load_part(directory)
        out = propose(part, point, wanted).to_dict()
        if out["point"] is not None and out["normal"] is not None:
            out["reach"] = reach_at(workcell_for(part.directory, part.mesh.bounds), out["point"], out["normal"])
        return out

    def change(self, directory: Path, body: dict[str, Any]) -> dict[str, Any]:
        """Add, edit or remove a spec, or undo the last change made here; the specs after."""
        action = body.get("action")
        if action not in ("add", "edit", "remove", "undo"):
            raise BadRequest("action: add, edit, remove or undo")
        unknown = sorted(set(body) - {"action", "spec", "id"})
        if unknown:
            raise BadRequest(f"unknown field {unknown[0]!r}")
        path = directory / SPECS_FILE
        with self._lock:
            if action == "undo":
                return self._undo_last(directory)
            before = path.read_bytes()
            part = load_part(directory)
            try:
                if action == "add":
                    made = specfile.add(part, _fields(body.get("spec"), full=True))
                    said = f"added {made.id}"
                elif action == "edit":
                    made = specfile.change(part, _spec_id(body.get("id")), _fields(body.get("spec"), full=False))
                    said = f"changed {made.id}"
                else:
                    specfile.remove(part, [_spec_id(body.get("id"))])
                    said = f"removed {body.get('id')}"
            except InputError as exc:
                raise BadRequest("; ".join(why for _, why in exc.problems)[:600] or "not a spec") from None
            stack = self._undo.setdefault(str(directory), [])
            stack.append((before, _digest(path.read_bytes())))
            del stack[:-UNDO_DEPTH]
        return {"done": said, **self.view(directory)}

    def _undo_last(self, directory: Path) -> dict[str, Any]:
        stack = self._undo.get(str(directory)) or []
        if not stack:
            raise BadRequest("nothing to undo: no change made here since the server started")
        before, after = stack[-1]
        path = directory / SPECS_FILE
        with locked(path):
            if _digest(path.read_bytes()) != after:
                raise BadRequest(f"{SPECS_FILE} changed since (by another program): not undone, nothing written")
            write_atomic(path, before)
        stack.pop()
        return {"done": "undone", **self.view(directory)}


def _spec_row(s: Any) -> dict[str, Any]:
    return {"id": s.id, "kind": s.kind.value, "feature": s.feature, "point": list(s.point), "normal": list(s.normal),
            "nominal": s.nominal, "lower": s.lower, "upper": s.upper, "datum": s.datum,
            "direction": None if s.direction is None else list(s.direction), "note": s.note}


def _spec_id(value: Any) -> str:
    if not isinstance(value, str) or not value.strip() or len(value) > 64:
        raise BadRequest("id: the id of one of the part's specs")
    return value.strip()


def _fields(value: Any, *, full: bool) -> dict[str, str]:
    """A spec's CSV fields as text (numbers taken as they come); BadRequest for anything
    else.  `full`: a whole spec (its id, kind, feature, point, normal, nominal, tolerance)."""
    if not isinstance(value, dict):
        raise BadRequest("spec: an object of a spec's fields (the columns of specs.csv)")
    out: dict[str, str] = {}
    for k, v in value.items():
        if k not in FIELDS:
            raise BadRequest(f"spec: unknown field {str(k)[:40]!r}; the fields are {', '.join(FIELDS)}")
        if v is None:
            v = ""
        if isinstance(v, bool) or not isinstance(v, (str, int, float)):
            raise BadRequest(f"spec: {k} is a text or a number")
        text = str(v)
        if len(text) > 200 or any(c in text for c in "\r\n\x00"):
            raise BadRequest(f"spec: {k} is one line of at most 200 characters")
        out[k] = text
    if full:
        missing = [k for k in ("id", "kind", "feature", "x", "y", "z", "nx", "ny", "nz", "nominal", "lower", "upper")
                   if not out.get(k)]
        if missing:
            raise BadRequest(f"spec: {', '.join(missing)} missing")
    return out
